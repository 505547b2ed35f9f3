/* bake.c - baking distance volumes (sdf_volume_bake in sdf.h; the TDF paper is
 * docs/papers/first-order-sdf-taylor.md).
 *
 * Zero order: the signed distance at every node, one batched query per slab of nodes.
 * First order (Algorithm 1): around every node x_i the distances on a fine (2H+1)^3 grid of
 * spacing Delta cells, the least-squares plane through them with the pseudo-inverse X_o^+
 * precomputed once (eq. 3), translated to the global power basis (eq. 2) and normalised.
 * A node's fine samples lie within a fraction of a cell of it, so they are one coherent run:
 * the node itself is asked first, then every sample's search starts from the bound
 * |f(x_i)| + |s - x_i| (packet traversal seeded as in sdf__query_seeded), and on a closed
 * mesh a sample nearer to x_i than |f(x_i)| takes x_i's sign without a sign query. Slabs
 * bound the memory and give progress reports and cancellation points. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/bigmem.h"
#include "core/diag.h"
#include "core/parallel.h"
#include "mesh/mesh.h"
#include "points/points.h"
#include "query/filter.h"
#include "query/samples.h"
#include "volume/pack.h"
#include "scan/scan.h"
#include "volume/volume.h"

#define DEFAULT_DIM 64
#define DEFAULT_MARGIN_OF_DIAGONAL 0.05
#define DEFAULT_FINE_SPACING 0.1 /* Delta, in cells: the paper's choice (sec. 5.1) */
#define MAX_FINE_HALF 4
#define MAX_FINE ((2 * MAX_FINE_HALF + 1) * (2 * MAX_FINE_HALF + 1) * (2 * MAX_FINE_HALF + 1))
#define SLAB_QUERIES ((size_t)1 << 18) /* distance queries per slab: bounds memory and the
                                          time between progress reports */

typedef struct bake_plan {
    sdf_volume_info info;
    const sdf_mesh *mesh;
    const sdf_filter_options *filter;
    sdf_filter_options resolved_filter; /* filter with its defaults filled in */
    sdf_query_options query;
    int closed;                   /* the mesh's sign flips only across its surface */
    size_t queries_per_point;     /* 1, or what one filtered value costs */
    int fine_count;               /* (2H+1)^3; 1 for order 0 */
    double fine[MAX_FINE][3];     /* s_oj, origin-centred fine grid, in world units */
    double pinv_t[MAX_FINE][4];   /* X_o^+ transposed: sample j's weights in a, b, c and the
                                     constant */
} bake_plan;

/* ---- options ----------------------------------------------------------------------------- */

/* The bake's corner nodes lo and hi: the options' bounds, or the mesh's box (r) grown by the
 * margin. 0 or SDF_EINVAL with its message. */
static int resolve_bounds(const sdf_bake_options *o, const sdf_mesh_report *r, double lo[3],
                          double hi[3], sdf_diag *diag)
{
    int default_box = 1;
    for (int a = 0; a < 3; a++)
        default_box = default_box && o->lo[a] == 0 && o->hi[a] == 0;
    if (default_box) {
        double margin = o->margin;
        if (margin == 0)
            margin = DEFAULT_MARGIN_OF_DIAGONAL * r->diagonal;
        if (!(isfinite(margin) && margin >= 0))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "margin must be a length >= 0");
        for (int a = 0; a < 3; a++) {
            lo[a] = r->bbox_min[a] - margin, hi[a] = r->bbox_max[a] + margin;
            if (!(fabs(lo[a]) <= SDF_MAX_COORDINATE && fabs(hi[a]) <= SDF_MAX_COORDINATE))
                return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                     "the default bounds (the mesh's box grown by a margin of "
                                     "%g) pass +-1e18 on %c; give bounds, or a smaller margin",
                                     margin, "xyz"[a]);
        }
    } else {
        for (int a = 0; a < 3; a++) {
            lo[a] = o->lo[a], hi[a] = o->hi[a];
            if (!(fabs(lo[a]) <= SDF_MAX_COORDINATE && fabs(hi[a]) <= SDF_MAX_COORDINATE &&
                  lo[a] < hi[a]))
                return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                     "bounds must be finite, within +-1e18, with lo < hi on "
                                     "every axis (%c)", "xyz"[a]);
        }
    }
    return 0;
}

