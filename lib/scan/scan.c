/* scan.c - closest-feature scan conversion of a volume's lattice (see scan.h).
 *
 * Features are numbered faces first, then edges (the mesh's edge ids), then vertices. Each
 * feature's region is built as a convex polyhedron twice over: as half-spaces n . p <= c,
 * which decide which nodes of a lattice row it holds, and as corners and edges, whose
 * crossings with a slice give the range of rows to visit. Regions reach only as far as any
 * node can be from the surface (`reach_front` on the outward side, `reach_back` inside),
 * which a coarse lattice of exact queries bounds. Worker threads take runs of features in
 * the mesh tree's order, each into its own per-node "best so far" arrays (no locks; the loop
 * over one region's nodes is scan/raster.c); the rows are then finished in parallel, the
 * workers' bests merged by (distance, feature id) so the result does not depend on how the
 * features were shared out. */
#include <assert.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/bigmem.h"
#include "core/parallel.h"
#include "core/workspace.h"
#include "mesh/mesh.h"
#include "mesh/topology.h"
#include "scan/regions.h"
#include "points/points.h"
#include "points/packet.h"
#include "geom/triangle.h"
#include "scan/raster.h"
#include "scan/scan.h"

#define COARSE_STEP 8      /* nodes between the coarse lattice's nodes */
#define FEATURE_CHUNK 256  /* features per work item */
#define SCAN_BUDGET_BYTES ((size_t)64 << 20) /* the workers' per-node arrays of one call */
#define PREFETCH_AHEAD 8   /* features between a prefetch and the region's build */
#define MERGE_NODES 256    /* nodes per sdf__sample_fn call */
#define SCAN_SLICE_LIMIT ((size_t)256 << 20) /* most scratch bytes one z-slice may take */
/* The same, first order: fewer calls rebuild fewer regions that span several (each worker
 * has its own copy, so more threads take fewer slices a call); past this budget the memory
 * grows faster than the time falls. */
#define SCAN_SAMPLE_BUDGET_BYTES ((size_t)256 << 20)
/* The region's estimate and the exact test's distance both lie within this much of the
 * scene's size of the true distance. */
#define SURE_DISTANCE_OF_EXTENT 1e-13

/* ---- calls ------------------------------------------------------------------------------- */

/* A region's z-span, rounded outwards to float, into span[0..1] (NAN..NAN when the feature
 * has none). */
static void record_zspan(const sdf__region *r, int built, float *span)
{
    span[0] = span[1] = NAN;
    if (!built)
        return;
    double lo = INFINITY, hi = -INFINITY;
    for (int c = 0; c < r->corners; c++)
        lo = sdf__min2(lo, r->corner[c][2]), hi = sdf__max2(hi, r->corner[c][2]);
    span[0] = nextafterf((float)lo, -INFINITY);
    span[1] = nextafterf((float)hi, INFINITY);
}

/* Does a recorded span miss the call's [z0, z1]? (NAN: not known to.) */
static int misses(const float *span, double z0, double z1)
{
    return span[0] > z1 || span[1] < z0;
}

static void features_range(void *ctx, size_t begin, size_t end, int worker)
{
    sdf__scan_call *st = ctx;
    sdf__region *r = &st->regions[worker];
    size_t mine = (size_t)worker * st->nodes;
    sdf__node_best *best = st->best ? st->best + mine : NULL;
    float *samples = st->sample_best ? st->sample_best + mine * SDF__POW3(st->fine_w) : NULL;
    const sdf__scan *s = st->scan;
    /* The call's z-span, widened by the dilation and padding: regions wholly outside it are
     * not built once their spans are known; the first call of a bake in several builds every
     * region and records its span. */
    double z0 = s->coord[2][st->k0] - st->rho[2] - s->feat.row_pad;
    double z1 = s->coord[2][st->k1 - 1] + st->rho[2] + s->feat.row_pad;
    int known = s->zspan && s->zspan_known, record = s->zspan && !s->zspan_known;
    for (size_t q = begin; q < end; q++) {
        uint32_t f = s->order[q];
        if (q + PREFETCH_AHEAD < end)
            sdf__feature_prefetch(&s->feat, s->order[q + PREFETCH_AHEAD], 0);
        if (q + PREFETCH_AHEAD / 2 < end)
            sdf__feature_prefetch(&s->feat, s->order[q + PREFETCH_AHEAD / 2], 1);
        if (known && misses(s->zspan + 2 * f, z0, z1))
            continue;
        int built = sdf__region_build(&s->feat, f, r);
        if (record)
            record_zspan(r, built, s->zspan + 2 * f);
        if (!built || (record && misses(s->zspan + 2 * f, z0, z1)))
            continue;
        sdf__fat_region *fr = st->fine_w ? &st->fat[worker] : NULL;
        if (fr)
            sdf__fat_prepare(st, r, fr);
        sdf__scan_region(st, r, f, best, samples, fr);
    }
}

/* Known spans let the calls of a bake in several calls skip the regions outside them: an
 * array for them, filled by the first call (features_range), which builds every region
 * anyway (a pass of its own would build them all once more). */
