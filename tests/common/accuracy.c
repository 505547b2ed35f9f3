/* accuracy.c - see accuracy.h. */
#include "accuracy.h"

#include <math.h>
#include <stdlib.h>
#include <time.h>

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

sdf_mesh *normalized_mesh(const sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    double centre[3], side = 0;
    for (int a = 0; a < 3; a++) {
        centre[a] = 0.5 * ((double)r.bbox_min[a] + (double)r.bbox_max[a]);
        side = fmax(side, (double)r.bbox_max[a] - (double)r.bbox_min[a]);
    }
    float *v = malloc(r.vertices * 3 * sizeof *v);
    if (!v)
        return NULL;
    const float *src = sdf_mesh_vertices(mesh);
    for (size_t i = 0; i < 3 * r.vertices; i++)
        v[i] = (float)(((double)src[i] - centre[i % 3]) * 2 / side);
    sdf_mesh *out = NULL;
    sdf_mesh_create(v, r.vertices, sdf_mesh_triangles(mesh), r.triangles, NULL, &out, NULL);
    free(v);
    return out;
}

static double mean_error(const sdf_volume *v, const float *points, const float *exact, size_t n,
                         float *scratch)
{
    if (sdf_volume_eval(v, points, n, SDF_VOLUME_NEAREST, scratch, NULL, NULL))
        return NAN;
    double sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += fabs((double)scratch[i] - (double)exact[i]);
    return sum / (double)n;
}

int accuracy_table(const sdf_mesh *mesh, const size_t *dims, int count, size_t reference,
                   int threads, int with_gradient, accuracy_row *rows)
{
    size_t n = reference * reference * reference;
    float *points = malloc(n * 3 * sizeof *points), *exact = malloc(n * sizeof *exact),
          *scratch = malloc(n * sizeof *scratch);
    int rc = points && exact && scratch ? 0 : SDF_ENOMEM;
    for (size_t q = 0; !rc && q < n; q++) {
        size_t ijk[3] = {q % reference, q / reference % reference, q / reference / reference};
        for (int a = 0; a < 3; a++)
            points[3 * q + a] = (float)(-1 + 2 * (double)ijk[a] / (double)(reference - 1));
    }
    sdf_query_options qo = {.threads = threads};
    sdf_query_result qr = {.distance = exact};
    if (!rc)
        rc = sdf_query(mesh, points, n, &qo, &qr);
    for (int r = 0; !rc && r < count; r++) {
        sdf_bake_options o = {.lo = {-1, -1, -1}, .hi = {1, 1, 1},
                              .dims = {dims[r], dims[r], dims[r]}, .query = {.threads = threads}};
        sdf_volume *zero = NULL, *first = NULL, *packed = NULL, *gradient = NULL;
        double t0 = now();
        rc = sdf_volume_bake(mesh, &o, &zero, NULL);
        double t1 = now();
        o.order = 1;
        if (!rc)
            rc = sdf_volume_bake(mesh, &o, &first, NULL);
        double t2 = now();
        o.encoding = SDF_ENCODING_PACKED32;
        if (!rc)
            rc = sdf_volume_bake(mesh, &o, &packed, NULL);
        o.encoding = SDF_ENCODING_FLOAT32;
        o.normalize = SDF_NORMALIZE_GRADIENT;
        if (!rc && with_gradient)
            rc = sdf_volume_bake(mesh, &o, &gradient, NULL);
        if (!rc) {
            rows[r].dim = dims[r];
            rows[r].zero = mean_error(zero, points, exact, n, scratch);
            rows[r].first = mean_error(first, points, exact, n, scratch);
            rows[r].packed = mean_error(packed, points, exact, n, scratch);
            rows[r].first_gradient =
                gradient ? mean_error(gradient, points, exact, n, scratch) : NAN;
            rows[r].zero_seconds = t1 - t0;
            rows[r].first_seconds = t2 - t1;
        }
        sdf_volume_destroy(zero), sdf_volume_destroy(first), sdf_volume_destroy(packed);
        sdf_volume_destroy(gradient);
    }
    free(points), free(exact), free(scratch);
    return rc;
}
