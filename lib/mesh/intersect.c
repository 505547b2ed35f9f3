/* intersect.c - self-intersection search (see intersect.h). */
#include "mesh/intersect.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>

#include "core/grow.h"
#include "core/parallel.h"
#include "sdf/sdf.h"

/* A triangle as the search first sees it, in the tree's primitive order (a leaf's are
 * consecutive): its box and corner ids. Most pairs of triangles end there. */
typedef struct prim_box {
    float lo[3], hi[3];
    uint32_t idx[3];
} prim_box;

/* A leaf's triangles' corners in double, converted once a pair needs orientation tests. */
typedef struct leaf_corners {
    uint32_t loaded; /* bit i: v[i] is filled */
    double v[SDF__TREE_MAX_LEAF][3][3];
} leaf_corners;

static const double (*corners(leaf_corners *c, const float *pos, const prim_box *b, int i))[3]
{
    if (!(c->loaded >> i & 1)) {
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                c->v[i][k][a] = pos[3 * (size_t)b->idx[k] + a];
        c->loaded |= 1u << i;
    }
    return c->v[i];
}

/* Sign of the volume of tetrahedron (a, b, c, d): which side of plane abc d lies on; 0 when
 * double precision cannot tell. Shewchuk's orient3d with his static error bound
 * ("Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric Predicates",
 * 1997): a determinant within (7 + 56 eps) eps times the permanent of its terms may have
 * the wrong sign, so it counts as coplanar. Without this, flat CAD regions full of
 * coplanar triangles report rounding noise as crossings. */
static int orient(const double a[3], const double b[3], const double c[3], const double d[3])
{
    const double eps = 0x1p-53, bound = (7.0 + 56.0 * eps) * eps;
    double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
    double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
    double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
    double bc = bdx * cdy - cdx * bdy, ca = cdx * ady - adx * cdy, ab = adx * bdy - bdx * ady;
    double det = adz * bc + bdz * ca + cdz * ab;
    double permanent = (fabs(bdx * cdy) + fabs(cdx * bdy)) * fabs(adz) +
                       (fabs(cdx * ady) + fabs(adx * cdy)) * fabs(bdz) +
                       (fabs(adx * bdy) + fabs(bdx * ady)) * fabs(cdz);
    if (det > bound * permanent)
        return 1;
    if (-det > bound * permanent)
        return -1;
    return 0;
}

/* Does segment pq meet triangle t? Touching counts (an edge through another triangle's edge
 * or vertex): for the sign, a contact breaks pseudonormals as surely as a crossing. A
 * segment lying in the triangle's plane is not reported. */
static int segment_crosses(const double p[3], const double q[3], const double (*t)[3])
{
    const double *a = t[0], *b = t[1], *c = t[2];
    int sp = orient(a, b, c, p), sq = orient(a, b, c, q);
    if (sp == sq) /* same side, or coplanar */
        return 0;
    int s1 = orient(p, q, a, b), s2 = orient(p, q, b, c), s3 = orient(p, q, c, a);
    int lo = s1 < s2 ? (s1 < s3 ? s1 : s3) : (s2 < s3 ? s2 : s3);
    int hi = s1 > s2 ? (s1 > s3 ? s1 : s3) : (s2 > s3 ? s2 : s3);
    return (lo >= 0 || hi <= 0) && (lo != 0 || hi != 0);
}

static int shares_vertex(const prim_box *a, const prim_box *b)
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (a->idx[i] == b->idx[j])
                return 1;
    return 0;
}

/* Triangles a and b, whose boxes overlap (ca, cb: their leaves' corner caches, i and j
 * their places there). */
static int triangles_intersect(const float *pos, const prim_box *a, const prim_box *b,
                               leaf_corners *ca, int i, leaf_corners *cb, int j)
{
    if (shares_vertex(a, b))
        return 0;
    const double(*u)[3] = corners(ca, pos, a, i), (*v)[3] = corners(cb, pos, b, j);
    for (int k = 0; k < 3; k++) {
        if (segment_crosses(u[k], u[(k + 1) % 3], v) || segment_crosses(v[k], v[(k + 1) % 3], u))
            return 1;
    }
    return 0;
}

/* Bit j set where box a overlaps ys[j]'s, j in [from, count): without branches, since
 * whether two neighbouring triangles' boxes overlap is a coin toss to the predictor. */
static uint32_t overlapping(const prim_box *a, const prim_box *ys, uint32_t from, uint32_t count)
{
    uint32_t mask = 0;
    for (uint32_t j = from; j < count; j++) {
        const prim_box *b = &ys[j];
        int apart = (a->hi[0] < b->lo[0]) | (b->hi[0] < a->lo[0]) | (a->hi[1] < b->lo[1]) |
                    (b->hi[1] < a->lo[1]) | (a->hi[2] < b->lo[2]) | (b->hi[2] < a->lo[2]);
        mask |= (uint32_t)!apart << j;
    }
    return mask;
}

static int leaves_intersect(const prim_box *boxes, const float *pos, const sdf__tree_node *x,
                            const sdf__tree_node *y)
{
    leaf_corners a, b;
    a.loaded = b.loaded = 0;
    leaf_corners *cb = x == y ? &a : &b;
    const prim_box *xs = boxes + x->first, *ys = boxes + y->first;
    for (uint32_t i = 0; i < x->count; i++)
        for (uint32_t m = overlapping(&xs[i], ys, x == y ? i + 1 : 0, y->count); m; m &= m - 1) {
            int j = __builtin_ctz(m);
            if (triangles_intersect(pos, &xs[i], &ys[j], &a, (int)i, cb, j))
                return 1;
        }
    return 0;
}

