/* scan.c - closest-feature scan conversion of a volume's lattice (see scan.h).
 *
 * Features are numbered faces first, then edges (the mesh's edge ids), then vertices. Each
 * feature's region is built as a convex polyhedron twice over: as half-spaces n . p <= c,
 * which decide which nodes of a lattice row it holds, and as corners and edges, whose
 * crossings with a slice give the range of rows to visit. Regions reach only as far as any
 * node can be from the surface (`reach_front` on the outward side, `reach_back` inside),
 * which a coarse lattice of exact queries bounds. Worker threads take runs of features in
 * Morton order, each into its own per-node "best so far" arrays (no locks); the rows are
 * then finished in parallel, the workers' bests merged by (distance, feature id) so the
 * result does not depend on how the features were shared out. */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/embree.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "mesh/mesh.h"
#include "mesh/topology.h"
#include "volume/regions.h"
#include "query/filter.h"
#include "query/packet.h"
#include "query/triangle.h"
#include "volume/scan.h"

#define COARSE_STEP 8      /* nodes between the coarse lattice's nodes */
#define FEATURE_CHUNK 256  /* features per work item */
#define SCAN_BUDGET_BYTES ((size_t)64 << 20) /* the workers' per-node arrays of one call */
#define MERGE_NODES 256    /* nodes per sdf__sample_fn call */
#define SCAN_SLICE_LIMIT ((size_t)256 << 20) /* most scratch bytes one z-slice may take */
/* The same, first order: fewer calls rebuild fewer regions that span several (refined_elephant
 * 128^3: 64 MiB 1.57-1.63 s, 128 MiB 1.46-1.49, 256 MiB 1.42-1.48). */
#define SCAN_SAMPLE_BUDGET_BYTES ((size_t)128 << 20)
#define MAX_W (2 * 4 + 1)  /* first order: the fine grid's width, H <= 4 */
#define MAX_SAMPLES (MAX_W * MAX_W * MAX_W)
#define POW3(w) ((size_t)(w) * (size_t)(w) * (size_t)(w))
/* Zero order, distances only: a node that lies inside its winner's region by more than this
 * much of the scene's size (beyond the planes' slack), and off the surface by more than
 * SURE_SIGN_OF_EXTENT, is "sure" (see rows_range). Double rounding of the plane values is
 * ~1e-16 of the scene's size; a float pseudonormal's rounding ~1e-7 of an edge's length. */
#define SURE_INSIDE_OF_EXTENT 1e-9
#define SURE_SIGN_OF_EXTENT 1e-6
/* The region's estimate and the exact test's distance both lie within this much of the
 * scene's size of the true distance. */
#define SURE_DISTANCE_OF_EXTENT 1e-13

struct sdf__scan {
    const sdf_mesh *mesh;
    sdf_query_options query;
    size_t dims[3];
    double origin[3], spacing[3];
    double *coord[3];          /* node coordinates per axis, as the float points sdf_query gets */
    sdf__features feat;
    double *coarse_coord[3];   /* the coarse lattice's node coordinates (feat.bound_coord) */
    uint32_t *order;           /* features in Morton order of their positions: neighbours in
                                  this order write to nearby nodes, so the per-node arrays stay
                                  in cache */
    float *coarse;             /* |f| on every COARSE_STEP-th node (feat.bound) */
    float *sample_scratch;     /* sdf__scan_samples' per-worker bests, kept between calls */
    float *zspan;              /* per feature its region's z-span (NAN: none), or NULL */
    size_t sample_scratch_count;
    double inv_spacing[3];
    double index_slack[3];     /* float rounding of node coordinates, in nodes */
    double extent;             /* the scene's size: the scale of every rounding margin */
};

/* ---- scanning ---------------------------------------------------------------------------- */

typedef struct fat_region fat_region;

/* Zero order: a node's best so far, in one place (the scan is bound by these loads: apart,
 * the three fields were three cache lines). */
typedef struct node_best {
    double d2;       /* smallest squared distance so far */
    uint32_t winner; /* its feature (ties: the lowest id, so the merge is deterministic) */
    int8_t sure;     /* with distances alone asked for: the winner's sign (+-1) when the node
                        is sure in its region (rows_range), else 0 */
} node_best;