static int ensure_zspans(sdf__scan *s, sdf__scan_call *st)
{
    if (s->zspan || (st->k0 == 0 && st->k1 == s->dims[2]))
        return 0;
    float *span = malloc((2 * s->feat.count + 1) * sizeof *span);
    if (!span)
        return SDF_ENOMEM;
    s->zspan = span;
    return 0;
}

/* The exact test of the triangles in `list`, kept in *hit where nearer (ties: the lower id,
 * the searches' rule: geom/triangle.h). */
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
    sdf__scan_call *st = ctx;
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
                const sdf__node_best *nb = &st->best[n];
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
    size_t node_bytes = fine_half ? SDF__POW3(2 * fine_half + 1) * sizeof(float)
                                  : sizeof(sdf__node_best);
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
    /* sdf__features_init's arrays (positions in double, edge ends, two CSR lists, each
     * vertex's first triangle) and its temporaries (the pairs' values and the neighbours'
     * keys, the two sorts' fill cursors at once), counted all at once. */
    size_t adjacency = 24 * vertices + 8 * edges + 4 * (edges + 1) + 12 * faces +
                       4 * (vertices + 1) + 8 * edges + 4 * (vertices + 1) + 12 * faces +
                       16 * edges + 4 * (edges + 1) + 4 * (vertices + 1);
    /* The visit order with its flags, the z-spans. */
    size_t order = (4 + 1 + 8) * (features + 1);
    /* The coarse lattice of exact distances: its points, values, closest points, axes and
     * queries. */
    size_t lattice = 28 * coarse + 8 * axes + sdf__query_scratch_bound(coarse, threads);
    /* Node coordinates (double, float while made). */
    size_t coords = 12 * axes;
    /* One call's per-node arrays, each worker's (as slices_within and sdf__scan_fits size
     * them: the budget, or one slice when that is larger, and no more slices than there
     * are; kept between calls in the scan's workspace), and its per-row arrays. */
    size_t workers = (size_t)sdf__effective_threads(threads, features, 1);
    size_t slice = nx * ny, call;
    if (info->order == 1) {
        size_t w3 = SDF__POW3(2 * info->fine_half + 1), node_bytes = w3 * sizeof(float);
        size_t slices = slices_for(slice, workers, node_bytes, SCAN_SAMPLE_BUDGET_BYTES);
        slices = slices > info->dims[2] ? info->dims[2] : slices;
        call = sdf__big_size(workers * slices * slice * node_bytes) +
               workers * (MERGE_NODES * w3 * sizeof(float) + sizeof(sdf__fat_region));
    } else {
        size_t slices = slices_for(slice, workers, sizeof(sdf__node_best), SCAN_BUDGET_BYTES);
        slices = slices > info->dims[2] ? info->dims[2] : slices;
        call = sdf__big_size(workers * slices * slice * sizeof(sdf__node_best)) +
               workers * nx * (3 * sizeof(float) + sizeof(sdf__hit) + sizeof(uint32_t) +
                               sizeof(float));
    }
    call += workers * sizeof(sdf__region) + sizeof(sdf__scan) + sdf__ws_create_bytes();
    return adjacency + order + lattice + coords + call;
}

size_t sdf__scan_slices_per_call(const sdf__scan *s)
{
    return slices_within(s, sizeof(sdf__node_best), SCAN_BUDGET_BYTES);
}

/* Fresh per-node arrays, each part first touched by the thread that clears it. */
static void clear_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    sdf__scan_call *st = ctx;
    for (size_t n = begin; n < end; n++) {
        if (st->sample_best)
            st->sample_best[n] = INFINITY;
        else
            st->best[n] = (sdf__node_best){INFINITY, UINT32_MAX, 0};
    }
}

int sdf__scan_slices(sdf__scan *s, size_t k0, size_t k1, const sdf_query_result *out)
{
    assert(k0 < k1 && k1 <= s->dims[2]);
    size_t nx = s->dims[0], rows = (k1 - k0) * s->dims[1];
    int workers = sdf__effective_threads(s->query.threads, s->feat.count, FEATURE_CHUNK);
    size_t w = (size_t)workers, nodes = rows * nx;
    /* Sure nodes (rows_range) only where distances alone are asked for. */
    int distances_only = out->distance && !out->gradient && !out->closest && !out->triangle &&
                         !out->barycentric;
    sdf__scan_call st = {.scan = s, .k0 = k0, .k1 = k1, .nodes = nodes,
                         .best = sdf__ws_alloc(s->ws, SDF__WS_SCAN_BESTS,
                                               w * nodes * sizeof(sdf__node_best)),
                         .distances_only = distances_only,
                         .regions = malloc(w * sizeof(sdf__region)),
                         .points = malloc(w * nx * 3 * sizeof(float)),
                         .hits = malloc(w * nx * sizeof(sdf__hit)),
                         .slow = malloc(w * nx * sizeof(uint32_t)),
                         .slow_out = malloc(w * nx * sizeof(float)),
                         .workers = workers, .out = *out};
    int rc = st.best && st.regions && st.points && st.hits && st.slow && st.slow_out
                 ? 0
                 : SDF_ENOMEM;
    if (!rc)
        rc = ensure_zspans(s, &st);
    if (!rc) {
        sdf__parallel_for(w * nodes, (size_t)1 << 16, workers, clear_range, &st);
        sdf__parallel_for(s->feat.count, FEATURE_CHUNK, workers, features_range, &st);
        s->zspan_known = s->zspan != NULL;
        sdf__parallel_for(rows, 8, workers, rows_range, &st);
    }
    sdf__ws_free(s->ws, st.best), free(st.regions), free(st.points);
    free(st.hits), free(st.slow), free(st.slow_out);
    return rc;
}

