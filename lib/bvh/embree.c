/* embree.c - Embree device, scene, point and ray queries (see embree.h). */
#include "bvh/embree.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/types.h>

#include <embree3/rtcore.h>

#include "core/diag.h"
#include "geom/triangle.h"

struct sdf__bvh {
    RTCDevice device;
    _Atomic(RTCScene) scene; /* committed on first use (sdf__bvh_ready), then never changed */
    pthread_mutex_t commit;   /* held while the scene is built */
    int commit_rc;            /* the first build's result, kept: a failed build is not retried */
    const float *positions;
    const uint32_t *triangles;
    size_t vertex_count, triangle_count;
    atomic_llong memory;
    atomic_int failed;
    char error[160];
};

static void on_error(void *user, enum RTCError code, const char *str)
{
    sdf__bvh *bvh = user;
    if (atomic_exchange(&bvh->failed, 1) == 0)
        snprintf(bvh->error, sizeof bvh->error, "Embree error %d: %s", (int)code,
                 str ? str : "(no message)");
}

static bool on_memory(void *user, ssize_t bytes, bool post)
{
    (void)post;
    sdf__bvh *bvh = user;
    atomic_fetch_add(&bvh->memory, (long long)bytes);
    return true;
}

int sdf__bvh_check(const sdf__bvh *bvh, sdf_diag *diag)
{
    if (!atomic_load(&((sdf__bvh *)bvh)->failed))
        return 0;
    return sdf__diag_set(diag, SDF_EBVH, 0, -1, "%s", bvh->error);
}

int sdf__bvh_create(const float *positions, size_t vertex_count, const uint32_t *triangles,
                    size_t triangle_count, sdf__bvh **out, sdf_diag *diag)
{
    *out = NULL;
    sdf__bvh *bvh = calloc(1, sizeof *bvh);
    if (!bvh)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory");
    if (pthread_mutex_init(&bvh->commit, NULL)) {
        free(bvh);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of resources for a mutex");
    }
    bvh->positions = positions;
    bvh->triangles = triangles;
    bvh->vertex_count = vertex_count;
    bvh->triangle_count = triangle_count;
    bvh->device = rtcNewDevice(NULL);
    if (!bvh->device) {
        pthread_mutex_destroy(&bvh->commit);
        free(bvh);
        return sdf__diag_set(diag, SDF_EBVH, 0, -1, "Embree device creation failed (error %d)",
                             (int)rtcGetDeviceError(NULL));
    }
    rtcSetDeviceErrorFunction(bvh->device, on_error, bvh);
    rtcSetDeviceMemoryMonitorFunction(bvh->device, on_memory, bvh);
    *out = bvh;
    return 0;
}

/* The scene over the mesh's triangles, committed; NULL after an Embree error. */
static RTCScene commit_scene(sdf__bvh *bvh)
{
    RTCScene scene = rtcNewScene(bvh->device);
    if (!scene)
        return NULL;
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry geom = rtcNewGeometry(bvh->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (geom) {
        rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                   bvh->positions, 0, 3 * sizeof(float), bvh->vertex_count);
        rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                   bvh->triangles, 0, 3 * sizeof(uint32_t), bvh->triangle_count);
        rtcCommitGeometry(geom);
        rtcAttachGeometry(scene, geom);
        rtcReleaseGeometry(geom);
    }
    rtcCommitScene(scene);
    if (!geom || atomic_load(&bvh->failed)) {
        rtcReleaseScene(scene);
        return NULL;
    }
    return scene;
}

int sdf__bvh_ready(const sdf__bvh *cbvh)
{
    sdf__bvh *bvh = (sdf__bvh *)cbvh; /* the scene is a cache: building it is not a change */
    if (atomic_load_explicit(&bvh->scene, memory_order_acquire))
        return 0;
    pthread_mutex_lock(&bvh->commit);
    if (!atomic_load_explicit(&bvh->scene, memory_order_relaxed) && !bvh->commit_rc) {
        RTCScene scene = commit_scene(bvh);
        if (scene)
            atomic_store_explicit(&bvh->scene, scene, memory_order_release);
        else
            bvh->commit_rc = SDF_EBVH;
    }
    int rc = bvh->commit_rc;
    pthread_mutex_unlock(&bvh->commit);
    return rc;
}

int sdf__bvh_is_ready(const sdf__bvh *bvh)
{
    return atomic_load_explicit(&((sdf__bvh *)bvh)->scene, memory_order_acquire) != NULL;
}

void sdf__bvh_destroy(sdf__bvh *bvh)
{
    if (!bvh)
        return;
    RTCScene scene = atomic_load(&bvh->scene);
    if (scene)
        rtcReleaseScene(scene);
    if (bvh->device)
        rtcReleaseDevice(bvh->device);
    pthread_mutex_destroy(&bvh->commit);
    free(bvh);
}

