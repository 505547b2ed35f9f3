/* filter.c - the convolution-filtered signed distance and its gradient (see sdf.h and
 * filter.h; its options and sample sets are samples.c's; paper:
 * docs/papers/convolution-filtering-sdf.md).
 *
 * Evaluation is batches of ordinary queries: f and grad f at the points themselves (for the
 * kernel size h), the medial stencil when adaptive, then every displaced sample p - s_i h(p).
 * A point's samples are stored consecutively and lie within a few kernel widths of it, so
 * each run of SDF__PACKET is one coherent packet whose searches start from |f(p)| + |x - p|
 * (sdf__query_seeded): the paper's "packet sampling". Large requests go in blocks of at most
 * BLOCK_SAMPLES sample points, so memory stays bounded. */
#include "query/filter.h"

#include <math.h>
#include <stdlib.h>

#include "core/bigmem.h"
#include "core/diag.h"
#include "core/parallel.h"
#include "core/workspace.h"
#include "points/morton.h"
#include "points/points.h"
#include "query/query.h"
#include "points/packet.h"
#include "query/samples.h"

#define BLOCK_SAMPLES (1u << 20) /* displaced points per internal batch (~37 MB of scratch) */
#define POINTS_CHUNK 256 /* points of a block per work item of its per-point loops */

/* ---- evaluation --------------------------------------------------------------------------- */

/* Kernel size h(p) (eq. 4) and its gradient, from f(p) and grad f(p). */
static double kernel_size(double f, const float *grad_f, double cap, double grad_h[3])
{
    double r = fabs(f) / cap;
    grad_h[0] = grad_h[1] = grad_h[2] = 0;
    if (r >= 1)
        return 1;
    /* dh/dr = 6 r (1 - r), grad r = sign(f) grad f / f_c (|f| is smooth where f != 0). */
    double scale = f == 0 ? 0 : 6 * r * (1 - r) * (f < 0 ? -1 : 1) / cap;
    for (int k = 0; k < 3; k++)
        grad_h[k] = scale * grad_f[k];
    return r * r * (3 - 2 * r);
}

/* The smoothing volume's signed distance f_s at p and its gradient (sphere and box are
 * closed forms; a mesh volume's come from a query, passed in `mesh_f`, `mesh_grad`). */
static double volume_distance(const sdf_smoothing_volume *v, const float *p, double mesh_f,
                              const float *mesh_grad, double grad[3])
{
    if (v->shape == SDF_VOLUME_MESH) {
        for (int k = 0; k < 3; k++)
            grad[k] = mesh_grad[k];
        return mesh_f;
    }
    if (v->shape == SDF_VOLUME_SPHERE) {
        double d[3], len = 0;
        for (int k = 0; k < 3; k++) {
            d[k] = p[k] - v->center[k];
            len += d[k] * d[k];
        }
        len = sqrt(len);
        for (int k = 0; k < 3; k++)
            grad[k] = len > 0 ? d[k] / len : (k == 0);
        return len - v->radius;
    }
    /* Box: q = |p - centre| - half extents, per axis. */
    double q[3], sgn[3], out2 = 0, inside = -INFINITY;
    int axis = 0;
    for (int k = 0; k < 3; k++) {
        double c = 0.5 * (v->lo[k] + v->hi[k]), half = 0.5 * (v->hi[k] - v->lo[k]);
        sgn[k] = p[k] < c ? -1 : 1;
        q[k] = fabs(p[k] - c) - half;
        out2 += q[k] > 0 ? q[k] * q[k] : 0;
        if (q[k] > inside)
            inside = q[k], axis = k;
    }
    if (out2 > 0) {
        double len = sqrt(out2);
        for (int k = 0; k < 3; k++)
            grad[k] = q[k] > 0 ? sgn[k] * q[k] / len : 0;
        return len;
    }
    for (int k = 0; k < 3; k++)
        grad[k] = k == axis ? sgn[k] : 0;
    return inside;
}