/* ---- first order ------------------------------------------------------------------------ */

size_t sdf__scan_sample_slices_per_call(const sdf__scan *s, int half)
{
    return slices_within(s, SDF__POW3(2 * half + 1) * sizeof(float), SCAN_SAMPLE_BUDGET_BYTES);
}

/* Runs of nodes: the workers' bests merged into signed distances (NAN for a sample no
 * region held; none should be), handed to the consumer. */
static void merge_samples(void *ctx, size_t begin, size_t end, int worker)
{
    sdf__scan_call *st = ctx;
    size_t m = SDF__POW3(st->fine_w), all = st->nodes * m, count = (end - begin) * m;
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
    assert(k0 < k1 && k1 <= s->dims[2] && half >= 1 && 2 * half + 1 <= SDF__SCAN_MAX_W);
    size_t w3 = SDF__POW3(2 * half + 1), nodes = (k1 - k0) * s->dims[0] * s->dims[1];
    int workers = sdf__effective_threads(s->query.threads, s->feat.count, FEATURE_CHUNK);
    size_t w = (size_t)workers, scratch = w * nodes * w3;
    sdf__scan_call st = {.scan = s, .k0 = k0, .k1 = k1, .nodes = nodes,
                         .regions = malloc(w * sizeof(sdf__region)), .workers = workers,
                         .fine_w = 2 * half + 1,
                         .sample_best = sdf__ws_alloc(s->ws, SDF__WS_SCAN_SAMPLES,
                                                      scratch * sizeof(float)),
                         .merged = malloc(w * MERGE_NODES * w3 * sizeof(float)),
                         .fat = malloc(w * sizeof(sdf__fat_region)), .consume = consume,
                         .user = user};
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
        s->zspan_known = s->zspan != NULL;
        sdf__parallel_for(nodes, MERGE_NODES, workers, merge_samples, &st);
        for (int t = 0; t < workers && !rc; t++)
            rc = st.consume_rc[t];
    }
    free(st.regions), free(st.merged), free(st.fat);
    return rc;
}

/* ---- set-up ------------------------------------------------------------------------------ */

/* Features in the order the mesh's tree holds its triangles, each face followed by those of
 * its edges and vertices not yet listed (then any feature no triangle of the tree lists): a
 * subtree's triangles are neighbours in space, so features near in this order write to
 * nearby nodes and the per-node arrays stay in cache, and the order costs one pass over the
 * tree rather than a sort of the features' positions. */
static void list_feature(uint8_t *listed, uint32_t *order, size_t *n, size_t feature)
{
    if (!listed[feature]) {
        listed[feature] = 1;
        order[(*n)++] = (uint32_t)feature;
    }
}

static int feature_order(sdf__scan *s)
{
    const sdf__features *f = &s->feat;
    const sdf__tree *tree = &s->mesh->tree;
    uint8_t *listed = calloc(f->count + 1, 1);
    s->order = malloc((f->count + 1) * sizeof *s->order);
    if (!listed || !s->order) {
        free(listed);
        return SDF_ENOMEM;
    }
    size_t n = 0;
    for (size_t i = 0; i < tree->prim_count; i++) {
        size_t t = tree->prims[i];
        list_feature(listed, s->order, &n, t);
        for (size_t c = 3 * t; c < 3 * t + 3; c++)
            list_feature(listed, s->order, &n, f->faces + s->mesh->edge_of[c]);
        for (size_t c = 3 * t; c < 3 * t + 3; c++)
            list_feature(listed, s->order, &n, f->faces + f->edges + f->triangles[c]);
    }
    for (size_t feature = 0; feature < f->count; feature++)
        list_feature(listed, s->order, &n, feature);
    free(listed);
    return 0;
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
    /* The per-node bests live in the caller's workspace, claimed for this one call, or (bakes
     * pass none) in the scan's own, kept across its calls; the scan's own queries (its coarse
     * lattice) take none. */
    s->ws = opts->workspace;
    s->query.workspace = NULL;
    double extent = mesh->report.diagonal;
    int rc = s->ws ? 0 : sdf_workspace_create(&s->own_ws);
    if (!rc && !s->ws)
        s->ws = s->own_ws;
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
        rc = sdf__features_init(&s->feat, mesh, opts->threads);
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
    free(s->order), free(s->coarse), free(s->zspan);
    sdf_workspace_destroy(s->own_ws);
    free(s);
}
