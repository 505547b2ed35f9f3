/* hermite.c - the tricubic Hermite reconstruction of first-order volumes, with node values
 * limited by the neighbours' closest points (why: hermite.h). */
#include "volume/hermite.h"

#include <math.h>

/* A limited value is taken only when it is shorter by more than rounding, so a plane field
 * (every candidate at least the node's own distance in exact arithmetic) keeps its bits. */
#define LIMIT_MARGIN (1 - 1e-12)

void sdf__hermite_locate(double p, double origin, double spacing, size_t dim,
                         sdf__hermite_axis *out)
{
    double u = (p - origin) / spacing, last = (double)(dim - 1);
    double(*b)[2] = out->basis, (*db)[2] = out->dbasis;
    for (int c = 0; c < 2; c++)
        b[c][0] = b[c][1] = db[c][0] = db[c][1] = 0;
    if (u < 0) {
        out->cell = 0;
        b[0][0] = 1, b[0][1] = p - origin, db[0][1] = 1;
    } else if (u > last) {
        out->cell = dim - 2;
        b[1][0] = 1, b[1][1] = p - (origin + last * spacing), db[1][1] = 1;
    } else {
        out->cell = u < (double)(dim - 2) ? (size_t)u : dim - 2;
        double t = u - (double)out->cell, t2 = t * t, t3 = t2 * t, h = spacing;
        b[0][0] = 1 - 3 * t2 + 2 * t3, b[1][0] = 3 * t2 - 2 * t3;
        b[0][1] = h * (t - 2 * t2 + t3), b[1][1] = h * (t3 - t2);
        db[0][0] = 6 * (t2 - t) / h, db[1][0] = -db[0][0];
        db[0][1] = 1 - 4 * t + 3 * t2, db[1][1] = 3 * t2 - 2 * t;
    }
    for (int r = 0; r < 4; r++) {
        size_t n = out->cell + (size_t)r;
        n = n == 0 ? 0 : n - 1; /* row r is node cell + r - 1 */
        out->node[r] = n < dim ? n : dim - 1;
        out->pos[r] = origin + (double)out->node[r] * spacing;
    }
}

static int block(int x, int y, int z) { return (z * 4 + y) * 4 + x; }

/* Node values and the feet of the nodes' planes (valid where the gradient is not zero). */
typedef struct block_nodes {
    double value[64], foot[64][3];
    int has_foot[64];
} block_nodes;

static void block_values(const sdf__hermite_axis ax[3], const double planes[64][4],
                         block_nodes *out)
{
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++) {
                int b = block(x, y, z);
                const double *pl = planes[b], at[3] = {ax[0].pos[x], ax[1].pos[y], ax[2].pos[z]};
                double v = pl[0] * at[0] + pl[1] * at[1] + pl[2] * at[2] + pl[3];
                double l2 = pl[0] * pl[0] + pl[1] * pl[1] + pl[2] * pl[2];
                out->value[b] = v;
                out->has_foot[b] = l2 > 0;
                for (int a = 0; a < 3; a++)
                    out->foot[b][a] = l2 > 0 ? at[a] - v * pl[a] / l2 : 0;
            }
}

/* The value of the node at block (x, y, z) (each 1 or 2), its distance to its own zero set
 * limited by the distances to its 26 neighbours' feet. */
static double limited_value(const sdf__hermite_axis ax[3], const double planes[64][4],
                            const block_nodes *bn, int x, int y, int z)
{
    int self = block(x, y, z);
    const double *pl = planes[self];
    double v = bn->value[self], len = sqrt(pl[0] * pl[0] + pl[1] * pl[1] + pl[2] * pl[2]);
    if (!(len > 0))
        return v;
    double own = fabs(v) / len, best2 = own * own;
    const double at[3] = {ax[0].pos[x], ax[1].pos[y], ax[2].pos[z]};
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int m = block(x + dx, y + dy, z + dz);
                /* rows repeat at the volume's ends: the same node is no neighbour */
                if (!bn->has_foot[m] || (ax[0].node[x + dx] == ax[0].node[x] &&
                                         ax[1].node[y + dy] == ax[1].node[y] &&
                                         ax[2].node[z + dz] == ax[2].node[z]))
                    continue;
                double e2 = 0;
                for (int a = 0; a < 3; a++) {
                    double e = at[a] - bn->foot[m][a];
                    e2 += e * e;
                }
                if (e2 < best2)
                    best2 = e2;
            }
    double best = sqrt(best2);
    return best < own * LIMIT_MARGIN ? copysign(best * len, v) : v;
}

