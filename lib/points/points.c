/* points.c - the point engine (points.h), and sdf_winding_numbers on the same batches.
 *
 * A checked batch is cut into chunks that worker threads take in turn. The closest points
 * come from packets of Morton-ordered points traversing our BVH together (points/packet.c;
 * points too spread out for a packet walk it one at a time), or with SDF_TRAVERSAL_SINGLE
 * from one Embree rtcPointQuery per point; all run the same exact double-precision triangle
 * test (geom/triangle.h). Then, per point, the sign by the requested method and the outputs
 * asked for. The distances do not depend on the thread count or the traversal. The filtered
 * field's samples (sdf__query_seeded) go by clusters (points/cluster.h). */
#include "points/points.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bvh/embree.h"
#include "core/bigmem.h"
#include "core/parallel.h"
#include "core/workspace.h"
#include "mesh/mesh.h"
#include "points/cluster.h"
#include "points/morton.h"
#include "points/packet.h"
#include "sign/pseudonormal.h"
#include "sign/raycast.h"
#include "sign/winding.h"

#define CHUNK 256          /* points per work item, single traversal */
#define PACKET_CHUNK 4096  /* most Morton-ordered points per work item, packet traversal */
/* A packet is traversed together only if its points lie within this many times (their
 * distance bound + the mean leaf size) of each other: sparse batches (1,000 points over a
 * mesh) share too little of their traversals. A smaller factor sends dense batches one at a
 * time, a larger one makes sparse batches walk together for nothing; 3 is near the best of
 * both (docs/performance.md). The leaf size keeps near-surface points (d_prev ~ 0), which
 * share their leaves, from falling back needlessly. */
#define PACKET_SPREAD 3.0
/* Candidate triangles one cluster of seeded points may hold (points/cluster.h); a cluster
 * that could be nearest to more takes the packets. Fewer sent many of a fine mesh's
 * clusters to the slower packets; more did not pay for their scratch. */
#define CLUSTER_CANDIDATES 1024
#define SEEDED_CHUNK 1024 /* seeded points per work item */
#define VISIT_COPY_CHUNK 65536 /* points per work item of the copy in visit order */
#define COPY_AHEAD 32          /* the copies' reads (and writes) prefetched this far ahead */

typedef struct batch {
    const sdf_mesh *mesh;
    const char *points;
    size_t stride;
    sdf_sign_method sign;
    sdf_query_result *out;
    float *winding;
    const uint32_t *order; /* packet traversal: visit order */
    float *visit_xyz;       /* packet traversal: the points copied in visit order, or NULL */
    sdf_query_result *final; /* packet traversal: the caller's outputs, filled at the end
                                from `out`, which is then indexed by visit position; or NULL */
    const double *bound;   /* sdf__query_seeded: each point's distance bound */
    const int8_t *sign_hint; /* sdf__query_seeded: a sign known in advance (+-1), or 0 */
    const uint8_t *run_start; /* sdf__query_seeded: 1 where a run of nearby points begins */
    sdf__cluster **clusters;  /* sdf__query_seeded: each worker's scratch (NULL: packets) */
    int by_embree;            /* SDF_TRAVERSAL_SINGLE: one rtcPointQuery per point */
    sdf_workspace *ws;        /* the call's claimed workspace (core/workspace.h), or NULL */
} batch;

static const float *point_at(const batch *b, size_t i)
{
    return (const float *)(b->points + i * b->stride);
}

/* Validate the common arguments and fill in the batch. */
static int batch_args(const sdf_mesh *mesh, const float *points, size_t count,
                      const sdf_query_options *opts, batch *b)
{
    if (!mesh || (!points && count))
        return SDF_EINVAL;
    size_t stride = opts && opts->point_stride ? opts->point_stride : 3 * sizeof(float);
    if (stride < 3 * sizeof(float) || stride % sizeof(float))
        return SDF_EINVAL;
    sdf_sign_method sign = opts ? opts->sign : SDF_SIGN_AUTO;
    if (sign < SDF_SIGN_AUTO || sign > SDF_SIGN_NONE)
        return SDF_EINVAL;
    if (opts && (opts->traversal < SDF_TRAVERSAL_PACKETS || opts->traversal > SDF_TRAVERSAL_SINGLE))
        return SDF_EINVAL;
    if (sign == SDF_SIGN_AUTO)
        sign = mesh->report.auto_sign;
    *b = (batch){.mesh = mesh, .points = (const char *)points, .stride = stride, .sign = sign,
                 .ws = opts ? opts->workspace : NULL};
    return 0;
}