typedef struct call_state {
    sdf__scan *scan;
    size_t k0, k1;     /* the call's slices */
    size_t nodes;      /* in the call */
    node_best *best;   /* per worker and node */
    int distances_only; /* sure nodes are marked (node_best.sure) */
    sdf__region *regions; /* per worker: the region being scanned */
    float *points;     /* per worker: a row of nodes */
    sdf__hit *hits;    /* per worker: their closest points */
    uint32_t *slow;    /* per worker: a row's nodes that take the exact test */
    float *slow_out;   /* per worker: their distances */
    int workers;
    sdf_query_result out;  /* zero order: the outputs, at the call's first node */
    /* First order (sdf__scan_samples): a node stands for its fine grid of W^3 samples. */
    int fine_w;            /* W = 2H + 1; 0 for zero order */
    double rho[3];         /* the fine grid's half-extent per axis: regions are dilated by it */
    double fine_offset[3][MAX_W]; /* per axis, the W offsets of the fine grid */
    fat_region *fat;       /* per worker */
    float *sample_best;    /* per worker, node and sample: the smallest squared distance so
                              far, negative where its feature's pseudonormal says inside */
    float *merged;         /* per worker: MERGE_NODES nodes' signed distances */
    sdf__sample_fn consume;
    void *user;
    int consume_rc[SDF__MAX_THREADS];
} call_state;

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

/* First order: what a region needs at every fine offset delta_j, once per region (the fine
 * grid is the same around every node). Samples sit at the float node plus delta_j, in
 * double: their distances are exact there, and within float rounding of the points a query
 * would be asked at. */
struct fat_region {
    double height[MAX_SAMPLES]; /* face: dir . delta */
    double side[MAX_SAMPLES];   /* sign_dir . delta */
    double delta[3][MAX_SAMPLES];
    double delta2[MAX_SAMPLES]; /* vertex: |delta|^2 */
    double cross[3][MAX_SAMPLES]; /* edge: delta x dir */
    double plane_c[SDF__REGION_PLANES]; /* planes n . (p - origin) <= c */
    double plane_lo[SDF__REGION_PLANES], plane_hi[SDF__REGION_PLANES]; /* n . delta's range */
    /* n . delta_j of plane p, made the first time p straddles a node's fine grid. */
    uint8_t plane_ready[SDF__REGION_PLANES];
    double plane_delta[SDF__REGION_PLANES][MAX_SAMPLES];
    float cand[MAX_SAMPLES];
};

