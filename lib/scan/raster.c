/* raster.c - the scan's inner loop: one feature's region over the nodes of a call (see
 * raster.h and scan/scan.h). Slices run across the region's thinnest axis, rows across the
 * middle one, each row along its longest; a row's interval comes from the region's planes,
 * and its nodes take the feature's distance as a quadratic along the row. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "core/simd.h"
#include "scan/raster.h"

/* Zero order, distances only: a node that lies inside its winner's region by more than this
 * much of the scene's size (beyond the planes' slack), and off the surface by more than
 * SURE_SIGN_OF_EXTENT, is "sure" (see rows_range in scan/scan.c). Double rounding of the
 * plane values is ~1e-16 of the scene's size; a float pseudonormal's rounding ~1e-7 of an
 * edge's length. */
#define SURE_INSIDE_OF_EXTENT 1e-9
#define SURE_SIGN_OF_EXTENT 1e-6

/* Node index range [lo, hi] of coordinates [from, to] on axis a, widened by the float
 * rounding of the node coordinates (callers compare a node's own coordinate); 0 when empty. */
static int node_range(const sdf__scan *s, int a, double from, double to, size_t first,
                      size_t last, size_t *lo, size_t *hi)
{
    double l = ceil((from - s->origin[a]) * s->inv_spacing[a] - s->index_slack[a]);
    double h = floor((to - s->origin[a]) * s->inv_spacing[a] + s->index_slack[a]);
    if (!(l <= h) || h < (double)first || l > (double)last)
        return 0;
    *lo = l < (double)first ? first : (size_t)l;
    *hi = h > (double)last ? last : (size_t)h;
    return 1;
}

void sdf__fat_prepare(const sdf__scan_call *st, const sdf__region *r, sdf__fat_region *fr)
{
    int w = st->fine_w;
    size_t j = 0; /* x fastest: j = x + w (y + w z) */
    for (int z = 0; z < w; z++)
        for (int y = 0; y < w; y++)
            for (int x = 0; x < w; x++, j++) {
                double dl[3] = {st->fine_offset[0][x], st->fine_offset[1][y],
                                st->fine_offset[2][z]}, c[3];
                for (int a = 0; a < 3; a++)
                    fr->delta[a][j] = dl[a];
                fr->height[j] = sdf__dot3(r->dir, dl);
                fr->side[j] = sdf__dot3(r->sign_dir, dl);
                fr->delta2[j] = sdf__dot3(dl, dl);
                sdf__cross3(c, dl, r->dir);
                fr->cross[0][j] = c[0], fr->cross[1][j] = c[1], fr->cross[2][j] = c[2];
            }
    for (int p = 0; p < r->planes; p++) {
        const double *pl = r->plane[p];
        fr->plane_ready[p] = 0;
        fr->plane_c[p] = pl[3] - sdf__dot3(pl, r->origin);
        fr->plane_lo[p] = fr->plane_hi[p] = 0;
        for (int a = 0; a < 3; a++) { /* separable: the extremes per axis */
            double lo = INFINITY, hi = -INFINITY;
            for (int o = 0; o < w; o++) {
                double v = pl[a] * st->fine_offset[a][o];
                lo = sdf__min2(lo, v), hi = sdf__max2(hi, v);
            }
            fr->plane_lo[p] += lo, fr->plane_hi[p] += hi;
        }
    }
}

/* First order: the region's feature at each fine sample of node idx, into cand (squared
 * distances, negative where the pseudonormal says inside; INFINITY at samples the region
 * does not hold). 0 when it holds none. A plane that holds every sample is not tested per
 * sample. */