/* Validate the common arguments; find the first point that is not finite or lies beyond
 * SDF_MAX_COORDINATE (fabsf(NaN) fails the comparison too). */
static int check_batch(const sdf_mesh *mesh, const float *points, size_t count,
                       const sdf_query_options *opts, batch *b, size_t *bad_index)
{
    int rc = batch_args(mesh, points, count, opts, b);
    if (rc)
        return rc;
    for (size_t i = 0; i < count; i++) {
        const float *p = point_at(b, i);
        if (!(fabsf(p[0]) <= SDF_MAX_COORDINATE && fabsf(p[1]) <= SDF_MAX_COORDINATE &&
              fabsf(p[2]) <= SDF_MAX_COORDINATE)) {
            if (bad_index)
                *bad_index = i;
            return SDF_ENONFINITE;
        }
    }
    /* Caches made on first use: rays need Embree's scene, winding numbers their moments. */
    return b->sign == SDF_SIGN_RAYCAST ? sdf__bvh_ready(mesh->bvh)
           : b->sign == SDF_SIGN_WINDING ? sdf__mesh_need_winding(mesh) : 0;
}

/* The side of the closest feature's pseudonormal `normal` that p is on: -1 or +1. */
static float pseudonormal_side(const float p[3], const sdf__hit *hit, const float normal[3])
{
    double s = 0;
    for (int i = 0; i < 3; i++)
        s += (p[i] - hit->point[i]) * normal[i];
    return s < 0 ? -1.0f : 1.0f;
}

/* Within this many surface_epsilon (4 float epsilons of the mesh's extent each) of a closed
 * mesh that does not intersect itself, the sign by rays is the pseudonormal's:
 * rays from so close cross the surface within rounding of the closest point, where a shared
 * edge under it counts twice or not at all for every direction at once (the unit cube one
 * float step under its top face's diagonal). The pseudonormal test is exact there. */
#define RAY_NEAR 64

static int ray_near(const sdf_mesh *m, double d)
{
    /* as for auto: pseudonormals decide only on closed meshes that do not cross themselves */
    return m->report.closed && !m->report.self_intersecting &&
           d < RAY_NEAR * (double)m->surface_epsilon;
}

/* -1 inside, +1 outside (or unsigned). `winding`: the point's winding number when it was
 * computed with its packet, else NAN. `normal`: the closest feature's pseudonormal, when
 * the sign is by pseudonormals or by rays at `d` within ray_near. */
static float sign_of(const batch *b, const float p[3], const sdf__hit *hit, const float normal[3],
                     double winding, double d)
{
    const sdf_mesh *m = b->mesh;
    switch (b->sign) {
    case SDF_SIGN_PSEUDONORMAL: {
        /* A closed mesh's inside lies within its box, so outside the box the sign needs no
         * closest feature, which double precision cannot single out for points ~1e16 times
         * the mesh's size away (every feature then lies at the same rounded distance). */
        const float *lo = m->report.bbox_min, *hi = m->report.bbox_max;
        if (m->report.closed && (p[0] <= lo[0] || p[0] >= hi[0] || p[1] <= lo[1] ||
                                 p[1] >= hi[1] || p[2] <= lo[2] || p[2] >= hi[2]))
            return 1.0f;
        return pseudonormal_side(p, hit, normal);
    }
    case SDF_SIGN_WINDING: {
        double q[3] = {p[0], p[1], p[2]};
        if (isnan(winding))
            winding = sdf__winding_number(sdf__mesh_winding(m), q);
        return winding > 0.5 ? -1.0f : 1.0f;
    }
    case SDF_SIGN_RAYCAST:
        if (ray_near(m, d))
            return pseudonormal_side(p, hit, normal);
        return sdf__raycast_inside(m->bvh, p) ? -1.0f : 1.0f;
    default:
        return 1.0f;
    }
}