static void fat_prepare(const call_state *st, const sdf__region *r, fat_region *fr)
{
    int w = st->fine_w;
    size_t m = POW3(w);
    for (size_t j = 0; j < m; j++) {
        size_t o[3] = {j % (size_t)w, j / (size_t)w % (size_t)w, j / (size_t)w / (size_t)w};
        double dl[3], c[3];
        for (int a = 0; a < 3; a++)
            dl[a] = fr->delta[a][j] = st->fine_offset[a][o[a]];
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

/* First order: the region's feature at each fine sample of node idx that the region holds,
 * kept where nearer than the sample's best so far (signed by the pseudonormal). A plane that
 * holds every sample is not tested per sample. */
SDF__HOT_INLINE void fat_node(const call_state *st, const sdf__region *r, fat_region *fr,
                              float *best, size_t n, const size_t idx[3])
{
    size_t m = POW3(st->fine_w);
    double d[3];
    for (int a = 0; a < 3; a++)
        d[a] = st->scan->coord[a][idx[a]] - r->origin[a];
    int straddling[SDF__REGION_PLANES], count = 0;
    double value[SDF__REGION_PLANES];
    for (int p = 0; p < r->planes; p++) {
        value[p] = sdf__dot3(r->plane[p], d) - fr->plane_c[p];
        if (value[p] + fr->plane_lo[p] > 0)
            return; /* no sample in the region */
        if (value[p] + fr->plane_hi[p] > 0)
            straddling[count++] = p;
    }
    double side = sdf__dot3(r->sign_dir, d);
    float *cand = fr->cand;
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
    float *out = best + n * m;
    for (size_t j = 0; j < m; j++) /* branchless, vectorised */
        out[j] = fabsf(cand[j]) < fabsf(out[j]) ? cand[j] : out[j];
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
SDF__SIMD_CLONES static void scan_region(const call_state *st, const sdf__region *r,
                                         uint32_t feature, node_best *best,
                                         float *best_samples, fat_region *fr)
{
    const sdf__scan *s = st->scan;
    double pad = s->feat.row_pad;
    /* How far inside every plane a sure node lies: past the slack, by the margin. */
    double inside_by = s->feat.slack + SURE_INSIDE_OF_EXTENT * s->extent;
    double sign_by = SURE_SIGN_OF_EXTENT * s->extent;
    size_t fr_samples = POW3(st->fine_w);
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
                    size_t idx[3];
                    idx[A] = sa, idx[B] = sb, idx[C] = u;
                    if (u < v1) { /* the next node's bests: rows run along any axis, at
                                   * a stride the hardware's prefetcher does not follow */
                        const float *next = best_samples + (row + (u + 1) * stride[C]) * fr_samples;
                        __builtin_prefetch(next);
                        __builtin_prefetch(next + 16);
                    }
                    fat_node(st, r, fr, best_samples, row + u * stride[C], idx);
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
                node_best *nb = &best[n];
                if (d2 < nb->d2 || (d2 == nb->d2 && feature < nb->winner)) {
                    double side = s0 + s1 * t;
                    nb->d2 = d2, nb->winner = feature;
                    nb->sure = (int8_t)(!node_sure || fabs(side) <= sign_by ? 0
                                        : side > 0 ? 1 : -1);
                }
            }
        }
    }
}

static void features_range(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    sdf__region *r = &st->regions[worker];
    size_t mine = (size_t)worker * st->nodes;
    node_best *best = st->best ? st->best + mine : NULL;
    float *samples = st->sample_best ? st->sample_best + mine * POW3(st->fine_w) : NULL;
    const sdf__scan *s = st->scan;
    /* The call's z-span, widened by the dilation and padding: regions wholly outside it are
     * not built (when their spans are known). */
    double z0 = s->coord[2][st->k0] - st->rho[2] - s->feat.row_pad;
    double z1 = s->coord[2][st->k1 - 1] + st->rho[2] + s->feat.row_pad;
    for (size_t q = begin; q < end; q++) {
        uint32_t f = s->order[q];
        if (s->zspan && (s->zspan[2 * f] > z1 || s->zspan[2 * f + 1] < z0))
            continue;
        if (!sdf__region_build(&s->feat, f, r))
            continue;
        fat_region *fr = st->fine_w ? &st->fat[worker] : NULL;
        if (fr)
            fat_prepare(st, r, fr);
        scan_region(st, r, f, best, samples, fr);
    }
}

/* The z-span of every feature's region (NAN..NAN for none), once, for bakes in several
 * calls. */
static void zspan_range(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    sdf__region *r = &st->regions[worker];
    float *span = st->scan->zspan;
    for (size_t f = begin; f < end; f++) {
        span[2 * f] = span[2 * f + 1] = NAN;
        if (!sdf__region_build(&st->scan->feat, f, r))
            continue;
        double lo = INFINITY, hi = -INFINITY;
        for (int c = 0; c < r->corners; c++)
            lo = sdf__min2(lo, r->corner[c][2]), hi = sdf__max2(hi, r->corner[c][2]);
        /* Rounded outwards to float. */
        span[2 * f] = nextafterf((float)lo, -INFINITY);
        span[2 * f + 1] = nextafterf((float)hi, INFINITY);
    }
}

/* Known spans let the calls of a bake in several calls skip the regions outside them. */
static int ensure_zspans(sdf__scan *s, call_state *st)
{
    if (s->zspan || (st->k0 == 0 && st->k1 == s->dims[2]))
        return 0;
    float *span = malloc((2 * s->feat.count + 1) * sizeof *span);
    if (!span)
        return SDF_ENOMEM;
    s->zspan = span;
    sdf__parallel_for(s->feat.count, FEATURE_CHUNK, st->workers, zspan_range, st);
    return 0;
}