/* Difference of gradient component `comp` between block rows lo and hi along axis `axis`
 * (the other two rows fixed at r), over their distance. */
static double difference(const sdf__hermite_axis ax[3], const double planes[64][4],
                         const int r[3], int axis, int comp)
{
    int lo[3] = {r[0], r[1], r[2]}, hi[3] = {r[0], r[1], r[2]};
    lo[axis]--, hi[axis]++;
    double h = ax[axis].pos[hi[axis]] - ax[axis].pos[lo[axis]];
    return (planes[block(hi[0], hi[1], hi[2])][comp] - planes[block(lo[0], lo[1], lo[2])][comp]) /
           h;
}

/* Mixed second difference of component `comp` along axes a1 and a2 at rows r. */
static double difference2(const sdf__hermite_axis ax[3], const double planes[64][4],
                          const int r[3], int a1, int a2, int comp)
{
    int lo[3] = {r[0], r[1], r[2]}, hi[3] = {r[0], r[1], r[2]};
    lo[a1]--, hi[a1]++;
    double h = ax[a1].pos[hi[a1]] - ax[a1].pos[lo[a1]];
    return (difference(ax, planes, hi, a2, comp) - difference(ax, planes, lo, a2, comp)) / h;
}

/* The Hermite data of the corner at block rows r: index bit 0 / 1 / 2 set = differentiated
 * along x / y / z (f, f_x, f_y, f_xy, f_z, f_xz, f_yz, f_xyz). Central differences at rows
 * 1 and 2 reach rows 0..3; where a row repeats at the volume's end they are one-sided. */
static void corner_data(const sdf__hermite_axis ax[3], const double planes[64][4],
                        const block_nodes *bn, int limit, const int r[3], double D[8])
{
    const double *pl = planes[block(r[0], r[1], r[2])];
    D[0] = limit ? limited_value(ax, planes, bn, r[0], r[1], r[2])
                 : bn->value[block(r[0], r[1], r[2])];
    D[1] = pl[0], D[2] = pl[1], D[4] = pl[2];
    D[3] = 0.5 * (difference(ax, planes, r, 1, 0) + difference(ax, planes, r, 0, 1));
    D[5] = 0.5 * (difference(ax, planes, r, 2, 0) + difference(ax, planes, r, 0, 2));
    D[6] = 0.5 * (difference(ax, planes, r, 2, 1) + difference(ax, planes, r, 1, 2));
    D[7] = (difference2(ax, planes, r, 1, 2, 0) + difference2(ax, planes, r, 0, 2, 1) +
            difference2(ax, planes, r, 0, 1, 2)) / 3;
}

void sdf__hermite_eval(const sdf__hermite_axis ax[3], const double planes[64][4], int limit,
                       double *value, double grad[3])
{
    block_nodes bn;
    block_values(ax, planes, &bn);
    double sum = 0, g[3] = {0, 0, 0};
    for (int c = 0; c < 8; c++) {
        int bit[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
        int r[3] = {1 + bit[0], 1 + bit[1], 1 + bit[2]};
        double D[8];
        corner_data(ax, planes, &bn, limit, r, D);
        for (int k = 0; k < 8; k++) {
            int e[3] = {k & 1, (k >> 1) & 1, (k >> 2) & 1};
            double bx = ax[0].basis[bit[0]][e[0]], by = ax[1].basis[bit[1]][e[1]],
                   bz = ax[2].basis[bit[2]][e[2]];
            sum += bx * by * bz * D[k];
            g[0] += ax[0].dbasis[bit[0]][e[0]] * by * bz * D[k];
            g[1] += bx * ax[1].dbasis[bit[1]][e[1]] * bz * D[k];
            g[2] += bx * by * ax[2].dbasis[bit[2]][e[2]] * D[k];
        }
    }
    *value = sum;
    grad[0] = g[0], grad[1] = g[1], grad[2] = g[2];
}