/* Sign and outputs of point i (at p), given its closest point (and its winding number, or
 * NAN).
 * The hit is read in place: a local copy of it made the pseudonormal's first read of the
 * face normal stall on the copy's stores. */
static void finish(const batch *b, size_t i, const float p[3], const sdf__hit *hit,
                   double winding)
{
    const sdf_mesh *m = b->mesh;
    double d = sqrt(hit->dist2);
    int on_surface = d <= m->surface_epsilon;
    float normal[3] = {0, 0, 0};
    int hinted = b->sign_hint && b->sign_hint[i] && d > 0;
    int by_normal = b->sign == SDF_SIGN_PSEUDONORMAL ||
                    (b->sign == SDF_SIGN_RAYCAST && ray_near(m, d));
    if ((by_normal && !hinted) || (on_surface && b->out->gradient))
        sdf__pseudonormal(m->normals, m->triangles, m->edge_of, hit->triangle, hit->feature,
                          hit->face_normal, normal);
    float s = hinted ? (float)b->sign_hint[i]
              : d > 0 ? sign_of(b, p, hit, normal, winding, d) : 1.0f;
    sdf_query_result *o = b->out;
    if (o->distance)
        o->distance[i] = s * (float)d;
    if (o->gradient) {
        for (int k = 0; k < 3; k++)
            o->gradient[3 * i + k] = on_surface ? normal[k] : (float)(s * (p[k] - hit->point[k]) / d);
    }
    if (o->closest)
        for (int k = 0; k < 3; k++)
            o->closest[3 * i + k] = (float)hit->point[k];
    if (o->triangle)
        o->triangle[i] = hit->triangle;
    if (o->barycentric)
        for (int k = 0; k < 3; k++)
            o->barycentric[3 * i + k] = (float)hit->bary[k];
}

/* The closest point to p by one walk of our BVH from bound2 (packet.h: sdf__closest_point);
 * a point that walk hands back (a bound rounding made too small, more near-equal candidates
 * than it holds) by the exact-only walk. */
static void closest_by_tree(const sdf_mesh *m, const float *p, double bound2, sdf__hit *hit)
{
    sdf__closest_point(&m->tree, m->positions, m->triangles, (float)m->report.diagonal, p,
                       bound2, hit);
    if (!isfinite(hit->dist2))
        sdf__closest_exact(&m->tree, m->positions, m->triangles, p, hit);
}

static void answer_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    const sdf_mesh *m = b->mesh;
    for (size_t i = begin; i < end; i++) {
        sdf__hit hit;
        const float *p = point_at(b, i);
        if (b->by_embree)
            sdf__bvh_closest(m->bvh, p, &hit);
        else
            closest_by_tree(m, p, INFINITY, &hit);
        finish(b, i, p, &hit, NAN);
    }
}

/* The point at position `pos` of the visit order. */
static const float *visit_point(const batch *b, size_t pos)
{
    return b->visit_xyz ? b->visit_xyz + 3 * pos : point_at(b, b->order[pos]);
}

/* Answer the points at visit positions [first, first + n) one at a time by our BVH
 * (packet.h: sdf__closest_point), each search starting from bound2[i] (NULL: unbounded). */
static void single_points(const batch *b, size_t first, int n, const double *bound2,
                          sdf__hit *hits)
{
    const sdf_mesh *m = b->mesh;
    for (int i = 0; i < n; i++) {
        size_t pos = first + (size_t)i;
        const float *p = visit_point(b, pos);
        closest_by_tree(m, p, bound2 ? bound2[i] : INFINITY, &hits[i]);
        finish(b, b->final ? pos : b->order[pos], p, &hits[i], NAN);
    }
}

/* Winding numbers for a packet's points in one traversal when the sign needs them (sign/
 * winding.h: the same values as one point at a time), else NAN. */