/* First order: the fitting grid's H, Delta and normalisation, checked, and its reach past
 * the bounds lo..hi. */
static int resolve_first_order(const sdf_bake_options *o, const double lo[3],
                               const double hi[3], sdf_volume_info *in, sdf_diag *diag)
{
    in->fine_half = o->fine_half ? o->fine_half : 1;
    in->fine_spacing = o->fine_spacing != 0 ? o->fine_spacing : DEFAULT_FINE_SPACING;
    if (in->fine_half < 1 || in->fine_half > MAX_FINE_HALF)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "H (fine_half) must be 1..%d, not %d",
                             MAX_FINE_HALF, in->fine_half);
    in->normalize = o->normalize;
    if ((unsigned)in->normalize > SDF_NORMALIZE_GRADIENT)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown normalisation %d",
                             (int)in->normalize);
    if (!(in->fine_spacing > 0 && in->fine_spacing <= 0.5))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                             "Delta (fine_spacing) must be in (0, 0.5] cells, not %g",
                             in->fine_spacing);
    /* The fitting grids of the corner nodes reach H Delta cells past the bounds: checked
     * here, so such a bake is refused before it starts rather than failing half-way. */
    for (int a = 0; a < 3; a++) {
        double reach = in->fine_half * in->fine_spacing * in->spacing[a];
        if (!(lo[a] - reach >= -SDF_MAX_COORDINATE && hi[a] + reach <= SDF_MAX_COORDINATE))
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "the first-order fitting grids (H Delta = %g cells) reach "
                                 "past +-1e18 on %c; give bounds further inside",
                                 in->fine_half * in->fine_spacing, "xyz"[a]);
    }
    return 0;
}

static int resolve(const sdf_mesh *mesh, const sdf_bake_options *o, bake_plan *plan,
                   sdf_diag *diag)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_volume_info *in = &plan->info;
    memset(in, 0, sizeof *in);
    double lo[3], hi[3];
    int rc = resolve_bounds(o, &r, lo, hi, diag);
    if (rc)
        return rc;
    for (int a = 0; a < 3; a++) {
        in->dims[a] = o->dims[a] ? o->dims[a] : DEFAULT_DIM;
        if (in->dims[a] < 2 || in->dims[a] > SDF_VOLUME_MAX_DIM)
            return sdf__diag_set(diag, SDF_EINVAL, 0, -1,
                                 "resolution %c is %zu; it must be 2..%d", "xyz"[a],
                                 in->dims[a], SDF_VOLUME_MAX_DIM);
        /* lo and hi are the corner nodes themselves. */
        in->origin[a] = lo[a];
        in->spacing[a] = (hi[a] - lo[a]) / (double)(in->dims[a] - 1);
    }
    if ((unsigned)o->query.sign > SDF_SIGN_NONE || o->query.threads < 0)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown sign method or negative thread count");
    in->order = o->order;
    in->encoding = o->encoding;
    in->filtered = o->filter != NULL;
    if (in->order == 1 && (rc = resolve_first_order(o, lo, hi, in, diag)))
        return rc;
    if (in->encoding == SDF_ENCODING_PACKED32)
        in->packed_range = 1; /* placeholder for the check; set from the data when baked */
    if ((rc = sdf__volume_check_info(in, diag)))
        return rc;
    plan->queries_per_point = 1;
    if (o->filter) {
        sdf_filter_options *resolved = &plan->resolved_filter;
        if ((rc = sdf__filter_resolve(mesh, o->filter, resolved, diag)))
            return rc;
        plan->queries_per_point = (size_t)resolved->samples + 1 + (resolved->min_samples ? 26 : 0);
    }
    plan->mesh = mesh;
    plan->filter = o->filter;
    plan->query = o->query;
    plan->query.point_stride = 0;
    plan->query.workspace = NULL; /* the bake's queries run on several threads at once */
    plan->closed = r.closed;
    return 0;
}

/* ---- the least-squares plane (eq. 3) ------------------------------------------------------ */