/* The exact test of the triangles in `list`, kept in *hit where nearer (ties: the lower id,
 * the searches' rule: query/triangle.h). */
static void exact_tests(const sdf__scan *s, const uint32_t *list, size_t count, const double p[3],
                        sdf__hit *hit)
{
    for (size_t c = 0; c < count; c++)
        sdf__triangle_offer(s->mesh->positions, s->mesh->triangles, list[c], p, hit);
}

/* The exact closest point on a triangle of the winning feature: the face itself; of an
 * edge's triangles, the nearer (each computes the shared point from its own corners, and the
 * two may round apart; ties: the lower id); of a vertex's, the lowest-numbered (each computes
 * the vertex itself: the same distance). The distance is the one a search finds; at such an
 * exact tie a search may name another of the triangles, as packets and single queries do. */
static void exact_hit(const sdf__scan *s, uint32_t feature, const double p[3], sdf__hit *hit)
{
    const sdf__features *f = &s->feat;
    uint32_t one = sdf__feature_triangle(f, feature);
    hit->dist2 = INFINITY;
    if (feature >= f->faces && feature < f->faces + f->edges) {
        size_t e = feature - f->faces;
        exact_tests(s, f->edge_tri + f->edge_first[e], f->edge_first[e + 1] - f->edge_first[e],
                    p, hit);
    } else {
        exact_tests(s, &one, 1, p, hit);
    }
}

/* A sure node's float distance without the exact test: inside its winner's region (past the
 * slack), the region's estimate is that feature's exact distance, and no region's estimate
 * is below its own feature's distance, so the winner is a closest feature; off the surface,
 * its pseudonormal's side is sdf_query's sign. The float is sdf_query's own when every
 * distance within SURE_DISTANCE_OF_EXTENT of the estimate rounds to it (the exact test's
 * lies there); else NAN, and the node takes the exact test. */
static float sure_distance(const sdf__scan *s, double estimate, int8_t sign)
{
    double d = sqrt(estimate), slack = SURE_DISTANCE_OF_EXTENT * s->extent;
    float lo = (float)(d - slack), hi = (float)(d + slack);
    if (lo != hi)
        return NAN;
    return s->query.sign == SDF_SIGN_NONE || sign > 0 ? lo : -lo;
}

/* Rows of the call: the workers' winners merged, their exact distances, then sdf_query's own
 * sign and output. With distances alone asked for, sure nodes are answered from their
 * estimates, and only the rest go through the exact test and sdf_query's finish. */
static void rows_range(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    const sdf__scan *s = st->scan;
    size_t nx = s->dims[0], ny = s->dims[1];
    float *points = st->points + (size_t)worker * nx * 3;
    sdf__hit *hits = st->hits + (size_t)worker * nx;
    uint32_t *slow = st->slow + (size_t)worker * nx;
    float *slow_out = st->slow_out + (size_t)worker * nx;
    for (size_t row = begin; row < end; row++) {
        size_t j = row % ny, k = st->k0 + row / ny, first = row * nx, m = 0;
        for (size_t i = 0; i < nx; i++) {
            double estimate = INFINITY;
            uint32_t w = UINT32_MAX;
            int8_t sign = 0;
            for (int t = 0; t < st->workers; t++) {
                size_t n = (size_t)t * st->nodes + first + i;
                const node_best *nb = &st->best[n];
                if (nb->d2 < estimate || (nb->d2 == estimate && nb->winner < w))
                    estimate = nb->d2, w = nb->winner, sign = nb->sure;
            }
            if (sign) {
                float f = sure_distance(s, estimate, sign);
                if (f == f) {
                    st->out.distance[first + i] = f;
                    continue;
                }
            }
            double p[3] = {s->coord[0][i], s->coord[1][j], s->coord[2][k]};
            for (int a = 0; a < 3; a++)
                points[3 * m + a] = (float)p[a];
            slow[m] = (uint32_t)i;
            hits[m].dist2 = INFINITY;
            if (w != UINT32_MAX) {
                exact_hit(s, w, p, &hits[m]);
                /* Inside its region a feature's estimate is its exact distance; more means
                 * the node was an extra candidate's (within the slack): search it instead. */
                if (hits[m].dist2 - estimate >
                    1e-12 * hits[m].dist2 + 1e-24 * (s->extent * s->extent))
                    hits[m].dist2 = INFINITY;
            }
            m++;
        }
        if (m == nx) { /* every node: straight into the outputs */
            sdf_query_result res = sdf__result_at(&st->out, first);
            sdf__query_finish(s->mesh, points, hits, nx, &s->query, &res);
            continue;
        }
        sdf_query_result res = {.distance = slow_out};
        sdf__query_finish(s->mesh, points, hits, m, &s->query, &res);
        for (size_t q = 0; q < m; q++)
            st->out.distance[first + slow[q]] = slow_out[q];
    }
}