static void packet_winding(const batch *b, const sdf__packet *pk, double *winding)
{
    _Static_assert(SDF__WINDING_LANES >= SDF__PACKET, "a packet fits the winding lanes");
    if (b->sign != SDF_SIGN_WINDING) {
        for (int i = 0; i < pk->n; i++)
            winding[i] = NAN;
        return;
    }
    double qx[SDF__WINDING_LANES], qy[SDF__WINDING_LANES], qz[SDF__WINDING_LANES];
    for (int i = 0; i < SDF__WINDING_LANES; i++) { /* padded lanes repeat the last point */
        int j = i < pk->n ? i : pk->n - 1;
        qx[i] = pk->x[j], qy[i] = pk->y[j], qz[i] = pk->z[j];
    }
    sdf__winding_packet(sdf__mesh_winding(b->mesh), qx, qy, qz, pk->n, winding);
}

/* Signs and outputs of a packet's points (coordinates filled in for lanes < n) whose
 * closest points are known: lane i is point order[i] or, without an order, point first + i.
 * A hit with dist2 == INFINITY (a bound rounding could not honour) is searched again. */
static void finish_packet(const batch *b, const sdf__packet *pk, const uint32_t *order,
                          size_t first, sdf__hit *hits)
{
    double winding[SDF__PACKET];
    int all_hinted = b->sign_hint != NULL;
    for (int i = 0; i < pk->n && all_hinted; i++)
        all_hinted = b->sign_hint[order ? order[i] : first + (size_t)i] != 0;
    if (all_hinted) /* every sign is known: no winding traversal */
        for (int i = 0; i < pk->n; i++)
            winding[i] = NAN;
    else
        packet_winding(b, pk, winding);
    for (int i = 0; i < pk->n; i++) {
        size_t idx = order ? order[i] : first + (size_t)i;
        const float p[3] = {pk->x[i], pk->y[i], pk->z[i]};
        if (!isfinite(hits[i].dist2))
            sdf__closest_exact(&b->mesh->tree, b->mesh->positions, b->mesh->triangles, p,
                               &hits[i]);
        finish(b, idx, p, &hits[i], winding[i]);
    }
}

/* Traverse one packet (its points and bounds filled in for lanes < n) and finish its points
 * (lanes as in finish_packet). */
static void answer_packet(const batch *b, sdf__packet *pk, const uint32_t *order, size_t first,
                          sdf__hit *hits)
{
    const sdf_mesh *m = b->mesh;
    for (int i = pk->n; i < SDF__PACKET; i++) /* pad: the box tests run on whole groups */
        pk->x[i] = pk->x[pk->n - 1], pk->y[i] = pk->y[pk->n - 1], pk->z[i] = pk->z[pk->n - 1];
    sdf__closest_packet(&m->tree, m->positions, m->triangles, (float)m->report.diagonal, pk,
                        hits);
    finish_packet(b, pk, order, first, hits);
}

/* Positions [begin, end) of the Morton order, packet by packet. Each packet's bounds are
 * seeded from the last point answered before it (packet.h, lever 1); a work item's first
 * point is answered alone so no packet ever starts unbounded. A packet spread over a region
 * much larger than its distances shares too little of its traversal (sparse batches, far
 * points): its points go one at a time instead. */