/* Invert the 4x4 matrix m by Gauss-Jordan elimination with partial pivoting. */
static int invert4(double m[4][4], double inv[4][4])
{
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            inv[i][j] = i == j;
    for (int c = 0; c < 4; c++) {
        int pivot = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(m[r][c]) > fabs(m[pivot][c]))
                pivot = r;
        if (fabs(m[pivot][c]) < 1e-300)
            return SDF_EINVAL;
        for (int j = 0; j < 4; j++) {
            double t = m[c][j]; m[c][j] = m[pivot][j]; m[pivot][j] = t;
            t = inv[c][j]; inv[c][j] = inv[pivot][j]; inv[pivot][j] = t;
        }
        double s = 1 / m[c][c];
        for (int j = 0; j < 4; j++)
            m[c][j] *= s, inv[c][j] *= s;
        for (int r = 0; r < 4; r++)
            if (r != c) {
                double f = m[r][c];
                for (int j = 0; j < 4; j++)
                    m[r][j] -= f * m[c][j], inv[r][j] -= f * inv[c][j];
            }
    }
    return 0;
}

/* The origin-centred fine grid s_oj and X_o^+ = (X^T X)^-1 X^T, X's rows (x, y, z, 1). */
static int plan_fine_grid(bake_plan *plan)
{
    const sdf_volume_info *in = &plan->info;
    int h = in->fine_half, n = 0;
    for (int k = -h; k <= h; k++)
        for (int j = -h; j <= h; j++)
            for (int i = -h; i <= h; i++) {
                double *s = plan->fine[n];
                s[0] = i * in->fine_spacing * in->spacing[0];
                s[1] = j * in->fine_spacing * in->spacing[1];
                s[2] = k * in->fine_spacing * in->spacing[2];
                n++;
            }
    plan->fine_count = n;
    double xtx[4][4] = {{0}}, inv[4][4];
    for (int s = 0; s < n; s++) {
        double row[4] = {plan->fine[s][0], plan->fine[s][1], plan->fine[s][2], 1};
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++)
                xtx[r][c] += row[r] * row[c];
    }
    if (invert4(xtx, inv))
        return SDF_EINVAL;
    for (int r = 0; r < 4; r++)
        for (int s = 0; s < n; s++) {
            double row[4] = {plan->fine[s][0], plan->fine[s][1], plan->fine[s][2], 1};
            plan->pinv_t[s][r] = inv[r][0] * row[0] + inv[r][1] * row[1] + inv[r][2] * row[2] +
                                 inv[r][3] * row[3];
        }
    return 0;
}

/* The plan of `opts` (NULL: the defaults) for `mesh`, checked as every entry point checks it:
 * the options, then the first order's fine grid. On failure *out is NULL. */
static int make_plan(const sdf_mesh *mesh, const sdf_bake_options *opts, bake_plan **out,
                     sdf_diag *diag)
{
    *out = NULL;
    sdf_bake_options defaults = {0};
    bake_plan *plan = calloc(1, sizeof *plan);
    if (!plan)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory to plan the bake");
    int rc = resolve(mesh, opts ? opts : &defaults, plan, diag);
    if (!rc && plan->info.order == 1 && plan_fine_grid(plan))
        rc = sdf__diag_set(diag, SDF_EINVAL, 0, -1, "the fine grid's normal matrix is singular");
    if (rc) {
        free(plan);
        return rc;
    }
    *out = plan;
    return 0;
}

int sdf_volume_plan(const sdf_mesh *mesh, const sdf_bake_options *opts, sdf_volume_info *planned,
                    sdf_diag *diag)
{
    if (!mesh || !planned)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no mesh");
    bake_plan *plan;
    int rc = make_plan(mesh, opts, &plan, diag);
    if (rc)
        return rc;
    *planned = plan->info;
    planned->packed_range = 0;
    free(plan);
    return 0;
}

/* ---- slabs ------------------------------------------------------------------------------- */