/* h_m(p) (sec. 6.1) and its gradient, from the volume's f_s and grad f_s. */
static double local_kernel_size(const sdf_smoothing_volume *v, double fs, const double grad_fs[3],
                                double grad_h[3])
{
    grad_h[0] = grad_h[1] = grad_h[2] = 0;
    if (fs >= 0)
        return 0; /* outside: g = f */
    double t = -fs / v->depth;
    if (t >= 1)
        return v->scale;
    double scale = v->scale * 6 * t * (1 - t) / v->depth; /* d/dp of smoothstep(-f_s / s_d) */
    for (int k = 0; k < 3; k++)
        grad_h[k] = -scale * grad_fs[k];
    return v->scale * t * t * (3 - 2 * t);
}

typedef struct scratch {
    float *centre_f, *centre_grad;   /* f and grad f at the query points */
    float *volume_f, *volume_grad;   /* a mesh smoothing volume's f_s and grad f_s there */
    float *sample_p, *sample_f;
    float *sample_grad;              /* the samples' gradients, when the caller wants g's */
    double *sample_bound;            /* |f(p)| + |x - p|: each sample's search starts there */
    int8_t *sample_sign;             /* sign(f(p)) where it is certain, else 0 (displace) */
    uint8_t *sample_run;             /* 1 at each point's first sample: packets stay within */
    int closed;                      /* the mesh is closed: its sign only flips at the surface */
    sdf_workspace *ws;               /* where the arrays live between calls (or NULL) */
} scratch;

/* Sample k's gradient, or zeros when no gradient is asked for (g's value needs none, and
 * without one the samples whose sign is known need no exact closest point, points/cluster.h). */
static const float *sample_gradient(const scratch *s, size_t k)
{
    static const float none[3] = {0, 0, 0};
    return s->sample_grad ? s->sample_grad + 3 * k : none;
}

static void free_scratch(scratch *s)
{
    sdf_workspace *ws = s->ws;
    sdf__ws_free(ws, s->centre_f), sdf__ws_free(ws, s->centre_grad);
    sdf__ws_free(ws, s->volume_f), sdf__ws_free(ws, s->volume_grad);
    sdf__ws_free(ws, s->sample_p), sdf__ws_free(ws, s->sample_f);
    sdf__ws_free(ws, s->sample_grad), sdf__ws_free(ws, s->sample_bound);
    sdf__ws_free(ws, s->sample_sign), sdf__ws_free(ws, s->sample_run);
}

/* What one point's filtered value needs: its kernel size and, with adaptive quality, how
 * many samples (full ones, then one weighted by frac) and grad n_a. */
typedef struct point_plan {
    double h, grad_h[3];
    int full;
    double frac, grad_n[3];
    int used;     /* samples evaluated: full (+1 with a fraction); 0 where h = 0 (g = f) */
    size_t first; /* its first sample in the block's sample arrays */
    size_t index; /* the point's index in the request */
} point_plan;

#define STENCIL 26 /* the 3^3 grid without its centre (the centre is p itself) */

/* Sample slot k: the point p - offset h and its search bound |f(p)| + |x - p| (f is
 * 1-Lipschitz; measured from the float point actually queried, grown for rounding). */
static void displace(const float *p, const double offset[3], double h, double fp, scratch *s,
                     size_t k)
{
    double gap2 = 0;
    for (int c = 0; c < 3; c++) {
        float x = (float)(p[c] - offset[c] * h);
        s->sample_p[3 * k + c] = x;
        gap2 += ((double)x - p[c]) * ((double)x - p[c]);
    }
    double gap = sqrt(gap2);
    s->sample_bound[k] = (fabs(fp) + gap) * (1 + 1e-6);
    /* On a closed mesh every sign method flips only across the surface, and no surface lies
     * nearer to p than |f(p)|: a sample that close shares p's sign, which spares its sign
     * computation (a winding number traversal on self-intersecting meshes). Open meshes' winding
     * signs also flip across holes, so there it is always computed. */
    s->sample_sign[k] = s->closed && fp != 0 && gap < fabs(fp) * (1 - 1e-6) ? (fp < 0 ? -1 : 1) : 0;
}

/* Smoothstep and its derivative on [0, 1], clamped. */
static double smoothstep(double t) { return t >= 1 ? 1 : t <= 0 ? 0 : t * t * (3 - 2 * t); }
static double smoothstep_slope(double t) { return t >= 1 || t <= 0 ? 0 : 6 * t * (1 - t); }