RTCDevice sdf__bvh_device(const sdf__bvh *bvh) { return bvh->device; }

size_t sdf__bvh_memory(const sdf__bvh *bvh)
{
    long long m = atomic_load(&((sdf__bvh *)bvh)->memory);
    return m > 0 ? (size_t)m : 0;
}

/* ---- closest point ------------------------------------------------------------------- */

typedef struct closest_query {
    const sdf__bvh *bvh;
    double p[3];
    sdf__hit *hit;
} closest_query;

static void corner(const sdf__bvh *bvh, uint32_t v, double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = bvh->positions[3 * v + i];
}

static bool visit_triangle(struct RTCPointQueryFunctionArguments *args)
{
    closest_query *q = args->userPtr;
    const uint32_t *t = q->bvh->triangles + 3 * (size_t)args->primID;
    double a[3], b[3], c[3], point[3], bary[3];
    corner(q->bvh, t[0], a);
    corner(q->bvh, t[1], b);
    corner(q->bvh, t[2], c);
    int feature;
    double d2 = sdf__closest_on_triangle(q->p, a, b, c, point, bary, &feature);
    if (d2 >= q->hit->dist2)
        return false;
    sdf__hit *h = q->hit;
    h->dist2 = d2;
    sdf__triangle_normal(a, b, c, h->face_normal);
    h->triangle = args->primID;
    h->feature = feature;
    for (int i = 0; i < 3; i++) {
        h->point[i] = point[i];
        h->bary[i] = bary[i];
    }
    /* Shrink the search; round up so float rounding never culls an equally close node. */
    args->query->radius = nextafterf((float)sqrt(d2), INFINITY);
    return true;
}

void sdf__bvh_closest(const sdf__bvh *bvh, const float p[3], sdf__hit *hit)
{
    hit->dist2 = INFINITY;
    hit->triangle = 0;
    closest_query q = {bvh, {p[0], p[1], p[2]}, hit};
    struct RTCPointQuery query = {.x = p[0], .y = p[1], .z = p[2], .time = 0,
                                  .radius = INFINITY};
    struct RTCPointQueryContext context;
    rtcInitPointQueryContext(&context);
    RTCScene scene = atomic_load_explicit(&((sdf__bvh *)bvh)->scene, memory_order_acquire);
    rtcPointQuery(scene, &query, &context, visit_triangle, &q);
}

/* ---- ray crossings -------------------------------------------------------------------- */

#define SEEN_MAX 64

/* RTCIntersectContext must come first: Embree hands the filter a pointer to it. */
typedef struct crossing_context {
    struct RTCIntersectContext base;
    unsigned crossings;
    unsigned seen_count;
    unsigned seen[SEEN_MAX];
} crossing_context;

/* Count every hit and reject it, so traversal goes on to the next one. A triangle can be
 * reported more than once; count it once. */
static void count_crossing(const struct RTCFilterFunctionNArguments *args)
{
    crossing_context *ctx = (crossing_context *)args->context;
    for (unsigned i = 0; i < args->N; i++) {
        if (args->valid[i] == 0)
            continue;
        args->valid[i] = 0;
        /* RTCHitN is SoA: Ng_x, Ng_y, Ng_z, u, v, primID, ... each N wide (rtcore_ray.h);
         * the accessor RTCHitN_primID exists only for C++. */
        unsigned prim = ((const unsigned *)args->hit)[5 * args->N + i];
        unsigned k = 0;
        while (k < ctx->seen_count && ctx->seen[k] != prim)
            k++;
        if (k < ctx->seen_count)
            continue;
        if (ctx->seen_count < SEEN_MAX)
            ctx->seen[ctx->seen_count++] = prim;
        ctx->crossings++;
    }
}

unsigned sdf__bvh_crossings(const sdf__bvh *bvh, const float origin[3], const float dir[3])
{
    crossing_context ctx;
    rtcInitIntersectContext(&ctx.base);
    ctx.base.filter = count_crossing;
    ctx.crossings = 0;
    ctx.seen_count = 0;
    struct RTCRayHit rh = {0};
    rh.ray.org_x = origin[0];
    rh.ray.org_y = origin[1];
    rh.ray.org_z = origin[2];
    rh.ray.dir_x = dir[0];
    rh.ray.dir_y = dir[1];
    rh.ray.dir_z = dir[2];
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = UINT32_MAX;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(atomic_load_explicit(&((sdf__bvh *)bvh)->scene, memory_order_acquire),
                  &ctx.base, &rh);
    return ctx.crossings;
}