typedef struct slab {
    const bake_plan *plan;
    size_t first, count;   /* nodes [first, first + count) */
    float *node_pos;       /* 3 per node */
    float *node_f;         /* f(x_i) */
    float *sample_pos;     /* 3 per sample (order 1) */
    float *sample_f;       /* f at the samples */
    double *bound;         /* per sample: |f(x_i)| + |s - x_i|, slightly widened */
    int8_t *hint;          /* per sample: the sign when it is known to be x_i's */
    uint8_t *run_start;    /* per sample: 1 at a node's first sample */
    float *plane;          /* out: per node the unit normal and the plane's value at the node */
} slab;

static void node_index(const sdf_volume_info *in, size_t n, size_t ijk[3])
{
    ijk[0] = n % in->dims[0];
    ijk[1] = n / in->dims[0] % in->dims[1];
    ijk[2] = n / in->dims[0] / in->dims[1];
}

/* The field at `count` points: the raw signed distance or the filtered one. */
static int field(const bake_plan *plan, const float *pos, size_t count, float *f)
{
    sdf_query_result out = {.distance = f};
    if (plan->filter)
        return sdf_query_filtered(plan->mesh, pos, count, &plan->query, plan->filter, &out, NULL);
    return sdf_query(plan->mesh, pos, count, &plan->query, &out);
}

static int slab_nodes(slab *s)
{
    const sdf_volume_info *in = &s->plan->info;
    for (size_t n = 0; n < s->count; n++) {
        size_t ijk[3];
        double x[3];
        node_index(in, s->first + n, ijk);
        sdf__volume_node(in, ijk[0], ijk[1], ijk[2], x);
        for (int a = 0; a < 3; a++)
            s->node_pos[3 * n + a] = (float)x[a];
    }
    return field(s->plan, s->node_pos, s->count, s->node_f);
}

/* Fine sample j of the node at float position x: the float point a query is asked at. */
static void sample_point(const bake_plan *plan, const float x[3], size_t j, float p[3])
{
    for (int a = 0; a < 3; a++)
        p[a] = (float)(x[a] + plan->fine[j][a]);
}

static int slab_samples(slab *s)
{
    const bake_plan *plan = s->plan;
    size_t m = (size_t)plan->fine_count;
    for (size_t n = 0; n < s->count; n++) {
        const float *x = s->node_pos + 3 * n;
        double fx = fabs((double)s->node_f[n]);
        for (size_t j = 0; j < m; j++) {
            size_t q = n * m + j;
            float *p = s->sample_pos + 3 * q;
            double gap2 = 0;
            sample_point(plan, x, j, p);
            for (int a = 0; a < 3; a++) {
                double d = (double)p[a] - x[a];
                gap2 += d * d;
            }
            double gap = sqrt(gap2);
            /* Triangle inequality, widened past the rounding of the float f(x_i). */
            s->bound[q] = (fx + gap) * (1 + 1e-6) + 1e-30;
            s->run_start[q] = j == 0;
            /* Every sign method flips only across a closed surface, and none lies within
             * |f(x_i)| of x_i. */
            s->hint[q] = plan->closed && fx > 0 && gap < fx * (1 - 1e-6)
                             ? (s->node_f[n] < 0 ? -1 : 1)
                             : 0;
        }
    }
    size_t samples = s->count * m;
    if (plan->filter)
        return field(plan, s->sample_pos, samples, s->sample_f);
    sdf_query_result out = {.distance = s->sample_f};
    return sdf__query_seeded(plan->mesh, s->sample_pos, s->bound, s->hint, s->run_start, samples,
                             &plan->query, &out);
}

/* Algorithm 1, steps 3-6 for `count` nodes from their fine samples f (m per node): a~ =
 * X_o^+ f, normalised by |(a~, b~, c~)| (all four coefficients, or with
 * SDF_NORMALIZE_GRADIENT the first three). The plane is kept local here (unit normal, value at
 * the node); the global constant d = value - n . x_i (eq. 2) is formed when the volume is
 * written. Each node's four sums run in order of j, FIT_BATCH nodes side by side: one node's
 * sums are four chains of m dependent additions, and a batch's chains overlap (the same
 * floats as one node at a time). */
#define FIT_BATCH 4