/* One block of a filtered call, for its per-point loops, which run on every thread: on one,
 * the other cores would wait on them (each point's work is its own, so the floats do not
 * depend on how the points are shared out). */
typedef struct block_work {
    const sdf_filter_options *f;
    scratch *s;
    const sdf__samples *samples;
    const float *points;
    size_t stride;
    const uint32_t *order; /* the points' visit order, or NULL: as given */
    size_t first;          /* the block's first position in that order */
    point_plan *plan;
    sdf_query_result *out;
    int adaptive;
    double stencil[STENCIL][3]; /* adaptive quality: the 3^3 stencil's offsets (plan_samples) */
    double delta;          /* ... their spacing, in units of h(p) */
} block_work;

static const float *work_point(const block_work *w, size_t index)
{
    return (const float *)((const char *)w->points + index * w->stride);
}

/* A point's `count` samples p - offset_i h(p) into slots first.., a run of their own. */
static void displace_point(const block_work *w, const point_plan *pl, const double (*offset)[3],
                           int count, size_t first)
{
    const float *p = work_point(w, pl->index);
    for (int i = 0; i < count; i++) {
        displace(p, offset[i], pl->h, w->s->centre_f[pl->index], w->s, first + (size_t)i);
        w->s->sample_run[first + (size_t)i] = i == 0;
    }
}

/* Sec. 5.2, first: each point's 3^3 stencil around it (spacing delta h(p), the grid of
 * eq. 9), displaced as its samples are. */
static void stencil_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const block_work *w = ctx;
    for (size_t j = begin; j < end; j++)
        displace_point(w, &w->plan[j], (const double (*)[3])w->stencil, STENCIL, j * STENCIL);
}

/* Sec. 5.2, then, from the stencil's distances: detect the medial axis from how far the
 * neighbours' mean is from the centre, and set n_a = N_min + (n_medial + n_distance) / 2
 * (N_max - N_min) with its gradient. */
static void medial_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const block_work *w = ctx;
    const sdf_filter_options *f = w->f;
    const scratch *s = w->s;
    double spread = 0.5 * (f->samples - f->min_samples);
    for (size_t j = begin; j < end; j++) {
        point_plan *pl = &w->plan[j];
        size_t q = pl->index;
        double fp = s->centre_f[q];
        const float *grad_fp = s->centre_grad + 3 * q;
        /* D = mean of the neighbours - centre, and its gradient through x_i = p - o_i h(p). */
        double mean = 0, grad_d[3] = {0, 0, 0};
        for (int i = 0; i < STENCIL; i++) {
            size_t k = j * STENCIL + (size_t)i;
            const float *g = sample_gradient(s, k);
            const double *o = w->stencil[i];
            double along = o[0] * g[0] + o[1] * g[1] + o[2] * g[2];
            mean += s->sample_f[k] / STENCIL;
            for (int c = 0; c < 3; c++)
                grad_d[c] += (g[c] - pl->grad_h[c] * along) / STENCIL;
        }
        double d = mean - fp, medial = 0, grad_medial[3] = {0, 0, 0};
        if (pl->h > 0) { /* M = |D| / (delta h); at h = 0 the stencil collapses: M = 0 */
            double scale = w->delta * pl->h, x = fabs(d) / scale / f->medial;
            medial = smoothstep(x);
            double slope = smoothstep_slope(x) / f->medial, sgn = d < 0 ? -1 : 1;
            for (int c = 0; c < 3; c++) {
                double grad_m = sgn * (grad_d[c] - grad_fp[c]) / scale -
                                fabs(d) / (scale * pl->h) * pl->grad_h[c];
                grad_medial[c] = slope * grad_m;
            }
        }
        /* n_distance = 1 - eq. (4)'s h: many samples near the surface, few far away. */
        double grad_h4[3];
        double distance = 1 - kernel_size(fp, grad_fp, f->cap, grad_h4);
        double n_a = f->min_samples + (medial + distance) * spread;
        pl->full = (int)floor(n_a);
        pl->frac = n_a - pl->full;
        if (pl->full >= f->samples)
            pl->full = f->samples, pl->frac = 0;
        for (int c = 0; c < 3; c++)
            pl->grad_n[c] = spread * (grad_medial[c] - grad_h4[c]);
    }
}