static void packet_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    const sdf_mesh *m = b->mesh;
    sdf__packet pk;
    sdf__hit hits[SDF__PACKET];
    single_points(b, begin, 1, NULL, hits);
    const float *first = visit_point(b, begin);
    double prev[3] = {first[0], first[1], first[2]}, prev_d = sqrt(hits[0].dist2);
    /* That point's closest point is on the surface, so its distance from any point bounds
     * that point's distance as well; beside each other over the surface it is the tighter
     * of the two bounds (the nearest of the last packet's closest points gained no more). */
    double near[3] = {hits[0].point[0], hits[0].point[1], hits[0].point[2]};
    for (size_t k = begin + 1; k < end; k += SDF__PACKET) {
        pk.n = (int)(end - k < SDF__PACKET ? end - k : SDF__PACKET);
        /* The next packet's points, scattered in memory by the Morton order unless they
         * were copied in it, are fetched while this one is traversed. */
        for (size_t i = k + SDF__PACKET; !b->visit_xyz && i < k + 2 * SDF__PACKET && i < end; i++)
            __builtin_prefetch(point_at(b, b->order[i]));
        double spread = 0;
        for (int i = 0; i < pk.n; i++) {
            const float *p = visit_point(b, k + (size_t)i);
            /* Answers land in request order, scattered by the Morton order: ask for the line
             * now, so finish() does not wait on it. */
            if (b->out->distance && !b->final)
                __builtin_prefetch(b->out->distance + b->order[k + (size_t)i], 1);
            pk.x[i] = p[0], pk.y[i] = p[1], pk.z[i] = p[2];
            double dx = p[0] - prev[0], dy = p[1] - prev[1], dz = p[2] - prev[2];
            double gap = sqrt(dx * dx + dy * dy + dz * dz), bound = prev_d + gap;
            double ex = p[0] - near[0], ey = p[1] - near[1], ez = p[2] - near[2];
            double via_near2 = ex * ex + ey * ey + ez * ez;
            pk.bound2[i] = via_near2 < bound * bound ? via_near2 : bound * bound;
            spread = gap > spread ? gap : spread;
        }
        if (spread > PACKET_SPREAD * (prev_d + m->tree.leaf_size)) {
            single_points(b, k, pk.n, pk.bound2, hits);
        } else {
            if (b->final)
                answer_packet(b, &pk, NULL, k, hits);
            else
                answer_packet(b, &pk, b->order + k, 0, hits);
        }
        const float *last = visit_point(b, k + (size_t)pk.n - 1);
        prev[0] = last[0], prev[1] = last[1], prev[2] = last[2];
        prev_d = sqrt(hits[pk.n - 1].dist2);
        for (int a = 0; a < 3; a++)
            near[a] = hits[pk.n - 1].point[a];
    }
}

/* The Morton visit order for the packet traversal; NULL for the single traversal, a batch of
 * one, or no memory (the single traversal then gives the same answers). */
static uint32_t *packet_order(const batch *b, size_t count, const sdf_query_options *opts)
{
    if ((opts && opts->traversal == SDF_TRAVERSAL_SINGLE) || count < 2 || count > UINT32_MAX)
        return NULL;
    uint32_t *order = sdf__ws_alloc(b->ws, SDF__WS_ORDER, count * sizeof *order);
    if (order && sdf__morton_order(b->points, b->stride, count, opts ? opts->threads : 0, b->ws,
                                   order)) {
        sdf__ws_free(b->ws, order);
        order = NULL;
    }
    return order;
}

/* Points [first, first + n), n <= SDF__PACKET, as one packet: their coordinates, and their
 * bounds from b->bound when `bounded`. */
static void fill_packet(const batch *b, size_t first, int n, int bounded, sdf__packet *pk)
{
    pk->n = n;
    for (int i = 0; i < n; i++) {
        const float *p = point_at(b, first + (size_t)i);
        pk->x[i] = p[0], pk->y[i] = p[1], pk->z[i] = p[2];
        if (bounded)
            pk->bound2[i] = b->bound[first + (size_t)i] * b->bound[first + (size_t)i];
    }
}

/* Runs of nearby points (sdf__query_seeded), up to SDF__CLUSTER_MAX at a time, each never
 * crossing the start of a run: by one candidate list per cluster (points/cluster.h), or, where
 * too many triangles could be closest, in bounded packets. */
