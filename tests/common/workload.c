/* workload.c - seeded query point sets (see workload.h). */
#include "workload.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

uint64_t sdf_rng_next(sdf_rng *r)
{
    uint64_t z = (r->state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

double sdf_rng_uniform(sdf_rng *r) { return (double)(sdf_rng_next(r) >> 11) * 0x1.0p-53; }

double sdf_rng_normal(sdf_rng *r)
{
    double u = sdf_rng_uniform(r), v = sdf_rng_uniform(r);
    return sqrt(-2 * log(u > 0 ? u : 1e-300)) * cos(2 * M_PI * v);
}

static void box_of(const sdf_mesh *mesh, double c[3], double e[3], double *diag)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    for (int i = 0; i < 3; i++) {
        c[i] = 0.5 * ((double)r.bbox_min[i] + r.bbox_max[i]);
        e[i] = 0.5 * ((double)r.bbox_max[i] - r.bbox_min[i]);
    }
    *diag = r.diagonal;
}

static int band(const sdf_mesh *mesh, size_t n, sdf_rng *rng, double diag, float *out)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const float *v = sdf_mesh_vertices(mesh);
    const uint32_t *t = sdf_mesh_triangles(mesh);
    double *cdf = malloc(r.triangles * sizeof *cdf);
    if (!cdf)
        return SDF_ENOMEM;
    double total = 0;
    for (size_t i = 0; i < r.triangles; i++) {
        const float *a = v + 3 * t[3 * i], *b = v + 3 * t[3 * i + 1], *c = v + 3 * t[3 * i + 2];
        double u[3], w[3];
        for (int k = 0; k < 3; k++) {
            u[k] = (double)b[k] - a[k];
            w[k] = (double)c[k] - a[k];
        }
        double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2],
               z = u[0] * w[1] - u[1] * w[0];
        total += sqrt(x * x + y * y + z * z);
        cdf[i] = total;
    }
    for (size_t i = 0; i < n; i++) {
        double target = sdf_rng_uniform(rng) * total;
        size_t lo = 0, hi = r.triangles - 1;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (cdf[mid] < target)
                lo = mid + 1;
            else
                hi = mid;
        }
        const float *a = v + 3 * t[3 * lo], *b = v + 3 * t[3 * lo + 1], *c = v + 3 * t[3 * lo + 2];
        double s = sqrt(sdf_rng_uniform(rng)), r2 = sdf_rng_uniform(rng);
        for (int k = 0; k < 3; k++)
            out[3 * i + k] = (float)((1 - s) * a[k] + s * (1 - r2) * b[k] + s * r2 * c[k] +
                                     sdf_rng_normal(rng) * 0.01 * diag);
    }
    free(cdf);
    return 0;
}

int sdf_workload(const sdf_mesh *mesh, const char *kind, size_t *n, uint64_t seed, float *points)
{
    sdf_rng rng = {seed};
    double c[3], e[3], diag;
    box_of(mesh, c, e, &diag);
    if (!strcmp(kind, "box")) {
        for (size_t i = 0; i < *n; i++)
            for (int k = 0; k < 3; k++)
                points[3 * i + k] = (float)(c[k] + (sdf_rng_uniform(&rng) * 2 - 1) * e[k] * 1.2);
        return 0;
    }
    if (!strcmp(kind, "far")) {
        for (size_t i = 0; i < *n; i++) {
            double p[3];
            int outside;
            do {
                outside = 0;
                for (int k = 0; k < 3; k++) {
                    p[k] = (sdf_rng_uniform(&rng) * 2 - 1) * 10 * (e[k] + 0.1 * diag);
                    outside |= fabs(p[k]) > 1.2 * e[k] + 0.05 * diag;
                }
            } while (!outside);
            for (int k = 0; k < 3; k++)
                points[3 * i + k] = (float)(c[k] + p[k]);
        }
        return 0;
    }
    if (!strcmp(kind, "band"))
        return band(mesh, *n, &rng, diag, points);
    if (!strcmp(kind, "grid")) {
        size_t k = (size_t)llround(cbrt((double)*n));
        while (k > 0 && k * k * k > *n) /* never more points than the caller has room for */
            k--;
        if (k < 2)
            return SDF_EINVAL;
        *n = k * k * k;
        for (size_t z = 0, i = 0; z < k; z++)
            for (size_t y = 0; y < k; y++)
                for (size_t x = 0; x < k; x++, i++) {
                    size_t idx[3] = {x, y, z};
                    for (int a = 0; a < 3; a++)
                        points[3 * i + a] =
                            (float)(c[a] - 1.2 * e[a] + 2.4 * e[a] * (double)idx[a] / (double)(k - 1));
                }
        return 0;
    }
    return SDF_EINVAL;
}
