/* accuracy.c - see accuracy.h. */
#include "accuracy.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

sdf_mesh *scaled_mesh(const sdf_mesh *mesh, double half)
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
        v[i] = (float)(((double)src[i] - centre[i % 3]) * 2 * half / side);
    sdf_mesh *out = NULL;
    sdf_mesh_create(v, r.vertices, sdf_mesh_triangles(mesh), r.triangles, NULL, &out, NULL);
    free(v);
    return out;
}

sdf_mesh *normalized_mesh(const sdf_mesh *mesh) { return scaled_mesh(mesh, 1); }

int accuracy_grid_make(const sdf_mesh *scaled, size_t reference, double half, int threads,
                       int with_gradient, accuracy_grid *out)
{
    size_t n = reference * reference * reference;
    *out = (accuracy_grid){.count = n, .half = half};
    out->points = malloc(n * 3 * sizeof *out->points);
    out->distance = malloc(n * sizeof *out->distance);
    out->gradient = with_gradient ? malloc(n * 3 * sizeof *out->gradient) : NULL;
    if (!out->points || !out->distance || (with_gradient && !out->gradient)) {
        accuracy_grid_free(out);
        return SDF_ENOMEM;
    }
    for (size_t q = 0; q < n; q++) {
        size_t ijk[3] = {q % reference, q / reference % reference, q / reference / reference};
        for (int a = 0; a < 3; a++)
            out->points[3 * q + a] =
                (float)(half * (-1 + 2 * (double)ijk[a] / (double)(reference - 1)));
    }
    sdf_query_options qo = {.threads = threads};
    sdf_query_result qr = {.distance = out->distance, .gradient = out->gradient};
    int rc = sdf_query(scaled, out->points, n, &qo, &qr);
    if (rc)
        accuracy_grid_free(out);
    return rc;
}

void accuracy_grid_free(accuracy_grid *grid)
{
    free(grid->points), free(grid->distance), free(grid->gradient);
    grid->points = grid->distance = grid->gradient = NULL;
}

static double angle_degrees(const float *a, const float *b)
{
    double dot = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    double cx = (double)a[1] * b[2] - (double)a[2] * b[1],
           cy = (double)a[2] * b[0] - (double)a[0] * b[2],
           cz = (double)a[0] * b[1] - (double)a[1] * b[0];
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), dot) * (180 / M_PI);
}

int accuracy_measure(const sdf_volume *volume, sdf_volume_filter filter,
                     const accuracy_grid *grid, accuracy_error *out)
{
    size_t n = grid->count;
    float *value = malloc(n * sizeof *value);
    float *grad = grid->gradient ? malloc(n * 3 * sizeof *grad) : NULL;
    int rc = !value || (grid->gradient && !grad) ? SDF_ENOMEM : 0;
    if (!rc)
        rc = sdf_volume_eval(volume, grid->points, n, filter, value, grad, NULL);
    double sum = 0, max = 0, angle = 0;
    for (size_t i = 0; !rc && i < n; i++) {
        double e = fabs((double)value[i] - (double)grid->distance[i]);
        sum += e;
        max = fmax(max, e);
        if (grad)
            angle += angle_degrees(grad + 3 * i, grid->gradient + 3 * i);
    }
    *out = (accuracy_error){sum / (double)n, max, grad ? angle / (double)n : NAN};
    free(value), free(grad);
    return rc;
}

int accuracy_bake(const sdf_mesh *scaled, const accuracy_grid *grid, size_t dims,
                  sdf_bake_options opts, sdf_volume **out)
{
    for (int a = 0; a < 3; a++)
        opts.lo[a] = -grid->half, opts.hi[a] = grid->half, opts.dims[a] = dims;
    return sdf_volume_bake(scaled, &opts, out, NULL);
}

static double mean_error(const sdf_volume *v, const accuracy_grid *grid, int *rc)
{
    accuracy_grid values = *grid;
    values.gradient = NULL;
    accuracy_error e = {NAN, NAN, NAN};
    if (v && !*rc)
        *rc = accuracy_measure(v, SDF_VOLUME_NEAREST, &values, &e);
    return e.mean;
}

int accuracy_table(const sdf_mesh *scaled, const accuracy_grid *grid, const size_t *dims,
                   int count, int threads, int with_gradient, accuracy_row *rows)
{
    int rc = 0;
    for (int r = 0; !rc && r < count; r++) {
        sdf_bake_options o = {.query = {.threads = threads}};
        sdf_volume *zero = NULL, *first = NULL, *packed = NULL, *gradient = NULL;
        double t0 = now();
        rc = accuracy_bake(scaled, grid, dims[r], o, &zero);
        double t1 = now();
        o.order = 1;
        if (!rc)
            rc = accuracy_bake(scaled, grid, dims[r], o, &first);
        double t2 = now();
        o.encoding = SDF_ENCODING_PACKED32;
        if (!rc)
            rc = accuracy_bake(scaled, grid, dims[r], o, &packed);
        o.encoding = SDF_ENCODING_FLOAT32;
        o.normalize = SDF_NORMALIZE_GRADIENT;
        if (!rc && with_gradient)
            rc = accuracy_bake(scaled, grid, dims[r], o, &gradient);
        rows[r] = (accuracy_row){.dim = dims[r], .zero_seconds = t1 - t0,
                                 .first_seconds = t2 - t1};
        rows[r].zero = mean_error(zero, grid, &rc);
        rows[r].first = mean_error(first, grid, &rc);
        rows[r].packed = mean_error(packed, grid, &rc);
        rows[r].first_gradient = gradient ? mean_error(gradient, grid, &rc) : NAN;
        sdf_volume_destroy(zero), sdf_volume_destroy(first), sdf_volume_destroy(packed);
        sdf_volume_destroy(gradient);
    }
    return rc;
}

int filter_table(const sdf_mesh *scaled, const accuracy_grid *grid, const size_t *dims,
                 int count, int threads, filter_row *rows)
{
    static const sdf_volume_filter filters[FILTER_COLUMNS] = {
        SDF_VOLUME_NEAREST, SDF_VOLUME_TRILINEAR, SDF_VOLUME_NEAREST, SDF_VOLUME_TRILINEAR,
        SDF_VOLUME_HERMITE, SDF_VOLUME_HERMITE};
    static const int volume_of[FILTER_COLUMNS] = {0, 0, 1, 1, 1, 2};
    int rc = 0;
    for (int r = 0; !rc && r < count; r++) {
        sdf_bake_options o = {.query = {.threads = threads}};
        sdf_volume *v[3] = {NULL, NULL, NULL};
        rc = accuracy_bake(scaled, grid, dims[r], o, &v[0]);
        o.order = 1;
        if (!rc)
            rc = accuracy_bake(scaled, grid, dims[r], o, &v[1]);
        o.encoding = SDF_ENCODING_PACKED32;
        if (!rc)
            rc = accuracy_bake(scaled, grid, dims[r], o, &v[2]);
        rows[r].dim = dims[r];
        for (int c = 0; !rc && c < FILTER_COLUMNS; c++)
            rc = accuracy_measure(v[volume_of[c]], filters[c], grid, &rows[r].e[c]);
        for (int i = 0; i < 3; i++)
            sdf_volume_destroy(v[i]);
    }
    return rc;
}