static void seeded_range(void *ctx, size_t begin, size_t end, int worker)
{
    const batch *b = ctx;
    const sdf_mesh *m = b->mesh;
    sdf__cluster *cluster = b->clusters[worker];
    sdf__packet pk;
    sdf__hit hits[SDF__CLUSTER_MAX];
    /* A point whose sign is known takes the float distance (sdf__query_seeded), and needs its
     * exact closest point only for outputs other than the distance. */
    const sdf_query_result *o = b->out;
    int distance_only = !o->gradient && !o->closest && !o->triangle && !o->barycentric;
    uint8_t want[SDF__CLUSTER_MAX];
    int n;
    for (size_t k = begin; k < end; k += (size_t)n) {
        n = 1;
        while (n < SDF__CLUSTER_MAX && k + (size_t)n < end &&
               !(b->run_start && b->run_start[k + (size_t)n]))
            n++;
        for (int i = 0; i < n; i++)
            want[i] = !b->sign_hint || !b->sign_hint[k + (size_t)i] ? SDF__CLUSTER_EXACT
                      : distance_only                              ? SDF__CLUSTER_FLOAT
                                                                   : SDF__CLUSTER_FLOAT_POINT;
        int clustered = cluster && sdf__cluster_closest(cluster, &m->tree, m->positions,
                                                        m->triangles, (float)m->report.diagonal,
                                                        b->points + k * b->stride, b->stride,
                                                        b->bound + k, want, n, hits) == 0;
        for (int s = 0; s < n; s += SDF__PACKET) {
            fill_packet(b, k + (size_t)s, n - s < SDF__PACKET ? n - s : SDF__PACKET, !clustered,
                        &pk);
            if (clustered)
                finish_packet(b, &pk, NULL, k + (size_t)s, hits + s);
            else
                answer_packet(b, &pk, NULL, k + (size_t)s, hits);
        }
    }
}

size_t sdf__query_scratch_bound(size_t count, int threads)
{
    /* The Morton order (4 bytes a point) and its radix sort's scratch, the lattice check's
     * axes (at most 12 a point), the points and answers in visit order (12, and at most 44:
     * every output), and every worker's cluster scratch (seeded queries). */
    size_t workers = (size_t)sdf__effective_threads(threads, SIZE_MAX, 1);
    return sdf__big_size(4 * count) + 12 * (count + 1) + sdf__big_size(12 * count) +
           sdf__big_size(44 * count + 4) + sdf__morton_scratch_bound(count, threads) +
           workers * sdf__cluster_bytes(CLUSTER_CANDIDATES);
}

int sdf__query_seeded(const sdf_mesh *mesh, const float *points, const double *bound,
                      const int8_t *sign_hint, const uint8_t *run_start, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out)
{
    batch b;
    int rc = check_batch(mesh, points, count, opts, &b, &out->bad_index);
    if (rc)
        return rc;
    b.out = out;
    b.bound = bound;
    b.sign_hint = sign_hint;
    b.run_start = run_start;
    /* One cluster scratch per worker (~190 KB each), made once for the call. */
    int threads = opts ? opts->threads : 0;
    int workers = sdf__effective_threads(threads, count, SEEDED_CHUNK);
    sdf__cluster *clusters[SDF__MAX_THREADS];
    for (int w = 0; w < workers; w++)
        clusters[w] = sdf__cluster_create(CLUSTER_CANDIDATES);
    b.clusters = clusters;
    sdf__parallel_for(count, SEEDED_CHUNK, threads, seeded_range, &b);
    for (int w = 0; w < workers; w++)
        sdf__cluster_destroy(clusters[w]);
    return 0;
}

int sdf__query_finish(const sdf_mesh *mesh, const float *points, const sdf__hit *hits,
                      size_t count, const sdf_query_options *opts, sdf_query_result *out)
{
    batch b;
    int rc = check_batch(mesh, points, count, opts, &b, &out->bad_index);
    if (rc)
        return rc;
    b.out = out;
    sdf__packet pk; /* only its coordinates: a packet's winding numbers come in one traversal */
    for (size_t first = 0; first < count; first += SDF__PACKET) {
        fill_packet(&b, first, count - first < SDF__PACKET ? (int)(count - first) : SDF__PACKET, 0,
                    &pk);
        sdf__hit part[SDF__PACKET];
        memcpy(part, hits + first, (size_t)pk.n * sizeof *part);
        finish_packet(&b, &pk, NULL, first, part);
    }
    return 0;
}

static int query_points(const batch *b, size_t count, const sdf_query_options *opts);

/* A checked batch writing to `out`. */
static int begin_batch(const sdf_mesh *mesh, const float *points, size_t count,
                       const sdf_query_options *opts, sdf_query_result *out, batch *b)
{
    if (!out)
        return SDF_EINVAL;
    int rc = check_batch(mesh, points, count, opts, b, &out->bad_index);
    b->out = out;
    return rc;
}

