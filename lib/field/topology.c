/* topology.c - connected parts of a sign pattern by union-find over face neighbours (see
 * topology.h). One pass links each node to its lower x, y and z neighbour of the same
 * sign; the roots left are the parts. Linear in the nodes, on the calling thread. */
#include "field/topology.h"

static uint32_t find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]]; /* path halving */
        x = parent[x];
    }
    return x;
}

static void link(uint32_t *parent, uint32_t a, uint32_t b)
{
    a = find(parent, a), b = find(parent, b);
    if (a < b)
        parent[b] = a;
    else if (b < a)
        parent[a] = b;
}

void sdf__field_count_parts(const sdf__field_grid *g, const float *phi, uint32_t *labels,
                            sdf__field_parts *out)
{
    size_t n0 = g->n[0], n1 = g->n[1], sy = n0, sz = n0 * n1;
    for (size_t at = 0; at < g->nodes; at++)
        labels[at] = (uint32_t)at;
    for (size_t k = 0, at = 0; k < g->n[2]; k++)
        for (size_t j = 0; j < n1; j++)
            for (size_t i = 0; i < n0; i++, at++) {
                int neg = phi[at] < 0;
                if (i > 0 && (phi[at - 1] < 0) == neg)
                    link(labels, (uint32_t)at, (uint32_t)(at - 1));
                if (j > 0 && (phi[at - sy] < 0) == neg)
                    link(labels, (uint32_t)at, (uint32_t)(at - sy));
                if (k > 0 && (phi[at - sz] < 0) == neg)
                    link(labels, (uint32_t)at, (uint32_t)(at - sz));
            }
    out->inside = out->outside = 0;
    for (size_t at = 0; at < g->nodes; at++)
        if (labels[at] == at) {
            if (phi[at] < 0)
                out->inside++;
            else
                out->outside++;
        }
}
