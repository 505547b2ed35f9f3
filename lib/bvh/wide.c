/* wide.c - the eight-wide view of the binary BVH (see wide.h). */
#include "bvh/wide.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/tree.h"
#include "sdf/sdf.h"

typedef struct collapser {
    const sdf__tree_node *nodes;
    sdf__wide *out;
} collapser;

/* Half the surface area of a node's box: the SAH's measure of how often a walk enters it. */
static float half_area(const sdf__tree_node *n)
{
    float dx = n->hi[0] - n->lo[0], dy = n->hi[1] - n->lo[1], dz = n->hi[2] - n->lo[2];
    return dx * dy + dy * dz + dz * dx;
}

/* Fill wide node `at` from binary node `b`'s descendants (wide.h: the collapse rule), then
 * its inner children recursively. */
static void collapse(collapser *c, uint32_t b, size_t at)
{
    const sdf__tree_node *nodes = c->nodes;
    uint32_t kids[SDF__WIDE];
    int n = 0;
    if (nodes[b].count) { /* a root that is a leaf: one child */
        kids[n++] = b;
    } else {
        kids[n++] = nodes[b].first;
        kids[n++] = nodes[b].first + 1;
    }
    while (n < SDF__WIDE) {
        int open = -1;
        float largest = -1;
        for (int i = 0; i < n; i++) {
            if (nodes[kids[i]].count)
                continue;
            float a = half_area(&nodes[kids[i]]);
            if (a > largest)
                largest = a, open = i;
        }
        if (open < 0)
            break;
        uint32_t inner = kids[open];
        kids[open] = nodes[inner].first;
        kids[n++] = nodes[inner].first + 1;
    }
    for (int i = 0; i < SDF__WIDE; i++) {
        sdf__wide_node *w = &c->out->nodes[at]; /* the array never moves: made to size */
        if (i >= n) {
            for (int a = 0; a < 3; a++)
                w->lo[a][i] = INFINITY, w->hi[a][i] = -INFINITY;
            w->child[i] = SDF__WIDE_EMPTY;
            continue;
        }
        const sdf__tree_node *k = &nodes[kids[i]];
        for (int a = 0; a < 3; a++)
            w->lo[a][i] = k->lo[a], w->hi[a][i] = k->hi[a];
        if (k->count) {
            w->child[i] = kids[i] | SDF__WIDE_LEAF;
            continue;
        }
        size_t next = c->out->count++;
        w->child[i] = (uint32_t)next;
        collapse(c, kids[i], next);
    }
}

int sdf__wide_build(const sdf__tree_node *nodes, size_t node_count, sdf__wide *out)
{
    memset(out, 0, sizeof *out);
    if (node_count >= SDF__WIDE_LEAF - 1)
        return SDF_EBVH;
    /* Every wide node but the root stands for a distinct inner binary node, and a binary
     * tree has fewer inner nodes than nodes / 2 + 1. */
    out->nodes = malloc((node_count / 2 + 1) * sizeof *out->nodes);
    if (!out->nodes)
        return SDF_ENOMEM;
    collapser c = {nodes, out};
    out->count = 1;
    collapse(&c, 0, 0);
    /* Nodes fill about half of their 8 slots, so give back the rest of the worst-case
     * allocation. */
    sdf__wide_node *fitted = realloc(out->nodes, out->count * sizeof *out->nodes);
    if (fitted)
        out->nodes = fitted;
    return 0;
}

void sdf__wide_free(sdf__wide *wide)
{
    free(wide->nodes);
    memset(wide, 0, sizeof *wide);
}
