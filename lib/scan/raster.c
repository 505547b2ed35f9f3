/* raster.c - the scan's inner loop: one feature's region over the nodes of a call (see
 * raster.h and scan/scan.h). Slices run across the region's thinnest axis, rows across the
 * middle one, each row along its longest; a row's interval comes from the region's planes,
 * and its nodes take the feature's distance as a quadratic along the row. */
#include <assert.h>
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
 * missed the cache in turn while the region's geometry waited on it; apart, the loads overlap
 * each other and the slicing. A region holds each node once, so the order of its offers does
 * not matter. */
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

/* One region's scan: what its slices, rows and nodes share. Slices run across the region's
 * thinnest axis A, rows across the middle one B, and each row along its longest C. */
typedef struct region_scan {
    const sdf__scan_call *st;
    const sdf__scan *s;
    const sdf__region *r;
    int A, B, C;
    double lo[3], hi[3];     /* the region's box */
    size_t from[3], to[3];   /* the call's nodes the box may hold, padded */
    double inside_by;        /* how far inside every plane a sure node lies */
    double sign_by;          /* how far off the sign plane a sure node's side is sure */
    /* The planes by the sign of their C component: upper bounds on C, lower bounds,
     * neither; each as (n_A, n_B, n_C, 1 / n_C, c dilated by the fine grid). */
    double plane[SDF__REGION_PLANES][5];
    int n_up, n_down, n_flat;
    /* The region's edges as lines over A: B and C at A = 0 and their slopes (edges lying
     * across A, in one slice, keep both ends). */
    double line[SDF__REGION_EDGES][6];
} region_scan;

/* The region's box and the nodes of the call it may hold; 0 when it holds none. */
SDF__HOT_INLINE int region_extent(region_scan *g)
{
    const sdf__scan *s = g->s;
    const sdf__region *r = g->r;
    const double *rho = g->st->rho;
    double pad = s->feat.row_pad;
    for (int a = 0; a < 3; a++)
        g->lo[a] = INFINITY, g->hi[a] = -INFINITY;
    for (int c = 0; c < r->corners; c++)
        for (int a = 0; a < 3; a++)
            g->lo[a] = sdf__min2(g->lo[a], r->corner[c][a]),
            g->hi[a] = sdf__max2(g->hi[a], r->corner[c][a]);
    size_t first[3] = {0, 0, g->st->k0};
    size_t last[3] = {s->dims[0] - 1, s->dims[1] - 1, g->st->k1 - 1};
    for (int a = 0; a < 3; a++)
        if (!node_range(s, a, g->lo[a] - pad - rho[a], g->hi[a] + pad + rho[a], first[a],
                        last[a], &g->from[a], &g->to[a]))
            return 0;
    return 1;
}

/* Slices across the thinnest span, rows along the longest. */
SDF__HOT_INLINE void pick_axes(region_scan *g)
{
    int A = 0, C = 0;
    for (int a = 1; a < 3; a++) {
        if (g->to[a] - g->from[a] < g->to[A] - g->from[A])
            A = a;
        if (g->to[a] - g->from[a] >= g->to[C] - g->from[C])
            C = a;
    }
    if (A == C)
        C = (A + 1) % 3;
    g->A = A, g->B = 3 - A - C, g->C = C;
    assert(g->A != g->B && g->B != g->C && g->A != g->C);
}

