/* query.c - sdf_query and sdf_winding_numbers: the batch entry points.
 *
 * A batch is checked whole first (finite coordinates, valid arguments) so that a bad point
 * fails the call before any output is written, then cut into chunks that worker threads
 * take in turn. Each point is answered independently, so results do not depend on the
 * thread count. Per point: the exact closest point (Embree BVH + double-precision triangle
 * test), then the sign by the requested method, then the outputs asked for. */
#include <math.h>
#include <string.h>

#include "bvh/embree.h"
#include "core/parallel.h"
#include "mesh/mesh.h"
#include "sign/pseudonormal.h"
#include "sign/raycast.h"
#include "sign/winding.h"

#define CHUNK 256

static const char *const sign_names[] = {"auto", "pseudonormal", "winding", "raycast", "none"};

int sdf_sign_from_name(const char *name, sdf_sign_method *out)
{
    for (int s = SDF_SIGN_AUTO; s <= SDF_SIGN_NONE && name; s++) {
        if (!strcmp(name, sign_names[s])) {
            *out = (sdf_sign_method)s;
            return 0;
        }
    }
    return SDF_EINVAL;
}

const char *sdf_sign_name(sdf_sign_method method)
{
    return method >= SDF_SIGN_AUTO && method <= SDF_SIGN_NONE ? sign_names[method] : "?";
}

typedef struct batch {
    const sdf_mesh *mesh;
    const char *points;
    size_t stride;
    sdf_sign_method sign;
    sdf_query_result *out;
    float *winding;
} batch;

static const float *point_at(const batch *b, size_t i)
{
    return (const float *)(b->points + i * b->stride);
}

/* Validate the common arguments; find the first non-finite point. */
static int check_batch(const sdf_mesh *mesh, const float *points, size_t count,
                       const sdf_query_options *opts, batch *b, size_t *bad_index)
{
    if (!mesh || (!points && count))
        return SDF_EINVAL;
    size_t stride = opts && opts->point_stride ? opts->point_stride : 3 * sizeof(float);
    if (stride < 3 * sizeof(float) || stride % sizeof(float))
        return SDF_EINVAL;
    sdf_sign_method sign = opts ? opts->sign : SDF_SIGN_AUTO;
    if (sign < SDF_SIGN_AUTO || sign > SDF_SIGN_NONE)
        return SDF_EINVAL;
    if (sign == SDF_SIGN_AUTO)
        sign = mesh->report.auto_sign;
    *b = (batch){mesh, (const char *)points, stride, sign, NULL, NULL};
    for (size_t i = 0; i < count; i++) {
        const float *p = point_at(b, i);
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
            if (bad_index)
                *bad_index = i;
            return SDF_ENONFINITE;
        }
    }
    return 0;
}

/* -1 inside, +1 outside (or unsigned). */
static float sign_of(const batch *b, const float p[3], const sdf__hit *hit, const float normal[3])
{
    const sdf_mesh *m = b->mesh;
    switch (b->sign) {
    case SDF_SIGN_PSEUDONORMAL: {
        double s = 0;
        for (int i = 0; i < 3; i++)
            s += (p[i] - hit->point[i]) * normal[i];
        return s < 0 ? -1.0f : 1.0f;
    }
    case SDF_SIGN_WINDING: {
        double q[3] = {p[0], p[1], p[2]};
        return sdf__winding_number(m->winding, q) > 0.5 ? -1.0f : 1.0f;
    }
    case SDF_SIGN_RAYCAST:
        return sdf__raycast_inside(m->bvh, p) ? -1.0f : 1.0f;
    default:
        return 1.0f;
    }
}

static void answer(const batch *b, size_t i)
{
    const sdf_mesh *m = b->mesh;
    const float *p = point_at(b, i);
    sdf__hit hit;
    sdf__bvh_closest(m->bvh, p, &hit);
    double d = sqrt(hit.dist2);
    int on_surface = d <= m->surface_epsilon;
    float normal[3] = {0, 0, 0};
    if (b->sign == SDF_SIGN_PSEUDONORMAL || (on_surface && b->out->gradient))
        sdf__pseudonormal(m->normals, m->triangles, m->edge_of, hit.triangle, hit.feature, normal);
    float s = d > 0 ? sign_of(b, p, &hit, normal) : 1.0f;
    sdf_query_result *o = b->out;
    if (o->distance)
        o->distance[i] = s * (float)d;
    if (o->gradient) {
        for (int k = 0; k < 3; k++)
            o->gradient[3 * i + k] = on_surface ? normal[k] : (float)(s * (p[k] - hit.point[k]) / d);
    }
    if (o->closest)
        for (int k = 0; k < 3; k++)
            o->closest[3 * i + k] = (float)hit.point[k];
    if (o->triangle)
        o->triangle[i] = hit.triangle;
    if (o->barycentric)
        for (int k = 0; k < 3; k++)
            o->barycentric[3 * i + k] = (float)hit.bary[k];
}

static void answer_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    for (size_t i = begin; i < end; i++)
        answer(ctx, i);
}

int sdf_query(const sdf_mesh *mesh, const float *points, size_t count,
              const sdf_query_options *opts, sdf_query_result *out)
{
    if (!out)
        return SDF_EINVAL;
    batch b;
    int rc = check_batch(mesh, points, count, opts, &b, &out->bad_index);
    if (rc)
        return rc;
    b.out = out;
    sdf__parallel_for(count, CHUNK, opts ? opts->threads : 0, answer_range, &b);
    return 0;
}

static void winding_range(void *ctx, size_t begin, size_t end, int worker)
{
    (void)worker;
    const batch *b = ctx;
    for (size_t i = begin; i < end; i++) {
        const float *p = point_at(b, i);
        double q[3] = {p[0], p[1], p[2]};
        b->winding[i] = (float)sdf__winding_number(b->mesh->winding, q);
    }
}

int sdf_winding_numbers(const sdf_mesh *mesh, const float *points, size_t count,
                        const sdf_query_options *opts, float *winding, size_t *bad_index)
{
    if (!winding && count)
        return SDF_EINVAL;
    batch b;
    int rc = check_batch(mesh, points, count, opts, &b, bad_index);
    if (rc)
        return rc;
    b.winding = winding;
    sdf__parallel_for(count, CHUNK, opts ? opts->threads : 0, winding_range, &b);
    return 0;
}