int sdf__scan_fits(size_t nx, size_t ny, int fine_half, int threads)
{
    size_t node_bytes = fine_half ? POW3(2 * fine_half + 1) * sizeof(float)
                                  : sizeof(node_best);
    size_t workers = (size_t)sdf__effective_threads(threads, SIZE_MAX, 1);
    return nx * ny * node_bytes * workers <= SCAN_SLICE_LIMIT;
}

/* Slices of `slice_nodes` nodes per call: `workers` copies of the per-node scratch within
 * `budget`, at least one slice. */
static size_t slices_for(size_t slice_nodes, size_t workers, size_t node_bytes, size_t budget)
{
    size_t slices = budget / (workers * node_bytes) / slice_nodes;
    return slices ? slices : 1;
}

static size_t slices_within(const sdf__scan *s, size_t node_bytes, size_t budget)
{
    size_t workers = (size_t)sdf__effective_threads(s->query.threads, s->feat.count, 1);
    return slices_for(s->dims[0] * s->dims[1], workers, node_bytes, budget);
}

size_t sdf__scan_scratch_bound(const sdf_mesh *mesh, const sdf_volume_info *info, int threads)
{
    size_t faces = mesh->report.triangles, edges = mesh->edge_count;
    size_t vertices = mesh->report.vertices, features = faces + edges + vertices;
    size_t nx = info->dims[0], ny = info->dims[1], axes = 0, coarse = 1;
    for (int a = 0; a < 3; a++) {
        axes += info->dims[a];
        coarse *= sdf__features_bound_nodes(info->dims[a], COARSE_STEP);
    }
    /* sdf__features_init's arrays (positions in double, edge ends, three CSR lists) and its
     * temporaries (sort keys and values, a fill cursor), counted all at once. */
    size_t adjacency = 24 * vertices + 8 * edges + 4 * (edges + 1) + 12 * faces +
                       2 * 4 * (vertices + 1) + 8 * edges + 12 * faces + 60 * faces +
                       4 * (edges + vertices + 1);
    /* The visit order with its positions and sort keys, the z-spans. */
    size_t order = (4 + 12 + 16 + 8) * (features + 1);
    /* The coarse lattice of exact distances: its points, values, axes and queries. */
    size_t lattice = 16 * coarse + 8 * axes + sdf__query_scratch_bound(coarse, threads);
    /* Node coordinates (double, float while made). */
    size_t coords = 12 * axes;
    /* One call's per-node arrays, each worker's (as slices_within and sdf__scan_fits size
     * them: the budget, or one slice when that is larger, and no more slices than there
     * are), and its per-row arrays. */
    size_t workers = (size_t)sdf__effective_threads(threads, features, 1);
    size_t slice = nx * ny, call;
    if (info->order == 1) {
        size_t w3 = POW3(2 * info->fine_half + 1), node_bytes = w3 * sizeof(float);
        size_t slices = slices_for(slice, workers, node_bytes, SCAN_SAMPLE_BUDGET_BYTES);
        slices = slices > info->dims[2] ? info->dims[2] : slices;
        call = workers * slices * slice * node_bytes +
               workers * (MERGE_NODES * w3 * sizeof(float) + sizeof(fat_region));
    } else {
        size_t slices = slices_for(slice, workers, sizeof(node_best), SCAN_BUDGET_BYTES);
        slices = slices > info->dims[2] ? info->dims[2] : slices;
        call = workers * slices * slice * sizeof(node_best) +
               workers * nx * (3 * sizeof(float) + sizeof(sdf__hit) + sizeof(uint32_t) +
                               sizeof(float));
    }
    call += workers * sizeof(sdf__region) + sizeof(sdf__scan);
    return adjacency + order + lattice + coords + call;
}