SDF__HOT_INLINE void sort_planes(region_scan *g)
{
    const sdf__region *r = g->r;
    const double *rho = g->st->rho;
    int A = g->A, B = g->B, C = g->C;
    g->n_up = g->n_down = g->n_flat = 0;
    for (int pass = 0; pass < 3; pass++)
        for (int p = 0; p < r->planes; p++) {
            const double *pl = r->plane[p];
            int kind = pl[C] > 1e-12 ? 0 : pl[C] < -1e-12 ? 1 : 2;
            if (kind != pass)
                continue;
            double *o5 = g->plane[g->n_up + g->n_down + g->n_flat];
            o5[0] = pl[A], o5[1] = pl[B], o5[2] = pl[C], o5[3] = kind < 2 ? 1 / pl[C] : 0;
            o5[4] = pl[3] + fabs(pl[0]) * rho[0] + fabs(pl[1]) * rho[1] + fabs(pl[2]) * rho[2];
            *(kind == 0 ? &g->n_up : kind == 1 ? &g->n_down : &g->n_flat) += 1;
        }
    assert(g->n_up + g->n_down + g->n_flat == r->planes);
}

SDF__HOT_INLINE void edge_lines(region_scan *g)
{
    const sdf__region *r = g->r;
    int A = g->A, B = g->B, C = g->C;
    for (int e = 0; e < r->edges; e++) {
        const double *c0 = r->corner[r->edge[e][0]], *c1 = r->corner[r->edge[e][1]];
        double *l = g->line[e];
        l[0] = sdf__min2(c0[A], c1[A]), l[1] = sdf__max2(c0[A], c1[A]);
        if (c0[A] != c1[A]) {
            double sb = (c1[B] - c0[B]) / (c1[A] - c0[A]), sc = (c1[C] - c0[C]) / (c1[A] - c0[A]);
            l[2] = c0[B] - sb * c0[A], l[3] = sb, l[4] = c0[C] - sc * c0[A], l[5] = sc;
        } else {
            l[2] = c0[B], l[3] = c1[B], l[4] = c0[C], l[5] = c1[C];
        }
    }
}

/* The cross-section of the slice at A = ca: where it crosses the region's edges (the slice
 * clamped into the region's span, whose planes already carry the slack), and the corners
 * within the fine grid's reach of it. Its box in B and C, unpadded; lo > hi when empty. */