SDF__HOT_INLINE int fat_node(const sdf__scan_call *st, const sdf__region *r, sdf__fat_region *fr,
                             float *cand, const size_t idx[3])
{
    size_t m = SDF__POW3(st->fine_w);
    double d[3];
    for (int a = 0; a < 3; a++)
        d[a] = st->scan->coord[a][idx[a]] - r->origin[a];
    int straddling[SDF__REGION_PLANES], count = 0;
    double value[SDF__REGION_PLANES];
    for (int p = 0; p < r->planes; p++) {
        value[p] = sdf__dot3(r->plane[p], d) - fr->plane_c[p];
        if (value[p] + fr->plane_lo[p] > 0)
            return 0; /* no sample in the region */
        if (value[p] + fr->plane_hi[p] > 0)
            straddling[count++] = p;
    }
    double side = sdf__dot3(r->sign_dir, d);
    if (r->kind == SDF__REGION_FACE) {
        double h0 = sdf__dot3(r->dir, d);
        for (size_t j = 0; j < m; j++) {
            double h = h0 + fr->height[j];
            float d2 = (float)(h * h);
            cand[j] = side + fr->side[j] < 0 ? -d2 : d2;
        }
    } else if (r->kind == SDF__REGION_VERTEX) {
        double dd = sdf__dot3(d, d);
        for (size_t j = 0; j < m; j++) {
            double t = d[0] * fr->delta[0][j] + d[1] * fr->delta[1][j] + d[2] * fr->delta[2][j];
            float d2 = (float)(dd + 2 * t + fr->delta2[j]);
            cand[j] = side + fr->side[j] < 0 ? -d2 : d2;
        }
    } else {
        double x0[3];
        sdf__cross3(x0, d, r->dir);
        for (size_t j = 0; j < m; j++) {
            double x = x0[0] + fr->cross[0][j], y = x0[1] + fr->cross[1][j];
            double z = x0[2] + fr->cross[2][j];
            float d2 = (float)(x * x + y * y + z * z);
            cand[j] = side + fr->side[j] < 0 ? -d2 : d2;
        }
    }
    for (int k = 0; k < count; k++) {
        int p = straddling[k];
        double v = value[p], *along = fr->plane_delta[p];
        if (!fr->plane_ready[p]) {
            const double *pl = r->plane[p];
            for (size_t j = 0; j < m; j++)
                along[j] = pl[0] * fr->delta[0][j] + pl[1] * fr->delta[1][j] +
                           pl[2] * fr->delta[2][j];
            fr->plane_ready[p] = 1;
        }
        for (size_t j = 0; j < m; j++) /* branchless, vectorised */
            cand[j] = v + along[j] > 0 ? INFINITY : cand[j];
    }
    return 1;
}

/* First order: the waiting nodes' candidates (see pending_visit) kept where nearer than their
 * samples' bests. */
SDF__HOT_INLINE void offer_fat_pending(float *best, const sdf__fat_region *fr, int held, size_t m)
{
    for (int k = 0; k < held; k++) {
        float *out = best + fr->pending_node[k] * m;
        const float *cand = fr->pending[k];
        for (size_t j = 0; j < m; j++) /* branchless, vectorised */
            out[j] = fabsf(cand[j]) < fabsf(out[j]) ? cand[j] : out[j];
    }
}

/* Zero order: the region's visits wait here (first order: in its sdf__fat_region), their
 * nodes prefetched, and are offered to the nodes' bests SDF__PENDING_VISITS at a time. The
 * bests are a worker's whole copy of the call's nodes, tens of MiB, and each visit's load
 * missed the cache in turn while the region's geometry waited on it (a third of the scan's
 * time, refined_elephant 128^3); apart, the loads overlap each other and the slicing. A
 * region holds each node once, so the order of its offers does not matter. */
typedef struct pending_visit {
    size_t node;
    double d2;
    int8_t sure;
} pending_visit;

SDF__HOT_INLINE void offer_pending(sdf__node_best *best, const pending_visit *pending, int held,
                                   uint32_t feature)
{
    for (int k = 0; k < held; k++) {
        sdf__node_best *nb = &best[pending[k].node];
        double d2 = pending[k].d2;
        if (d2 < nb->d2 || (d2 == nb->d2 && feature < nb->winner))
            nb->d2 = d2, nb->winner = feature, nb->sure = pending[k].sure;
    }
}

/* A slice's cross-section fits this many lattice points or fewer: test each one against the
 * planes instead of computing row intervals (thin prisms cross a slice in a point or two). */