/* Sec. 5.2 for the block's first m points: their stencils, queried together, set each one's
 * sample count. */
static int plan_samples(const sdf_mesh *mesh, const sdf_query_options *inner, block_work *w,
                        size_t m)
{
    const sdf_filter_options *f = w->f;
    scratch *s = w->s;
    w->delta = f->kernel == SDF_KERNEL_GAUSSIAN ? sdf__gaussian_sigma(f->a) : f->b / 2;
    int o = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++)
                if (x || y || z) {
                    double *at = w->stencil[o++];
                    at[0] = x * w->delta, at[1] = y * w->delta, at[2] = z * w->delta;
                }
    sdf__parallel_for(m, POINTS_CHUNK, inner->threads, stencil_range, w);
    sdf_query_result res = {.distance = s->sample_f, .gradient = s->sample_grad};
    int rc = sdf__query_seeded(mesh, s->sample_p, s->sample_bound, s->sample_sign,
                               s->sample_run, m * STENCIL, inner, &res);
    if (rc)
        return rc;
    sdf__parallel_for(m, POINTS_CHUNK, inner->threads, medial_range, w);
    return 0;
}

/* The kernel size at point q (eq. 4, or sec. 6.1's h_m inside a smoothing volume). */
static double size_at(const sdf_filter_options *f, const scratch *s, const float *p, size_t q,
                      double grad_h[3])
{
    if (f->smooth.shape == SDF_VOLUME_NONE)
        return kernel_size(s->centre_f[q], s->centre_grad + 3 * q, f->cap, grad_h);
    double grad_fs[3];
    double fs = volume_distance(&f->smooth, p, s->volume_f ? s->volume_f[q] : 0,
                                s->volume_grad ? s->volume_grad + 3 * q : NULL, grad_fs);
    return local_kernel_size(&f->smooth, fs, grad_fs, grad_h);
}

/* Points per block: BLOCK_SAMPLES samples' worth (at least one point), and no more than the
 * call has, so a small call's sample arrays are small too. */
static size_t points_per_block(size_t per_point, size_t count)
{
    size_t block = BLOCK_SAMPLES / per_point > 0 ? BLOCK_SAMPLES / per_point : 1;
    return count > 0 && count < block ? count : block;
}

size_t sdf__filter_scratch_bound(const sdf_filter_options *f, size_t count, int gradient,
                                 int threads)
{
    /* As sdf_query_filtered allocates: f and grad f at the points (and at the smoothing
     * mesh), the sample set, one block's samples and plans, the points' Morton order and its
     * sort's scratch, and the larger of its inner queries' own scratch. */
    size_t n = f->grid ? 27 : (size_t)f->samples;
    size_t per_point = n + (f->min_samples ? STENCIL : 0);
    size_t block = points_per_block(per_point, count), per_block = block * per_point;
    size_t centre = 2 * (sdf__big_size((count + 1) * sizeof(float)) +
                         sdf__big_size((3 * count + 1) * sizeof(float)));
    size_t samples = sdf__big_size(3 * per_block * sizeof(float)) +
                     sdf__big_size(per_block * sizeof(float)) +
                     (gradient ? sdf__big_size(3 * per_block * sizeof(float)) : 0) +
                     sdf__big_size(per_block * sizeof(double)) +
                     2 * sdf__big_size(per_block * sizeof(uint8_t));
    size_t inner = sdf__query_scratch_bound(count > per_block ? count : per_block, threads);
    return centre + n * 4 * sizeof(double) + samples + block * sizeof(point_plan) +
           sdf__big_size(count * sizeof(uint32_t)) + sdf__morton_scratch_bound(count, threads) +
           inner;
}