static void fit_nodes(const bake_plan *plan, const float *f, size_t count, float *out)
{
    size_t m = (size_t)plan->fine_count;
    for (size_t first = 0; first < count; first += FIT_BATCH) {
        size_t batch = count - first < FIT_BATCH ? count - first : FIT_BATCH;
        const float *fb = f + first * m;
        double c[FIT_BATCH][4] = {{0}};
        if (batch == FIT_BATCH) {
            for (size_t j = 0; j < m; j++)
                for (int k = 0; k < FIT_BATCH; k++)
                    for (int r = 0; r < 4; r++)
                        c[k][r] += plan->pinv_t[j][r] * fb[k * m + j];
        } else {
            for (size_t k = 0; k < batch; k++)
                for (size_t j = 0; j < m; j++)
                    for (int r = 0; r < 4; r++)
                        c[k][r] += plan->pinv_t[j][r] * fb[k * m + j];
        }
        for (size_t k = 0; k < batch; k++) {
            const double *ck = c[k];
            float *o = out + 4 * (first + k);
            double len = sqrt(ck[0] * ck[0] + ck[1] * ck[1] + ck[2] * ck[2]);
            /* A vanishing fitted gradient (a perfectly symmetric spot of the medial axis) has
             * no direction to normalise to: keep the value with a zero gradient. */
            double scale = len > 1e-12 ? 1 / len : 1;
            o[0] = (float)(ck[0] * scale), o[1] = (float)(ck[1] * scale);
            o[2] = (float)(ck[2] * scale);
            o[3] = (float)(plan->info.normalize == SDF_NORMALIZE_PLANE ? ck[3] * scale : ck[3]);
        }
    }
}

static void fit_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    slab *s = ctx;
    size_t m = (size_t)s->plan->fine_count;
    fit_nodes(s->plan, s->sample_f + begin * m, end - begin, s->plane + 4 * begin);
}

/* ---- assembly ---------------------------------------------------------------------------- */

/* Local planes (normal, value at node) -> the volume's encoding, for a run of nodes. Float32
 * volumes hold their local planes in their own data until here (sdf_volume_bake), and are
 * rewritten in place: each node reads its plane before it writes it. */
typedef struct store_state {
    sdf_volume *v;
    const float *plane;
} store_state;

static void store_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const store_state *ss = ctx;
    sdf_volume *v = ss->v;
    const sdf_volume_info *in = &v->info;
    for (size_t n = begin; n < end; n++) {
        const float *p = ss->plane + 4 * n;
        size_t ijk[3];
        double x[3], normal[3] = {p[0], p[1], p[2]}, value = p[3];
        node_index(in, n, ijk);
        sdf__volume_node(in, ijk[0], ijk[1], ijk[2], x);
        if (in->encoding == SDF_ENCODING_FLOAT32) {
            float *o = v->data.f + 4 * n;
            o[0] = (float)normal[0], o[1] = (float)normal[1], o[2] = (float)normal[2];
            o[3] = (float)(value - (normal[0] * x[0] + normal[1] * x[1] + normal[2] * x[2]));
        } else {
            if (normal[0] == 0 && normal[1] == 0 && normal[2] == 0)
                normal[2] = 1; /* any direction: the packing has no zero normal */
            v->data.u[n] = sdf__pack_plane(normal, value - in->packed_center, in->packed_range);
        }
    }
}

static void store_planes(sdf_volume *v, const float *plane, int threads)
{
    store_state ss = {v, plane};
    sdf__parallel_for(v->nodes, (size_t)1 << 14, threads, store_range, &ss);
}

static void free_slab(slab *s)
{
    sdf__big_free(s->node_pos), sdf__big_free(s->node_f), sdf__big_free(s->sample_pos);
    sdf__big_free(s->sample_f), sdf__big_free(s->bound), sdf__big_free(s->hint);
    sdf__big_free(s->run_start);
}

/* The bake's distances: the span of f at the nodes (for packing) and, for first order, the
 * local planes, one call per run of slices or slab of nodes. */
typedef struct bake_out {
    sdf_volume *v;
    float *planes;               /* order 1: 4 per node */
    double smallest_f, largest_f;
} bake_out;