size_t sdf__scan_slices_per_call(const sdf__scan *s)
{
    return slices_within(s, sizeof(node_best), SCAN_BUDGET_BYTES);
}

/* Fresh per-node arrays, each part first touched by the thread that clears it. */
static void clear_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    call_state *st = ctx;
    for (size_t n = begin; n < end; n++) {
        if (st->sample_best)
            st->sample_best[n] = INFINITY;
        else
            st->best[n] = (node_best){INFINITY, UINT32_MAX, 0};
    }
}

int sdf__scan_slices(sdf__scan *s, size_t k0, size_t k1, const sdf_query_result *out)
{
    size_t nx = s->dims[0], rows = (k1 - k0) * s->dims[1];
    int workers = sdf__effective_threads(s->query.threads, s->feat.count, FEATURE_CHUNK);
    size_t w = (size_t)workers, nodes = rows * nx;
    /* Sure nodes (rows_range) only where distances alone are asked for. */
    int distances_only = out->distance && !out->gradient && !out->closest && !out->triangle &&
                         !out->barycentric;
    call_state st = {.scan = s, .k0 = k0, .k1 = k1, .nodes = nodes,
                     .best = malloc(w * nodes * sizeof(node_best)),
                     .distances_only = distances_only,
                     .regions = malloc(w * sizeof(sdf__region)),
                     .points = malloc(w * nx * 3 * sizeof(float)),
                     .hits = malloc(w * nx * sizeof(sdf__hit)),
                     .slow = malloc(w * nx * sizeof(uint32_t)),
                     .slow_out = malloc(w * nx * sizeof(float)), .workers = workers, .out = *out};
    int rc = st.best && st.regions && st.points &&
                     st.hits && st.slow && st.slow_out
                 ? 0 : SDF_ENOMEM;
    if (!rc)
        rc = ensure_zspans(s, &st);
    if (!rc) {
        sdf__parallel_for(w * nodes, (size_t)1 << 16, workers, clear_range, &st);
        sdf__parallel_for(s->feat.count, FEATURE_CHUNK, workers, features_range, &st);
        sdf__parallel_for(rows, 8, workers, rows_range, &st);
    }
    free(st.best), free(st.regions), free(st.points);
    free(st.hits), free(st.slow), free(st.slow_out);
    return rc;
}

/* ---- first order ------------------------------------------------------------------------ */

size_t sdf__scan_sample_slices_per_call(const sdf__scan *s, int half)
{
    return slices_within(s, POW3(2 * half + 1) * sizeof(float), SCAN_SAMPLE_BUDGET_BYTES);
}

/* Runs of nodes: the workers' bests merged into signed distances (NAN for a sample no
 * region held; none should be), handed to the consumer. */
static void merge_samples(void *ctx, size_t begin, size_t end, int worker)
{
    call_state *st = ctx;
    size_t m = POW3(st->fine_w), all = st->nodes * m, count = (end - begin) * m;
    int sign = st->scan->query.sign != SDF_SIGN_NONE;
    float *f = st->merged + (size_t)worker * MERGE_NODES * m;
    memcpy(f, st->sample_best + begin * m, count * sizeof *f);
    for (int t = 1; t < st->workers; t++) {
        const float *b = st->sample_best + (size_t)t * all + begin * m;
        for (size_t q = 0; q < count; q++)
            f[q] = fabsf(b[q]) < fabsf(f[q]) ? b[q] : f[q];
    }
    for (size_t q = 0; q < count; q++) {
        float v = f[q], d = sqrtf(fabsf(v));
        f[q] = v == INFINITY ? NAN : sign && v < 0 ? -d : d;
    }
    size_t first = st->k0 * st->scan->dims[0] * st->scan->dims[1] + begin;
    int rc = st->consume(st->user, first, end - begin, f, worker);
    if (rc)
        st->consume_rc[worker] = rc;
}