/* Each point's kernel size h(p), and the full sample count until adaptive quality sets it. */
static void plan_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const block_work *w = ctx;
    for (size_t j = begin; j < end; j++) {
        point_plan *pl = &w->plan[j];
        pl->index = w->order ? w->order[w->first + j] : w->first + j;
        pl->h = size_at(w->f, w->s, work_point(w, pl->index), pl->index, pl->grad_h);
        pl->full = w->samples->n, pl->frac = 0;
        pl->grad_n[0] = pl->grad_n[1] = pl->grad_n[2] = 0;
    }
}

/* The displaced sample points p - s_i h(p) (eq. 10), each point's from its plan's `first`. */
static void displace_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const block_work *w = ctx;
    for (size_t j = begin; j < end; j++) {
        const point_plan *pl = &w->plan[j];
        displace_point(w, pl, (const double (*)[3])w->samples->offset, pl->used, pl->first);
    }
}

/* g and grad g at each point from its samples' f and grad f. */
static void accumulate_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const block_work *w = ctx;
    for (size_t j = begin; j < end; j++) {
        const point_plan *pl = &w->plan[j];
        size_t q = pl->index;
        double fp = w->s->centre_f[q];
        const float *grad_fp = w->s->centre_grad + 3 * q;
        double total = pl->full + pl->frac; /* the weights' sum: n, or n_a */
        double value = 0, grad[3] = {0, 0, 0}, along = 0, last = 0;
        for (int i = 0; i < pl->used; i++) {
            size_t k = pl->first + (size_t)i;
            double v = w->s->sample_f[k], sgn = 1;
            if (w->f->unsigned_integrand) { /* |f| and its gradient sign(f) grad f */
                sgn = v < 0 ? -1 : 1;
                v = fabs(v);
            }
            const float *gs = sample_gradient(w->s, k);
            /* 1/n each (eq. 10), w(s_i) for the grid (eq. 9); adaptive: the last sample
             * weighs the fractional part of n_a. */
            double weight = w->adaptive ? (i < pl->full ? 1 : pl->frac) / total
                                        : w->samples->weight[i];
            const double *offset = w->samples->offset[i];
            value += weight * v;
            last = v;
            for (int c = 0; c < 3; c++)
                grad[c] += weight * sgn * gs[c];
            along += weight * sgn * (offset[0] * gs[0] + offset[1] * gs[1] + offset[2] * gs[2]);
        }
        /* grad g = sum w_i (I - grad h s_i^T) grad f(x_i), x_i = p - s_i h(p), plus, when
         * n_a varies, dg/dn_a grad n_a with dg/dn_a = (v_last - g) / n_a. The samples'
         * mean gradient, when asked for, is the first term alone. */
        for (int c = 0; c < 3 && !w->f->sample_gradient; c++)
            grad[c] -= pl->grad_h[c] * along;
        if (w->adaptive && pl->frac > 0 && !w->f->sample_gradient)
            for (int c = 0; c < 3; c++)
                grad[c] += (last - value) / total * pl->grad_n[c];
        double outer = w->f->unsigned_integrand ? (fp < 0 ? -1 : 1) : 1;
        if (pl->h == 0) { /* on the surface or outside a smoothing volume: g = f */
            value = fp, outer = 1;
            for (int c = 0; c < 3; c++)
                grad[c] = grad_fp[c];
        }
        if (w->out->distance)
            w->out->distance[q] = (float)(outer * value);
        if (w->out->gradient)
            for (int c = 0; c < 3; c++)
                w->out->gradient[3 * q + c] = (float)(outer * grad[c]);
    }
}

/* f and grad f at the points (which this also checks: NaN -> SDF_ENONFINITE and its index
 * in out->bad_index), and with a mesh smoothing volume f_s and grad f_s from its mesh, into
 * s's centre and volume arrays. 0 or the code, with its message in *diag. */