/* Report progress; SDF_ECANCELED (with its message) when asked to stop. */
static int progress(const sdf_bake_options *opts, double fraction, sdf_diag *diag)
{
    if (opts->progress && opts->progress(opts->user, fraction))
        return sdf__diag_set(diag, SDF_ECANCELED, 0, -1, "the bake was canceled");
    return 0;
}

/* Samples the scan could not place (NAN) are asked through sdf_query. */
static int search_missing(const bake_plan *plan, size_t first_node, size_t count, float *f)
{
    size_t m = (size_t)plan->fine_count;
    for (size_t q = 0; q < count * m; q++) {
        if (!isnan(f[q]))
            continue;
        size_t ijk[3];
        double x[3];
        float node[3], p[3];
        node_index(&plan->info, first_node + q / m, ijk);
        sdf__volume_node(&plan->info, ijk[0], ijk[1], ijk[2], x);
        for (int a = 0; a < 3; a++)
            node[a] = (float)x[a];
        sample_point(plan, node, q % m, p);
        sdf_query_result res = {.distance = f + q};
        int rc = sdf_query(plan->mesh, p, 1, &plan->query, &res);
        if (rc)
            return rc;
    }
    return 0;
}

typedef struct fit_state {
    const bake_plan *plan;
    bake_out *o;
    double smallest_f[SDF__MAX_THREADS], largest_f[SDF__MAX_THREADS]; /* per worker */
} fit_state;

/* sdf__sample_fn: Algorithm 1's fit of a run of nodes from their scanned samples. */
static int fit_samples(void *user, size_t first, size_t count, float *f, int worker)
{
    fit_state *fs = user;
    size_t m = (size_t)fs->plan->fine_count;
    int rc = search_missing(fs->plan, first, count, f);
    if (!rc)
        fit_nodes(fs->plan, f, count, fs->o->planes + 4 * first);
    for (size_t n = 0; !rc && n < count; n++) {
        double centre = f[n * m + m / 2]; /* the centre sample is the node */
        fs->smallest_f[worker] = fmin(fs->smallest_f[worker], centre);
        fs->largest_f[worker] = fmax(fs->largest_f[worker], centre);
    }
    return rc;
}

/* The scan takes the raw field on closed meshes signed by pseudonormals or unsigned
 * (scan/scan.h), in runs of whole z-slices that fit its scratch. */
static int scannable(const bake_plan *plan)
{
    const sdf_volume_info *in = &plan->info;
    return !plan->filter && sdf__scan_supported(plan->mesh, plan->query.sign) &&
           sdf__scan_fits(in->dims[0], in->dims[1], in->order == 1 ? in->fine_half : 0,
                          plan->query.threads);
}

/* The raw field on a closed mesh by closest-feature scan conversion (scan/scan.h), in runs
 * of whole z-slices: zero order gives sdf_query's floats at the nodes, first order the fine
 * samples that the planes are fitted to. */
static int scan_bake(const bake_plan *plan, bake_out *o, const sdf_bake_options *opts,
                     sdf_diag *diag)
{
    const sdf_volume_info *in = &plan->info;
    int first = in->order == 1;
    size_t slice = in->dims[0] * in->dims[1];
    sdf__scan *scan = NULL;
    fit_state *fs = first ? malloc(sizeof *fs) : NULL;
    int rc = first && !fs ? SDF_ENOMEM : sdf__scan_create(plan->mesh, in, &plan->query, &scan);
    if (rc)
        sdf__diag_set(diag, rc, 0, -1, "no memory for the bake's scratch");
    for (int t = 0; fs && t < SDF__MAX_THREADS; t++)
        fs->smallest_f[t] = INFINITY, fs->largest_f[t] = -INFINITY;
    if (fs)
        fs->plan = plan, fs->o = o;
    size_t per_call = rc          ? 1
                      : first     ? sdf__scan_sample_slices_per_call(scan, in->fine_half)
                                  : sdf__scan_slices_per_call(scan);
    for (size_t k = 0; !rc && k < in->dims[2]; k += per_call) {
        size_t end = k + per_call < in->dims[2] ? k + per_call : in->dims[2];
        rc = first ? sdf__scan_samples(scan, k, end, in->fine_half, in->fine_spacing,
                                       fit_samples, fs)
                   : sdf__scan_slices(scan, k, end,
                                      &(sdf_query_result){.distance = o->v->data.f + k * slice});
        if (rc)
            sdf__diag_set(diag, rc, 0, -1, "the scan failed: %s", sdf_strerror(rc));
        else
            rc = progress(opts, (double)end / (double)in->dims[2], diag);
    }
    for (int t = 0; fs && t < SDF__MAX_THREADS; t++) {
        o->smallest_f = fmin(o->smallest_f, fs->smallest_f[t]);
        o->largest_f = fmax(o->largest_f, fs->largest_f[t]);
    }
    free(fs);
    sdf__scan_destroy(scan);
    return rc;
}