static int boxes_overlap(const sdf__tree_node *a, const sdf__tree_node *b)
{
    for (int i = 0; i < 3; i++)
        if (a->hi[i] < b->lo[i] || b->hi[i] < a->lo[i])
            return 0;
    return 1;
}

typedef struct pair {
    uint32_t a, b;
} pair;

typedef struct pair_stack {
    pair *items;
    size_t count, cap;
} pair_stack;

static int push(pair_stack *s, uint32_t a, uint32_t b)
{
    if (sdf__grow((void **)&s->items, &s->cap, s->count + 1, sizeof *s->items))
        return SDF_ENOMEM;
    s->items[s->count++] = (pair){a, b};
    return 0;
}

/* Expand one pair into the pairs of children that still need a look. */
static int expand(pair_stack *s, const sdf__tree *tree, pair p)
{
    const sdf__tree_node *x = &tree->nodes[p.a], *y = &tree->nodes[p.b];
    if (p.a == p.b) { /* a node against itself: both children, and them against each other */
        uint32_t l = x->first, r = x->first + 1;
        return push(s, l, l) || push(s, r, r) || push(s, l, r) ? SDF_ENOMEM : 0;
    }
    /* Split the inner node, or the bigger one when both are inner. */
    int split_a = y->count || (!x->count && (x->hi[0] - x->lo[0]) + (x->hi[1] - x->lo[1]) +
                                                    (x->hi[2] - x->lo[2]) >=
                                                (y->hi[0] - y->lo[0]) + (y->hi[1] - y->lo[1]) +
                                                    (y->hi[2] - y->lo[2]));
    uint32_t inner = split_a ? p.a : p.b, other = split_a ? p.b : p.a;
    uint32_t first = tree->nodes[inner].first;
    return push(s, first, other) || push(s, first + 1, other) ? SDF_ENOMEM : 0;
}

typedef struct search {
    const sdf__tree *tree;
    const float *positions;
    const uint32_t *triangles;
    prim_box *boxes; /* tree->prims[i]'s box and corner ids at boxes[i] */
    const pair *tasks;
    atomic_int found; /* 1: an intersection; SDF_ENOMEM: a thread ran out of memory */
} search;

/* Search below one pair with a private stack until an intersection turns up here or in
 * another thread. Returns 1, 0, or SDF_ENOMEM. */
static int search_pair(search *sr, pair start)
{
    const sdf__tree *tree = sr->tree;
    pair_stack s = {0};
    int rc = push(&s, start.a, start.b);
    while (!rc && s.count && !atomic_load_explicit(&sr->found, memory_order_relaxed)) {
        pair p = s.items[--s.count];
        const sdf__tree_node *x = &tree->nodes[p.a], *y = &tree->nodes[p.b];
        if (p.a != p.b && !boxes_overlap(x, y))
            continue;
        if (x->count && y->count)
            rc = leaves_intersect(sr->boxes, sr->positions, x, y);
        else
            rc = expand(&s, tree, p);
    }
    free(s.items);
    return rc;
}

static void search_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    search *sr = ctx;
    for (size_t i = begin; i < end && !atomic_load(&sr->found); i++) {
        int rc = search_pair(sr, sr->tasks[i]);
        if (rc) {
            int none = 0;
            atomic_compare_exchange_strong(&sr->found, &none, rc);
        }
    }
}

/* The primitives' boxes and corner ids, in the tree's order. */
static void boxes_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    search *sr = ctx;
    for (size_t i = begin; i < end; i++) {
        prim_box *b = &sr->boxes[i];
        const uint32_t *t = sr->triangles + 3 * (size_t)sr->tree->prims[i];
        const float *c[3];
        for (int k = 0; k < 3; k++) {
            b->idx[k] = t[k];
            c[k] = sr->positions + 3 * (size_t)t[k];
        }
        for (int a = 0; a < 3; a++) {
            b->lo[a] = c[0][a] < c[1][a] ? c[0][a] : c[1][a];
            b->lo[a] = c[2][a] < b->lo[a] ? c[2][a] : b->lo[a];
            b->hi[a] = c[0][a] > c[1][a] ? c[0][a] : c[1][a];
            b->hi[a] = c[2][a] > b->hi[a] ? c[2][a] : b->hi[a];
        }
    }
}

/* The top of the search runs here until there are enough independent pairs to share out;
 * the rest runs on every CPU. */
#define PARALLEL_TASKS 256

int sdf__self_intersects(const sdf__tree *tree, const float *positions, const uint32_t *triangles)
{
    pair_stack top = {0}, tasks = {0};
    int rc = push(&top, 0, 0);
    size_t next = 0; /* breadth first: top.items[next..] wait their turn */
    while (!rc && next < top.count && top.count - next + tasks.count < PARALLEL_TASKS) {
        pair p = top.items[next++];
        const sdf__tree_node *x = &tree->nodes[p.a], *y = &tree->nodes[p.b];
        if (p.a != p.b && !boxes_overlap(x, y))
            continue;
        if (x->count && y->count) /* a pair of leaves is a task of its own */
            rc = push(&tasks, p.a, p.b);
        else
            rc = expand(&top, tree, p);
    }
    for (size_t i = next; !rc && i < top.count; i++)
        rc = push(&tasks, top.items[i].a, top.items[i].b);
    free(top.items);
    if (rc) {
        free(tasks.items);
        return rc;
    }
    search sr = {tree, positions, triangles, malloc((tree->prim_count + 1) * sizeof(prim_box)),
                 tasks.items, 0};
    if (!sr.boxes) {
        free(tasks.items);
        return SDF_ENOMEM;
    }
    sdf__parallel_for(tree->prim_count, 16384, 0, boxes_range, &sr);
    sdf__parallel_for(tasks.count, 1, 0, search_range, &sr);
    free(sr.boxes);
    free(tasks.items);
    return atomic_load(&sr.found);
}