int sdf__scan_samples(sdf__scan *s, size_t k0, size_t k1, int half, double fine_spacing,
                      sdf__sample_fn consume, void *user)
{
    size_t w3 = POW3(2 * half + 1), nodes = (k1 - k0) * s->dims[0] * s->dims[1];
    int workers = sdf__effective_threads(s->query.threads, s->feat.count, FEATURE_CHUNK);
    size_t w = (size_t)workers, scratch = w * nodes * w3;
    if (scratch > s->sample_scratch_count) { /* kept between calls: fresh pages cost */
        free(s->sample_scratch);
        s->sample_scratch = malloc(scratch * sizeof(float));
        s->sample_scratch_count = s->sample_scratch ? scratch : 0;
    }
    call_state st = {.scan = s, .k0 = k0, .k1 = k1, .nodes = nodes,
                     .regions = malloc(w * sizeof(sdf__region)), .workers = workers,
                     .fine_w = 2 * half + 1, .sample_best = s->sample_scratch,
                     .merged = malloc(w * MERGE_NODES * w3 * sizeof(float)),
                     .fat = malloc(w * sizeof(fat_region)), .consume = consume, .user = user};
    int rc = st.regions && st.sample_best && st.merged && st.fat ? 0 : SDF_ENOMEM;
    if (half < 1 || half > 4)
        rc = SDF_EINVAL;
    for (int a = 0; a < 3; a++) {
        for (int o = -half; o <= half && !rc; o++) /* as the bake forms them */
            st.fine_offset[a][o + half] = o * fine_spacing * s->spacing[a];
        st.rho[a] = half * fine_spacing * s->spacing[a] + s->index_slack[a] * s->spacing[a];
    }
    if (!rc)
        rc = ensure_zspans(s, &st);
    if (!rc) {
        sdf__parallel_for(scratch, (size_t)1 << 16, workers, clear_range, &st);
        sdf__parallel_for(s->feat.count, FEATURE_CHUNK, workers, features_range, &st);
        sdf__parallel_for(nodes, MERGE_NODES, workers, merge_samples, &st);
        for (int t = 0; t < workers && !rc; t++)
            rc = st.consume_rc[t];
    }
    free(st.regions), free(st.merged), free(st.fat);
    return rc;
}

/* ---- set-up ------------------------------------------------------------------------------ */

/* The visit order of the features: faces at their centroids, edges at their midpoints. */
static int feature_order(sdf__scan *s)
{
    float *at = malloc((3 * s->feat.count + 1) * sizeof *at);
    s->order = malloc((s->feat.count + 1) * sizeof *s->order);
    if (!at || !s->order) {
        free(at);
        return SDF_ENOMEM;
    }
    for (size_t f = 0; f < s->feat.count; f++)
        sdf__feature_position(&s->feat, f, at + 3 * f);
    int rc = sdf__morton_order((const char *)at, 3 * sizeof(float), s->feat.count, s->order);
    free(at);
    return rc;
}

int sdf__scan_supported(const sdf_mesh *mesh, sdf_sign_method sign)
{
    if (sign == SDF_SIGN_AUTO)
        sign = mesh->report.auto_sign;
    const sdf_mesh_report *r = &mesh->report;
    if (!r->closed || r->triangles == 0 ||
        (sign != SDF_SIGN_PSEUDONORMAL && sign != SDF_SIGN_NONE) ||
        r->triangles + mesh->edge_count + r->vertices >= UINT32_MAX) /* feature ids */
        return 0;
    for (size_t c = 0; c < 3 * mesh->report.triangles; c++)
        if (mesh->edge_of[c] == SDF__NO_EDGE)
            return 0;
    return 1;
}

/* A scan of the lattice of node coordinates axis[a][0..dims[a]), strictly increasing; origin
 * and spacing give the index arithmetic (nodes may stray from origin + i spacing by rounding,
 * which the index slack covers: a node's own coordinate always decides). */