static int centre_fields(const sdf_mesh *mesh, const float *points, size_t count,
                         const sdf_filter_options *f, const sdf_query_options *centre_opts,
                         scratch *s, sdf_query_result *out, sdf_diag *diag)
{
    s->centre_f = sdf__ws_alloc(s->ws, SDF__WS_CENTRE_F, (count + 1) * sizeof(float));
    s->centre_grad = sdf__ws_alloc(s->ws, SDF__WS_CENTRE_GRAD, (3 * count + 1) * sizeof(float));
    if (!s->centre_f || !s->centre_grad)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory for %zu points", count);
    sdf_query_result centre = {.distance = s->centre_f, .gradient = s->centre_grad};
    int rc = sdf__query(mesh, points, count, centre_opts, &centre);
    if (rc) {
        out->bad_index = centre.bad_index;
        return sdf__diag_set(diag, rc, 0, -1, "%s", sdf_strerror(rc));
    }
    if (f->smooth.shape != SDF_VOLUME_MESH)
        return 0;
    s->volume_f = sdf__ws_alloc(s->ws, SDF__WS_VOLUME_F, (count + 1) * sizeof(float));
    s->volume_grad = sdf__ws_alloc(s->ws, SDF__WS_VOLUME_GRAD, (3 * count + 1) * sizeof(float));
    sdf_query_result vol = {.distance = s->volume_f, .gradient = s->volume_grad};
    sdf_query_options vol_opts = *centre_opts;
    vol_opts.sign = SDF_SIGN_AUTO;
    rc = s->volume_f && s->volume_grad
             ? sdf__query(f->smooth.mesh, points, count, &vol_opts, &vol)
             : SDF_ENOMEM;
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "smoothing mesh: %s", sdf_strerror(rc));
    return 0;
}

/* The sample arrays of one block of `per_block` samples (gradients only when asked for).
 * 0 or SDF_ENOMEM. */
static int alloc_samples(scratch *s, size_t per_block, int gradient)
{
    sdf_workspace *ws = s->ws;
    s->sample_p = sdf__ws_alloc(ws, SDF__WS_SAMPLE_P, 3 * per_block * sizeof(float));
    s->sample_f = sdf__ws_alloc(ws, SDF__WS_SAMPLE_F, per_block * sizeof(float));
    s->sample_grad =
        gradient ? sdf__ws_alloc(ws, SDF__WS_SAMPLE_GRAD, 3 * per_block * sizeof(float)) : NULL;
    s->sample_bound = sdf__ws_alloc(ws, SDF__WS_SAMPLE_BOUND, per_block * sizeof(double));
    s->sample_sign = sdf__ws_alloc(ws, SDF__WS_SAMPLE_SIGN, per_block * sizeof(int8_t));
    s->sample_run = sdf__ws_alloc(ws, SDF__WS_SAMPLE_RUN, per_block * sizeof(uint8_t));
    return s->sample_p && s->sample_f && (!gradient || s->sample_grad) && s->sample_bound &&
                   s->sample_sign && s->sample_run
               ? 0
               : SDF_ENOMEM;
}

/* The points in Morton order, so consecutive points' samples touch the same parts of the
 * tree; NULL without memory for it (then the given order: the same floats). */
static uint32_t *filter_order(const float *points, size_t stride, size_t count, int threads,
                              sdf_workspace *ws)
{
    uint32_t *order = count > 1 && count <= UINT32_MAX
                          ? sdf__ws_alloc(ws, SDF__WS_FILTER_ORDER, count * sizeof *order)
                          : NULL;
    if (order && sdf__morton_order((const char *)points, stride, count, threads, ws, order)) {
        sdf__ws_free(ws, order);
        order = NULL;
    }
    return order;
}

/* One block of m points from work->first: their plans, samples, the samples' queries and
 * the filtered values. 0 or a query's code. */