/* Any field, any mesh: every node (and fine sample) asked through sdf_query or
 * sdf_query_filtered, in slabs of nodes. */
static int query_bake(const bake_plan *plan, bake_out *o, const sdf_bake_options *opts,
                      sdf_diag *diag)
{
    sdf_volume *v = o->v;
    int first = plan->info.order == 1, rc = 0;
    size_t m = first ? (size_t)plan->fine_count : 1;
    size_t per_slab = SLAB_QUERIES / (m * plan->queries_per_point);
    if (per_slab < 1)
        per_slab = 1;
    if (per_slab > v->nodes)
        per_slab = v->nodes;
    slab s = {.plan = plan};
    s.node_pos = sdf__big_alloc(per_slab * 3 * sizeof(float));
    s.node_f = first ? sdf__big_alloc(per_slab * sizeof(float)) : NULL;
    if (first) {
        s.sample_pos = sdf__big_alloc(per_slab * m * 3 * sizeof(float));
        s.sample_f = sdf__big_alloc(per_slab * m * sizeof(float));
        s.bound = sdf__big_alloc(per_slab * m * sizeof(double));
        s.hint = sdf__big_alloc(per_slab * m);
        s.run_start = sdf__big_alloc(per_slab * m);
    }
    if (!s.node_pos || (first && (!s.node_f || !s.sample_pos || !s.sample_f || !s.bound ||
                                  !s.hint || !s.run_start)))
        rc = sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory for the bake's scratch");
    for (size_t done = 0; !rc && done < v->nodes; done += s.count) {
        s.first = done;
        s.count = v->nodes - done < per_slab ? v->nodes - done : per_slab;
        if (!first) {
            s.node_f = v->data.f + done;
            rc = slab_nodes(&s);
            s.node_f = NULL;
        } else if (!(rc = slab_nodes(&s)) && !(rc = slab_samples(&s))) {
            for (size_t n = 0; n < s.count; n++) {
                o->largest_f = fmax(o->largest_f, (double)s.node_f[n]);
                o->smallest_f = fmin(o->smallest_f, (double)s.node_f[n]);
            }
            s.plane = o->planes + 4 * done;
            sdf__parallel_for(s.count, 256, plan->query.threads, fit_range, &s);
        }
        if (rc)
            sdf__diag_set(diag, rc, 0, -1, "distance queries failed: %s", sdf_strerror(rc));
        else
            rc = progress(opts, (double)(done + s.count) / (double)v->nodes, diag);
    }
    free_slab(&s);
    return rc;
}

/* An upper bound of what query_bake allocates: its slab arrays and the largest query it
 * makes (a slab's nodes, then their fine samples). A slab never holds two whole z-slices
 * when the scan does not take the bake, so no query of it takes sdf_query's lattice path. */
static size_t query_bake_scratch(const bake_plan *plan)
{
    int first = plan->info.order == 1;
    size_t m = first ? (size_t)plan->fine_count : 1;
    size_t nodes = plan->info.dims[0] * plan->info.dims[1] * plan->info.dims[2];
    size_t per_slab = SLAB_QUERIES / (m * plan->queries_per_point);
    per_slab = per_slab < 1 ? 1 : per_slab > nodes ? nodes : per_slab;
    size_t arrays = sdf__big_size(per_slab * 3 * sizeof(float));
    if (first)
        arrays += sdf__big_size(per_slab * sizeof(float)) +
                  sdf__big_size(per_slab * m * 3 * sizeof(float)) +
                  sdf__big_size(per_slab * m * sizeof(float)) +
                  sdf__big_size(per_slab * m * sizeof(double)) + 2 * sdf__big_size(per_slab * m);
    size_t largest = per_slab * m;
    int threads = plan->query.threads;
    size_t queries = plan->filter
                         ? sdf__filter_scratch_bound(&plan->resolved_filter, largest, 0, threads)
                         : sdf__query_scratch_bound(largest, threads);
    return arrays + queries;
}

