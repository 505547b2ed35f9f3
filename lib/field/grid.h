/* grid.h - the node grid the field operations work on, and the per-node state bits that
 * the re-distancing modules (redist.c, sussman.c, sweep.c) share. A plain float array of
 * node values in the volume's order (x fastest, then y, then z) is a field on it. */
#ifndef SDF_FIELD_GRID_H
#define SDF_FIELD_GRID_H

#include <stddef.h>
#include <stdint.h>

typedef struct sdf__field_grid {
    size_t n[3];     /* nodes along x, y, z, each >= 2 */
    size_t nodes;    /* n[0] n[1] n[2] */
    double h[3];     /* spacing along x, y, z, > 0 */
    double hmin, hmax;
    int threads;     /* as parallel.h takes it: 0 = all CPUs */
} sdf__field_grid;

/* state[] bits of a node during one re-distancing. */
#define SDF__NODE_FROZEN 1u /* next to the zero set: holds its linear-crossing distance */
#define SDF__NODE_ACTIVE 2u /* within the band being solved */
#define SDF__NODE_NEG 4u    /* inside: the initial field is < 0 there */
#define SDF__NODE_STAGE1 8u /* scratch of the band's separable dilation */
#define SDF__NODE_STAGE2 16u

/* Rows (lines along x) are the unit of parallel work: row r is (j, k) = (r % n1, r / n1). */
static inline size_t sdf__field_rows(const sdf__field_grid *g)
{
    return g->n[1] * g->n[2];
}

/* Rows per work item: about 16k nodes, a fraction of a millisecond of any pass. */
static inline size_t sdf__field_row_chunk(const sdf__field_grid *g)
{
    size_t c = 16384 / g->n[0];
    return c ? c : 1;
}

/* fmin / fmax without their NaN rules, which keep GCC from inlining them (no NaN gets
 * here: the volume's values are checked finite). */
static inline double sdf__lo2(double a, double b)
{
    return a < b ? a : b;
}
static inline double sdf__hi2(double a, double b)
{
    return a > b ? a : b;
}

#endif