static int filter_block(const sdf_mesh *mesh, const sdf_query_options *inner, block_work *work,
                        size_t m)
{
    point_plan *plan = work->plan;
    sdf__parallel_for(m, POINTS_CHUNK, inner->threads, plan_range, work);
    if (work->adaptive) { /* sec. 5.2: the stencil first, then how many samples each point gets */
        int rc = plan_samples(mesh, inner, work, m);
        if (rc)
            return rc;
    }
    /* Each point's samples, consecutive. A point with h = 0 (on the surface, or outside a
     * smoothing volume) needs none: there every sample is p itself and g = f. */
    size_t at = 0;
    for (size_t j = 0; j < m; j++) {
        plan[j].first = at;
        plan[j].used = plan[j].h == 0 ? 0 : plan[j].full + (plan[j].frac > 0);
        at += (size_t)plan[j].used;
    }
    sdf__parallel_for(m, POINTS_CHUNK, inner->threads, displace_range, work);
    /* Packet sampling (sec. 3): a point's samples are consecutive, so they make coherent
     * packets, each search bounded by |f(p)| + |x - p| (Lipschitz). */
    const scratch *s = work->s;
    sdf_query_result res = {.distance = s->sample_f, .gradient = s->sample_grad};
    int rc = sdf__query_seeded(mesh, s->sample_p, s->sample_bound, s->sample_sign, s->sample_run,
                               at, inner, &res);
    if (rc) /* out of memory, or a kernel so wide that samples pass SDF_MAX_COORDINATE */
        return rc;
    sdf__parallel_for(m, POINTS_CHUNK, inner->threads, accumulate_range, work);
    return 0;
}

/* sdf_query_filtered with its options' workspace claimed (or none). */
static int query_filtered(const sdf_mesh *mesh, const float *points, size_t count,
                          const sdf_query_options *opts, const sdf_filter_options *filter,
                          sdf_query_result *out, sdf_diag *diag)
{
    if (!mesh || !out || (!points && count))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "missing mesh, points or outputs");
    if (out->closest || out->triangle || out->barycentric || out->normal)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "the filtered field has a value and a gradient only");
    sdf_filter_options f;
    int rc = sdf__filter_resolve(mesh, filter, &f, diag);
    if (rc)
        return rc;
    size_t stride = opts && opts->point_stride ? opts->point_stride : 3 * sizeof(float);
    sdf_query_options inner = opts ? *opts : (sdf_query_options){0};
    inner.point_stride = 0;
    scratch s = {.ws = inner.workspace};
    sdf_mesh_report report;
    sdf_mesh_get_report(mesh, &report);
    s.closed = report.closed;
    sdf_query_options centre_opts = inner;
    centre_opts.point_stride = stride;
    if ((rc = centre_fields(mesh, points, count, &f, &centre_opts, &s, out, diag))) {
        free_scratch(&s);
        return rc;
    }
    if (count == 0) { /* the options are checked: callers validate this way, cheaply */
        free_scratch(&s);
        return 0;
    }
    sdf__samples samples;
    if (sdf__samples_draw(&f, &samples)) {
        free_scratch(&s);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory for the samples");
    }
    int adaptive = f.min_samples > 0;
    size_t per_point = (size_t)samples.n + (adaptive ? STENCIL : 0);
    size_t block = points_per_block(per_point, count);
    rc = alloc_samples(&s, block * per_point, out->gradient != NULL);
    point_plan *plan = malloc(block * sizeof *plan);
    if (rc || !plan) {
        free(plan);
        sdf__samples_free(&samples);
        free_scratch(&s);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory for the samples");
    }
    uint32_t *order = filter_order(points, stride, count, inner.threads, s.ws);
    block_work work = {.f = &f, .s = &s, .samples = &samples, .points = points,
                       .stride = stride, .order = order, .plan = plan, .out = out,
                       .adaptive = adaptive};
    for (size_t first = 0; first < count && !rc; first += block) {
        work.first = first;
        rc = filter_block(mesh, &inner, &work, count - first < block ? count - first : block);
    }
    sdf__ws_free(s.ws, order);
    free(plan);
    sdf__samples_free(&samples);
    free_scratch(&s);
    if (rc == SDF_ENONFINITE) /* the points themselves were checked above */
        return sdf__diag_set(diag, rc, 0, -1,
                             "the kernel displaces samples beyond +-1e18: make it narrower");
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "%s", sdf_strerror(rc));
    return 0;
}

int sdf_query_filtered(const sdf_mesh *mesh, const float *points, size_t count,
                       const sdf_query_options *opts, const sdf_filter_options *filter,
                       sdf_query_result *out, sdf_diag *diag)
{
    sdf__ws_call call;
    int rc = query_filtered(mesh, points, count, sdf__ws_enter(opts, &call), filter, out, diag);
    sdf__ws_leave(&call);
    return rc;
}