static int scan_new(const sdf_mesh *mesh, const size_t dims[3], const float *const axis[3],
                    const double origin[3], const double spacing[3],
                    const sdf_query_options *opts, sdf__scan **out)
{
    sdf__scan *s = calloc(1, sizeof *s);
    if (!s)
        return SDF_ENOMEM;
    s->mesh = mesh;
    s->query = *opts;
    s->query.point_stride = 0;
    double extent = mesh->report.diagonal;
    int rc = 0;
    for (int a = 0; a < 3 && !rc; a++) {
        s->dims[a] = dims[a], s->origin[a] = origin[a], s->spacing[a] = spacing[a];
        s->inv_spacing[a] = 1 / spacing[a];
        s->coord[a] = malloc(dims[a] * sizeof(double));
        if (!s->coord[a]) {
            rc = SDF_ENOMEM;
            break;
        }
        double stray = 0, far = 0;
        for (size_t i = 0; i < dims[a]; i++) {
            s->coord[a][i] = axis[a][i];
            stray = sdf__max2(stray, fabs(axis[a][i] - (origin[a] + (double)i * spacing[a])));
            far = sdf__max2(far, fabs(axis[a][i]));
        }
        s->index_slack[a] = (stray + 2 * FLT_EPSILON * far) / spacing[a] + 1e-9;
        extent = sdf__max2(extent, sdf__max2(far, sdf__max2(fabs(mesh->report.bbox_min[a]),
                                                            fabs(mesh->report.bbox_max[a]))));
    }
    s->extent = extent;
    if (!rc)
        rc = sdf__features_init(&s->feat, mesh);
    /* Double rounding of a plane's value is ~1e-16 of the coordinates; node coordinates are
     * used as the exact floats they are. */
    s->feat.slack = 1e-12 * extent;
    s->feat.row_pad = 1e-6 * extent;
    if (!rc)
        rc = sdf__features_bound(&s->feat, mesh, (const double *const *)s->coord, dims,
                                 COARSE_STEP, s->query.threads, &s->coarse, s->coarse_coord);
    if (!rc)
        rc = feature_order(s);
    if (rc) {
        sdf__scan_destroy(s);
        return rc;
    }
    *out = s;
    return 0;
}

int sdf__scan_create(const sdf_mesh *mesh, const sdf_volume_info *info,
                     const sdf_query_options *opts, sdf__scan **out)
{
    float *axis[3] = {NULL, NULL, NULL};
    int rc = 0;
    for (int a = 0; a < 3 && !rc; a++) { /* the float points a query would be given */
        axis[a] = malloc(info->dims[a] * sizeof(float));
        if (!axis[a])
            rc = SDF_ENOMEM;
        for (size_t i = 0; !rc && i < info->dims[a]; i++)
            axis[a][i] = (float)(info->origin[a] + (double)i * info->spacing[a]);
    }
    if (!rc)
        rc = scan_new(mesh, info->dims, (const float *const *)axis, info->origin, info->spacing,
                      opts, out);
    free(axis[0]), free(axis[1]), free(axis[2]);
    return rc;
}

int sdf__scan_create_lattice(const sdf_mesh *mesh, const size_t dims[3],
                             const float *const axis[3], const sdf_query_options *opts,
                             sdf__scan **out)
{
    double origin[3], spacing[3];
    for (int a = 0; a < 3; a++) {
        if (dims[a] < 2)
            return SDF_EINVAL;
        origin[a] = axis[a][0];
        spacing[a] = ((double)axis[a][dims[a] - 1] - axis[a][0]) / (double)(dims[a] - 1);
        if (!(spacing[a] > 0))
            return SDF_EINVAL;
        /* Nodes within 1 % of a cell of even spacing (so also increasing): the index
         * arithmetic's slack stays under a node. */
        for (size_t i = 0; i < dims[a]; i++)
            if (!(fabs(axis[a][i] - (origin[a] + (double)i * spacing[a])) <= 0.01 * spacing[a]))
                return SDF_EINVAL;
    }
    return scan_new(mesh, dims, axis, origin, spacing, opts, out);
}

void sdf__scan_destroy(sdf__scan *s)
{
    if (!s)
        return;
    for (int a = 0; a < 3; a++)
        free(s->coord[a]);
    for (int a = 0; a < 3; a++)
        free(s->coarse_coord[a]);
    sdf__features_free(&s->feat);
    free(s->order), free(s->coarse), free(s->sample_scratch), free(s->zspan);
    free(s);
}