int sdf__query_check(const sdf_mesh *mesh, const float *points, size_t count,
                     const sdf_query_options *opts, sdf_query_result *out)
{
    batch b;
    return begin_batch(mesh, points, count, opts, out, &b);
}

int sdf__query_checked_points(const sdf_mesh *mesh, const float *points, size_t count,
                              const sdf_query_options *opts, sdf_query_result *out)
{
    batch b;
    int rc = batch_args(mesh, points, count, opts, &b);
    assert(rc == 0); /* sdf__query_check passed these arguments */
    b.out = out;
    return rc ? rc : query_points(&b, count, opts);
}

int sdf__query_points(const sdf_mesh *mesh, const float *points, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out)
{
    batch b;
    int rc = begin_batch(mesh, points, count, opts, out, &b);
    return rc ? rc : query_points(&b, count, opts);
}

/* The points copied in visit order (batch.visit_xyz), so that packets read them in turn. In
 * the batch's own order the Morton order scatters each packet's reads over the whole array,
 * and each missed the cache and the TLB while the packets waited. */
static void copy_in_visit_order(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    float *out = b->visit_xyz;
    for (size_t i = begin; i < end; i++) {
        if (i + COPY_AHEAD < end)
            __builtin_prefetch(point_at(b, b->order[i + COPY_AHEAD]));
        const float *p = point_at(b, b->order[i]);
        out[3 * i] = p[0], out[3 * i + 1] = p[1], out[3 * i + 2] = p[2];
    }
}

/* Outputs like `like`'s (the same arrays asked for) for `count` points, in one block (the
 * caller hands it back with sdf__ws_free; NULL without memory). */
static void *alloc_like(sdf_workspace *ws, const sdf_query_result *like, size_t count,
                        sdf_query_result *out)
{
    size_t words = (like->distance ? 1 : 0) + (like->gradient ? 3 : 0) +
                   (like->closest ? 3 : 0) + (like->triangle ? 1 : 0) +
                   (like->barycentric ? 3 : 0);
    uint32_t *block = sdf__ws_alloc(ws, SDF__WS_VISIT_OUT, words * count * sizeof *block + 1);
    uint32_t *at = block;
    if (!block)
        return NULL;
    *out = (sdf_query_result){0};
    if (like->distance)
        out->distance = (float *)at, at += count;
    if (like->gradient)
        out->gradient = (float *)at, at += 3 * count;
    if (like->closest)
        out->closest = (float *)at, at += 3 * count;
    if (like->triangle)
        out->triangle = at, at += count;
    if (like->barycentric)
        out->barycentric = (float *)at;
    return block;
}

/* Answers written in visit order (batch.final set) into the caller's arrays, in the batch's
 * order. */
static void scatter_answers(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    const sdf_query_result *from = b->out, *to = b->final;
    const uint32_t *order = b->order;
    if (to->distance)
        for (size_t i = begin; i < end; i++) {
            if (i + COPY_AHEAD < end)
                __builtin_prefetch(to->distance + order[i + COPY_AHEAD], 1);
            to->distance[order[i]] = from->distance[i];
        }
    if (to->triangle)
        for (size_t i = begin; i < end; i++)
            to->triangle[order[i]] = from->triangle[i];
    float *const dst3[3] = {to->gradient, to->closest, to->barycentric};
    const float *const src3[3] = {from->gradient, from->closest, from->barycentric};
    for (int a = 0; a < 3; a++)
        for (size_t i = begin; dst3[a] && i < end; i++)
            memcpy(dst3[a] + 3 * (size_t)order[i], src3[a] + 3 * i, 3 * sizeof(float));
}