SDF__HOT_INLINE void slice_section(const region_scan *g, double ca, double blc[4])
{
    const sdf__region *r = g->r;
    const double *rho = g->st->rho;
    int A = g->A, B = g->B, C = g->C;
    double blo = INFINITY, bhi = -INFINITY, clo = INFINITY, chi = -INFINITY;
    for (int end = rho[A] > 0 ? -1 : 1; end <= 1; end += 2) {
        double cq = sdf__min2(sdf__max2(ca + end * rho[A], g->lo[A]), g->hi[A]);
        for (int e = 0; e < r->edges; e++) {
            const double *l = g->line[e];
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
    blc[0] = blo, blc[1] = bhi, blc[2] = clo, blc[3] = chi;
}

/* A row (B = cb) of a slice whose planes sit at offsets `off`: inside the planes parallel
 * to C at all? Then its interval along C and its sure interval, and whether its nodes can be
 * sure at all (distances alone asked for, inside the parallel planes by the margin). */
typedef struct row_span {
    double lo_c, hi_c, lo_sure, hi_sure;
    int sure;
} row_span;

SDF__HOT_INLINE int row_inside(const region_scan *g, const double *off, double cb, int few,
                               row_span *row)
{
    const double (*up)[5] = g->plane, (*down)[5] = g->plane + g->n_up;
    const double (*flat)[5] = g->plane + g->n_up + g->n_down;
    const double *off_up = off, *off_down = off + g->n_up, *off_flat = off + g->n_up + g->n_down;
    *row = (row_span){-INFINITY, INFINITY, -INFINITY, INFINITY, g->st->distances_only};
    int inside = 1;
    for (int p = 0; p < g->n_flat; p++) {
        inside &= flat[p][1] * cb <= off_flat[p];
        row->sure &= flat[p][1] * cb <= off_flat[p] - g->inside_by;
    }
    if (!inside || few)
        return inside;
    for (int p = 0; p < g->n_up; p++) {
        double at = (off_up[p] - up[p][1] * cb) * up[p][3];
        row->hi_c = sdf__min2(row->hi_c, at);
        row->hi_sure = sdf__min2(row->hi_sure, at - g->inside_by * up[p][3]);
    }
    for (int p = 0; p < g->n_down; p++) {
        double at = (off_down[p] - down[p][1] * cb) * down[p][3];
        row->lo_c = sdf__max2(row->lo_c, at);
        row->lo_sure = sdf__max2(row->lo_sure, at - g->inside_by * down[p][3]);
    }
    return 1;
}

/* The feature's squared distance along a row, a quadratic in the node's C offset t: face
 * (h0 + h1 t)^2, edge |x0 + t x1|^2 (x = d x dir), vertex r0 + t^2; and the sign side,
 * (p - origin) . sign_dir = s0 + s1 t. `d` is the row's start less the region's origin. */
typedef struct row_quadratic {
    double x0[3], x1[3];
    double h0, h1, r0, s0, s1;
} row_quadratic;

SDF__HOT_INLINE void row_quadratic_of(const sdf__region *r, const double d[3], int C,
                                      row_quadratic *q)
{
    double unit_c[3] = {0, 0, 0};
    *q = (row_quadratic){.s0 = sdf__dot3(d, r->sign_dir), .s1 = r->sign_dir[C]};
    unit_c[C] = 1;
    if (r->kind == SDF__REGION_FACE) {
        q->h0 = sdf__dot3(d, r->dir), q->h1 = r->dir[C];
    } else if (r->kind == SDF__REGION_EDGE) {
        sdf__cross3(q->x0, d, r->dir);
        sdf__cross3(q->x1, unit_c, r->dir);
    } else {
        q->r0 = sdf__dot3(d, d);
    }
}

SDF__HOT_INLINE double row_d2(const sdf__region *r, const row_quadratic *q, double t)
{
    if (r->kind == SDF__REGION_FACE) {
        double h = q->h0 + q->h1 * t;
        return h * h;
    }
    if (r->kind == SDF__REGION_EDGE) {
        double x = q->x0[0] + t * q->x1[0], y = q->x0[1] + t * q->x1[1],
               z = q->x0[2] + t * q->x1[2];
        return x * x + y * y + z * z;
    }
    return q->r0 + t * t;
}

/* Is node cc of a row (at B = cb) in the region, and sure there (*sure: the row's say on
 * entry)? Few points: against every plane bounding C; else the row's interval decides. */
SDF__HOT_INLINE int node_inside(const region_scan *g, const double *off, const row_span *row,
                                int few, double cb, double cc, int *sure)
{
    if (few) {
        int in = 1;
        for (int p = 0; p < g->n_up + g->n_down; p++) {
            double v = g->plane[p][1] * cb + g->plane[p][2] * cc - off[p];
            in &= v <= 0;
            *sure &= v <= -g->inside_by;
        }
        return in;
    }
    if (cc < row->lo_c || cc > row->hi_c)
        return 0;
    *sure &= cc >= row->lo_sure && cc <= row->hi_sure;
    return 1;
}

/* First order: queue node n (lattice index idx) when the region reaches its fine grid,
 * prefetching every cache line of its samples: the lines from its start, and its last
 * byte's, as it need not start on a line. */
SDF__HOT_INLINE void visit_fine(const sdf__scan_call *st, const sdf__region *r,
                                sdf__fat_region *fr, float *best_samples, size_t fr_samples,
                                const size_t idx[3], size_t n, int *held)
{
    if (!fat_node(st, r, fr, fr->pending[*held], idx))
        return;
    const char *at = (const char *)(best_samples + n * fr_samples);
    for (size_t b = 0; b < fr_samples * sizeof(float); b += 64)
        __builtin_prefetch(at + b, 1);
    __builtin_prefetch(at + fr_samples * sizeof(float) - 1, 1);
    fr->pending_node[(*held)++] = n;
    if (*held == SDF__PENDING_VISITS) {
        offer_fat_pending(best_samples, fr, *held, fr_samples);
        *held = 0;
    }
}

/* Hand the region's feature to every node of the call it holds (region_scan says how the
 * region is sliced). Compiled for AVX2 as well (core/simd.h): the first order's per-sample
 * loops run 4 doubles or 8 floats to a vector there; without FMA contraction (ISO C), each
 * lane rounds as the scalar code does, so the bits do not depend on the CPU. */
SDF__SIMD_CLONES void sdf__scan_region(const sdf__scan_call *st, const sdf__region *r,
                                       uint32_t feature, sdf__node_best *best,
                                       float *best_samples, sdf__fat_region *fr)
{
    const sdf__scan *s = st->scan;
    region_scan g; /* field by field: its tables (~9 KB) are filled before they are read */
    g.st = st, g.s = s, g.r = r;
    g.inside_by = s->feat.slack + SURE_INSIDE_OF_EXTENT * s->extent;
    g.sign_by = SURE_SIGN_OF_EXTENT * s->extent;
    if (!region_extent(&g))
        return;
    pick_axes(&g);
    sort_planes(&g);
    edge_lines(&g);
    int A = g.A, B = g.B, C = g.C;
    double pad = s->feat.row_pad, off[SDF__REGION_PLANES];
    const double *rho = st->rho, *o = r->origin;
    size_t fr_samples = SDF__POW3(st->fine_w);
    size_t stride[3] = {1, s->dims[0], s->dims[0] * s->dims[1]};
    size_t base = st->k0 * stride[2];
    pending_visit pending[SDF__PENDING_VISITS];
    int held = 0;
    for (size_t sa = g.from[A]; sa <= g.to[A]; sa++) {
        double ca = s->coord[A][sa], blc[4];
        slice_section(&g, ca, blc);
        size_t b0, b1, u0, u1;
        if (blc[0] > blc[1] ||
            !node_range(s, B, blc[0] - pad - rho[B], blc[1] + pad + rho[B], g.from[B], g.to[B],
                        &b0, &b1) ||
            !node_range(s, C, blc[2] - pad - rho[C], blc[3] + pad + rho[C], g.from[C], g.to[C],
                        &u0, &u1))
            continue;
        for (int p = 0; p < r->planes; p++) /* the planes' offsets on this slice */
            off[p] = g.plane[p][4] - g.plane[p][0] * ca;
        int few = (b1 - b0 + 1) * (u1 - u0 + 1) <= FEW_POINTS;
        double d[3];
        d[A] = ca - o[A];
        for (size_t sb = b0; sb <= b1; sb++) {
            double cb = s->coord[B][sb];
            row_span row;
            size_t v0 = u0, v1 = u1;
            if (!row_inside(&g, off, cb, few, &row) ||
                (!few && !node_range(s, C, row.lo_c, row.hi_c, u0, u1, &v0, &v1)))
                continue;
            d[B] = cb - o[B];
            d[C] = 0;
            row_quadratic q;
            row_quadratic_of(r, d, C, &q);
            size_t row_at = sa * stride[A] + sb * stride[B] - base;
            for (size_t u = v0; u <= v1; u++) {
                double cc = s->coord[C][u];
                int node_sure = row.sure;
                if (!node_inside(&g, off, &row, few, cb, cc, &node_sure))
                    continue;
                size_t n = row_at + u * stride[C];
                assert(n < st->nodes);
                if (st->fine_w) {
                    size_t idx[3];
                    idx[A] = sa, idx[B] = sb, idx[C] = u;
                    visit_fine(st, r, fr, best_samples, fr_samples, idx, n, &held);
                    continue;
                }
                double t = cc - o[C], d2 = row_d2(r, &q, t);
                __builtin_prefetch(&best[n], 1);
                double side = q.s0 + q.s1 * t;
                pending[held++] = (pending_visit){
                    n, d2, (int8_t)(!node_sure || fabs(side) <= g.sign_by ? 0 : side > 0 ? 1 : -1)};
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