#define FEW_POINTS 12

/* Hand the region's feature to every node of the call it holds. Slices run across the
 * region's thinnest axis A, rows across the middle one B, and each row along its longest C.
 * Compiled for AVX2 as well (core/simd.h): the first order's per-sample loops run 4 doubles
 * or 8 floats to a vector there (refined_elephant 128^3 first order -15 %); without FMA
 * contraction (ISO C), each lane rounds as the scalar code does, so the bits do not depend
 * on the CPU. */
SDF__SIMD_CLONES void sdf__scan_region(const sdf__scan_call *st, const sdf__region *r,
                                       uint32_t feature, sdf__node_best *best,
                                       float *best_samples, sdf__fat_region *fr)
{
    const sdf__scan *s = st->scan;
    double pad = s->feat.row_pad;
    /* How far inside every plane a sure node lies: past the slack, by the margin. */
    double inside_by = s->feat.slack + SURE_INSIDE_OF_EXTENT * s->extent;
    double sign_by = SURE_SIGN_OF_EXTENT * s->extent;
    size_t fr_samples = SDF__POW3(st->fine_w);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    const double *rho = st->rho;
    for (int c = 0; c < r->corners; c++)
        for (int a = 0; a < 3; a++)
            lo[a] = sdf__min2(lo[a], r->corner[c][a]), hi[a] = sdf__max2(hi[a], r->corner[c][a]);
    size_t first[3] = {0, 0, st->k0}, last[3] = {s->dims[0] - 1, s->dims[1] - 1, st->k1 - 1};
    size_t from[3], to[3];
    for (int a = 0; a < 3; a++)
        if (!node_range(s, a, lo[a] - pad - rho[a], hi[a] + pad + rho[a], first[a], last[a],
                        &from[a], &to[a]))
            return;
    int A = 0, C = 0;
    for (int a = 1; a < 3; a++) {
        if (to[a] - from[a] < to[A] - from[A])
            A = a;
        if (to[a] - from[a] >= to[C] - from[C])
            C = a;
    }
    if (A == C)
        C = (A + 1) % 3;
    int B = 3 - A - C;
    /* Planes by the sign of their C component: upper bounds on C, lower bounds, neither;
     * each as (n_A, n_B, n_C, 1 / n_C, c). */
    double pl_sorted[SDF__REGION_PLANES][5], off[SDF__REGION_PLANES];
    int n_up = 0, n_down = 0, n_flat = 0;
    for (int pass = 0; pass < 3; pass++)
        for (int p = 0; p < r->planes; p++) {
            const double *pl = r->plane[p];
            int kind = pl[C] > 1e-12 ? 0 : pl[C] < -1e-12 ? 1 : 2;
            if (kind != pass)
                continue;
            double *o5 = pl_sorted[n_up + n_down + n_flat];
            o5[0] = pl[A], o5[1] = pl[B], o5[2] = pl[C], o5[3] = kind < 2 ? 1 / pl[C] : 0;
            o5[4] = pl[3] + fabs(pl[0]) * rho[0] + fabs(pl[1]) * rho[1] + fabs(pl[2]) * rho[2];
            *(kind == 0 ? &n_up : kind == 1 ? &n_down : &n_flat) += 1;
        }
    const double (*up)[5] = pl_sorted, (*down)[5] = pl_sorted + n_up;
    const double (*flat)[5] = pl_sorted + n_up + n_down;
    /* The region's edges as lines over A: B and C at A = 0 and their slopes (edges lying
     * across A, in one slice, keep both ends). */
    double line[SDF__REGION_EDGES][6];
    for (int e = 0; e < r->edges; e++) {
        const double *c0 = r->corner[r->edge[e][0]], *c1 = r->corner[r->edge[e][1]];
        double *l = line[e];
        l[0] = sdf__min2(c0[A], c1[A]), l[1] = sdf__max2(c0[A], c1[A]);
        if (c0[A] != c1[A]) {
            double sb = (c1[B] - c0[B]) / (c1[A] - c0[A]), sc = (c1[C] - c0[C]) / (c1[A] - c0[A]);
            l[2] = c0[B] - sb * c0[A], l[3] = sb, l[4] = c0[C] - sc * c0[A], l[5] = sc;
        } else {
            l[2] = c0[B], l[3] = c1[B], l[4] = c0[C], l[5] = c1[C];
        }
    }
    size_t stride[3] = {1, s->dims[0], s->dims[0] * s->dims[1]};
    size_t base = st->k0 * stride[2];
    pending_visit pending[SDF__PENDING_VISITS];
    int held = 0;
    const double *o = r->origin;
    for (size_t sa = from[A]; sa <= to[A]; sa++) {
        double ca = s->coord[A][sa];
        /* The slice's cross-section: where it crosses the region's edges (the slice clamped
         * into the region's span, whose planes already carry the slack), padded. */
        double blo = INFINITY, bhi = -INFINITY, clo = INFINITY, chi = -INFINITY;
        for (int end = rho[A] > 0 ? -1 : 1; end <= 1; end += 2) {
            double cq = sdf__min2(sdf__max2(ca + end * rho[A], lo[A]), hi[A]);
            for (int e = 0; e < r->edges; e++) {
                const double *l = line[e];
                if (cq < l[0] || cq > l[1])
                    continue;
                if (l[0] != l[1]) {
                    double b = l[2] + l[3] * cq, c = l[4] + l[5] * cq;
                    blo = sdf__min2(blo, b), bhi = sdf__max2(bhi, b);
                    clo = sdf__min2(clo, c), chi = sdf__max2(chi, c);
                } else {
                    blo = sdf__min2(blo, sdf__min2(l[2], l[3]));
                    bhi = sdf__max2(bhi, sdf__max2(l[2], l[3]));
                    clo = sdf__min2(clo, sdf__min2(l[4], l[5]));
                    chi = sdf__max2(chi, sdf__max2(l[4], l[5]));
                }
            }
        }
        for (int c = 0; rho[A] > 0 && c < r->corners; c++) /* corners between the two ends */
            if (fabs(r->corner[c][A] - ca) <= rho[A]) {
                blo = sdf__min2(blo, r->corner[c][B]), bhi = sdf__max2(bhi, r->corner[c][B]);
                clo = sdf__min2(clo, r->corner[c][C]), chi = sdf__max2(chi, r->corner[c][C]);
            }
        size_t b0, b1, u0, u1;
        if (blo > bhi ||
            !node_range(s, B, blo - pad - rho[B], bhi + pad + rho[B], from[B], to[B], &b0, &b1) ||
            !node_range(s, C, clo - pad - rho[C], chi + pad + rho[C], from[C], to[C], &u0, &u1))
            continue;
        for (int p = 0; p < r->planes; p++) /* the planes' offsets on this slice */
            off[p] = pl_sorted[p][4] - pl_sorted[p][0] * ca;
        const double *off_up = off, *off_down = off + n_up, *off_flat = off + n_up + n_down;
        int few = (b1 - b0 + 1) * (u1 - u0 + 1) <= FEW_POINTS;
        double d[3];
        d[A] = ca - o[A];
        for (size_t sb = b0; sb <= b1; sb++) {
            double cb = s->coord[B][sb], lo_c = -INFINITY, hi_c = INFINITY;
            double lo_sure = -INFINITY, hi_sure = INFINITY; /* the row's sure interval */
            int inside = 1, row_sure = st->distances_only;
            for (int p = 0; p < n_flat; p++) {
                inside &= flat[p][1] * cb <= off_flat[p];
                row_sure &= flat[p][1] * cb <= off_flat[p] - inside_by;
            }
            if (!inside)
                continue;
            size_t v0 = u0, v1 = u1;
            if (!few) { /* the row's interval along C */
                for (int p = 0; p < n_up; p++) {
                    double at = (off_up[p] - up[p][1] * cb) * up[p][3];
                    hi_c = sdf__min2(hi_c, at);
                    hi_sure = sdf__min2(hi_sure, at - inside_by * up[p][3]);
                }
                for (int p = 0; p < n_down; p++) {
                    double at = (off_down[p] - down[p][1] * cb) * down[p][3];
                    lo_c = sdf__max2(lo_c, at);
                    lo_sure = sdf__max2(lo_sure, at - inside_by * down[p][3]);
                }
                if (!node_range(s, C, lo_c, hi_c, u0, u1, &v0, &v1))
                    continue;
            }
            d[B] = cb - o[B];
            d[C] = 0;
            /* The feature's squared distance along the row, a quadratic in the node's C:
             * face (h0 + h1 t)^2, edge |x0 + t x1|^2 (x = d x dir), vertex r0 + t^2. */
            double unit_c[3] = {0, 0, 0}, x0[3] = {0, 0, 0}, x1[3] = {0, 0, 0};
            double h0 = 0, h1 = 0, r0 = 0;
            /* The sign side along the row, (p - origin) . sign_dir = s0 + s1 t. */
            double s0 = sdf__dot3(d, r->sign_dir), s1 = r->sign_dir[C];
            unit_c[C] = 1;
            if (r->kind == SDF__REGION_FACE) {
                h0 = sdf__dot3(d, r->dir), h1 = r->dir[C];
            } else if (r->kind == SDF__REGION_EDGE) {
                sdf__cross3(x0, d, r->dir);
                sdf__cross3(x1, unit_c, r->dir);
            } else {
                r0 = sdf__dot3(d, d);
            }
            size_t row = sa * stride[A] + sb * stride[B] - base;
            for (size_t u = v0; u <= v1; u++) {
                double cc = s->coord[C][u];
                int node_sure = row_sure;
                if (few) { /* the node against every plane */
                    int in = 1;
                    for (int p = 0; p < n_up + n_down; p++) {
                        double v = up[p][1] * cb + up[p][2] * cc - off_up[p];
                        in &= v <= 0;
                        node_sure &= v <= -inside_by;
                    }
                    if (!in)
                        continue;
                } else if (cc < lo_c || cc > hi_c) {
                    continue; /* the node's own coordinate decides */
                } else {
                    node_sure &= cc >= lo_sure && cc <= hi_sure;
                }
                if (st->fine_w) {
                    size_t idx[3], n = row + u * stride[C];
                    idx[A] = sa, idx[B] = sb, idx[C] = u;
                    if (fat_node(st, r, fr, fr->pending[held], idx)) {
                        /* Every cache line of the node's samples: the lines from its
                         * start, and its last byte's, as it need not start on a line. */
                        const char *at = (const char *)(best_samples + n * fr_samples);
                        for (size_t b = 0; b < fr_samples * sizeof(float); b += 64)
                            __builtin_prefetch(at + b, 1);
                        __builtin_prefetch(at + fr_samples * sizeof(float) - 1, 1);
                        fr->pending_node[held++] = n;
                        if (held == SDF__PENDING_VISITS) {
                            offer_fat_pending(best_samples, fr, held, fr_samples);
                            held = 0;
                        }
                    }
                    continue;
                }
                double t = cc - o[C], d2;
                if (r->kind == SDF__REGION_FACE) {
                    double h = h0 + h1 * t;
                    d2 = h * h;
                } else if (r->kind == SDF__REGION_EDGE) {
                    double x = x0[0] + t * x1[0], y = x0[1] + t * x1[1], z = x0[2] + t * x1[2];
                    d2 = x * x + y * y + z * z;
                } else {
                    d2 = r0 + t * t;
                }
                size_t n = row + u * stride[C];
                __builtin_prefetch(&best[n], 1);
                double side = s0 + s1 * t;
                pending[held++] = (pending_visit){
                    n, d2, (int8_t)(!node_sure || fabs(side) <= sign_by ? 0 : side > 0 ? 1 : -1)};
                if (held == SDF__PENDING_VISITS) {
                    offer_pending(best, pending, held, feature);
                    held = 0;
                }
            }
        }
    }
    if (st->fine_w)
        offer_fat_pending(best_samples, fr, held, fr_samples);
    else
        offer_pending(best, pending, held, feature);
}