/* Packets (or single queries) over a checked batch. */
static int query_points(const batch *b0, size_t count, const sdf_query_options *opts)
{
    batch b = *b0;
    int threads = opts ? opts->threads : 0;
    uint32_t *order = packet_order(&b, count, opts);
    if (order) {
        /* Small batches still need a few work items per thread to keep every core busy. */
        int workers = sdf__effective_threads(threads, count, CHUNK);
        size_t chunk = count / (4 * (size_t)workers);
        chunk = chunk < CHUNK ? CHUNK : chunk > PACKET_CHUNK ? PACKET_CHUNK : chunk;
        b.order = order;
        /* Without these copies the points are read, and the answers written, through the
         * order: the same answers. */
        float *visit_xyz = sdf__ws_alloc(b.ws, SDF__WS_VISIT_XYZ, count * 3 * sizeof *visit_xyz);
        if (visit_xyz) {
            b.visit_xyz = visit_xyz;
            sdf__parallel_for(count, VISIT_COPY_CHUNK, threads, copy_in_visit_order, &b);
        }
        sdf_query_result visit_out;
        void *visit_block = alloc_like(b.ws, b.out, count, &visit_out);
        if (visit_block) {
            b.final = b.out;
            b.out = &visit_out;
        }
        sdf__parallel_for(count, chunk, threads, packet_range, &b);
        if (visit_block)
            sdf__parallel_for(count, VISIT_COPY_CHUNK, threads, scatter_answers, &b);
        sdf__ws_free(b.ws, visit_block);
        sdf__ws_free(b.ws, visit_xyz);
        sdf__ws_free(b.ws, order);
    } else { /* single traversal, or no memory for the order: same answers */
        if (opts && opts->traversal == SDF_TRAVERSAL_SINGLE) {
            int rc = sdf__bvh_ready(b.mesh->bvh); /* Embree's scene, built on first use */
            if (rc)
                return rc;
            b.by_embree = 1;
        }
        sdf__parallel_for(count, CHUNK, threads, answer_range, &b);
    }
    return 0;
}

static void winding_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    for (size_t i = begin; i < end; i++) {
        const float *p = point_at(b, i);
        double q[3] = {p[0], p[1], p[2]};
        b->winding[i] = (float)sdf__winding_number(sdf__mesh_winding(b->mesh), q);
    }
}

/* Positions [begin, end) of the Morton order, SDF__WINDING_LANES points per traversal. */
static void winding_packet_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    for (size_t k = begin; k < end; k += SDF__WINDING_LANES) {
        int n = (int)(end - k < SDF__WINDING_LANES ? end - k : SDF__WINDING_LANES);
        double qx[SDF__WINDING_LANES], qy[SDF__WINDING_LANES], qz[SDF__WINDING_LANES];
        double w[SDF__WINDING_LANES];
        for (int i = 0; i < SDF__WINDING_LANES; i++) { /* padded lanes repeat the last point */
            const float *p = point_at(b, b->order[k + (size_t)(i < n ? i : n - 1)]);
            qx[i] = p[0], qy[i] = p[1], qz[i] = p[2];
        }
        sdf__winding_packet(sdf__mesh_winding(b->mesh), qx, qy, qz, n, w);
        for (int i = 0; i < n; i++)
            b->winding[b->order[k + (size_t)i]] = (float)w[i];
    }
}

static int winding_numbers(const sdf_mesh *mesh, const float *points, size_t count,
                           const sdf_query_options *opts, float *winding, size_t *bad_index)
{
    if (!winding && count)
        return SDF_EINVAL;
    batch b;
    int rc = check_batch(mesh, points, count, opts, &b, bad_index);
    if (!rc)
        rc = sdf__mesh_need_winding(mesh);
    if (rc)
        return rc;
    b.winding = winding;
    int threads = opts ? opts->threads : 0;
    uint32_t *order = packet_order(&b, count, opts);
    if (order) { /* packets of nearby points share the tree's upper levels */
        b.order = order;
        sdf__parallel_for(count, 1024, threads, winding_packet_range, &b);
        sdf__ws_free(b.ws, order);
    } else {
        sdf__parallel_for(count, CHUNK, threads, winding_range, &b);
    }
    return 0;
}

int sdf_winding_numbers(const sdf_mesh *mesh, const float *points, size_t count,
                        const sdf_query_options *opts, float *winding, size_t *bad_index)
{
    sdf__ws_call call;
    int rc = winding_numbers(mesh, points, count, sdf__ws_enter(opts, &call), winding, bad_index);
    sdf__ws_leave(&call);
    return rc;
}