int sdf_volume_bake_scratch(const sdf_mesh *mesh, const sdf_bake_options *opts, size_t *bytes,
                            sdf_diag *diag)
{
    if (!mesh || !bytes)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no mesh");
    bake_plan *plan;
    int rc = make_plan(mesh, opts, &plan, diag);
    if (rc)
        return rc;
    const sdf_volume_info *in = &plan->info;
    size_t nodes = in->dims[0] * in->dims[1] * in->dims[2];
    /* The plan, the volume's header and its data's rounding to huge pages (core/bigmem.h),
     * the first order's fit state and its planes (apart from the data when packed), the
     * sign's data made on first use, and the way the bake goes. */
    size_t data = nodes * (size_t)sdf_volume_channels(in) * 4;
    *bytes = sizeof(bake_plan) + sizeof(sdf_volume) + (sdf__big_size(data) - data) +
             sdf__mesh_first_use_bound(mesh, plan->query.sign) +
             (in->order == 1 ? sizeof(fit_state) : 0) +
             (in->order == 1 && in->encoding != SDF_ENCODING_FLOAT32
                  ? sdf__big_size(nodes * 4 * sizeof(float))
                  : 0) +
             (scannable(plan) ? sdf__scan_scratch_bound(mesh, in, plan->query.threads)
                              : query_bake_scratch(plan));
    free(plan);
    return 0;
}

int sdf_volume_bake(const sdf_mesh *mesh, const sdf_bake_options *opts, sdf_volume **out,
                    sdf_diag *diag)
{
    if (!out)
        return SDF_EINVAL;
    *out = NULL;
    if (!mesh)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "no mesh");
    sdf_bake_options defaults = {0};
    if (!opts)
        opts = &defaults;
    bake_plan *plan;
    int rc = make_plan(mesh, opts, &plan, diag);
    if (rc)
        return rc;
    bake_out o = {.smallest_f = INFINITY, .largest_f = -INFINITY};
    if ((rc = sdf__volume_alloc(&plan->info, &o.v)))
        sdf__diag_set(diag, rc, 0, -1, "no memory for a volume of %zu x %zu x %zu nodes",
                      plan->info.dims[0], plan->info.dims[1], plan->info.dims[2]);
    int first = plan->info.order == 1;
    /* First order: the local planes, in the volume's own data when it holds four floats a
     * node (store_planes). */
    int planes_apart = first && plan->info.encoding != SDF_ENCODING_FLOAT32;
    if (!rc && first)
        o.planes = planes_apart ? sdf__big_alloc(o.v->nodes * 4 * sizeof(float)) : o.v->data.f;
    if (!rc && first && !o.planes)
        rc = sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory for the bake's scratch");
    if (!rc)
        rc = scannable(plan) ? scan_bake(plan, &o, opts, diag) : query_bake(plan, &o, opts, diag);
    sdf_volume *v = o.v;
    if (!rc && first) {
        /* The packed values span the distances at the nodes, [smallest f, largest f]. A plane
         * whose fitted gradient is short (near the medial axis) has its value inflated by
         * step 6's normalisation; spanning those outliers would coarsen every other node, so
         * they clamp to the span instead. */
        if (v->info.encoding == SDF_ENCODING_PACKED32) {
            v->info.packed_center = 0.5 * (o.largest_f + o.smallest_f);
            v->info.packed_range =
                o.largest_f > o.smallest_f ? 0.5 * (o.largest_f - o.smallest_f) : 1;
        }
        store_planes(v, o.planes, plan->query.threads);
    }
    if (planes_apart)
        sdf__big_free(o.planes);
    free(plan);
    if (rc) {
        sdf_volume_destroy(v);
        return rc;
    }
    *out = v;
    return 0;
}
