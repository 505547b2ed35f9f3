/* reference.c - brute-force references (see reference.h). */
#include "reference.h"

#include <math.h>

static double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

static double segment(const double p[3], const double a[3], const double b[3], double q[3])
{
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
    double l2 = dot(ab, ab), t = l2 > 0 ? dot(ap, ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d2 = 0;
    for (int i = 0; i < 3; i++) {
        q[i] = a[i] + t * ab[i];
        d2 += (p[i] - q[i]) * (p[i] - q[i]);
    }
    return sqrt(d2);
}

double ref_point_triangle(const double p[3], const double a[3], const double b[3],
                          const double c[3], double closest[3])
{
    double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3];
    cross(ab, ac, n);
    double n2 = dot(n, n);
    if (n2 > 0) {
        /* Project onto the plane and test the projection's barycentric coordinates. */
        double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
        double h = dot(ap, n) / n2;
        double q[3] = {p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]};
        double e[3][3] = {{b[0] - a[0], b[1] - a[1], b[2] - a[2]},
                          {c[0] - b[0], c[1] - b[1], c[2] - b[2]},
                          {a[0] - c[0], a[1] - c[1], a[2] - c[2]}};
        const double *v[3] = {a, b, c};
        int inside = 1;
        for (int k = 0; k < 3; k++) {
            double vq[3] = {q[0] - v[k][0], q[1] - v[k][1], q[2] - v[k][2]}, x[3];
            cross(e[k], vq, x);
            if (dot(x, n) < 0)
                inside = 0;
        }
        if (inside) {
            for (int i = 0; i < 3; i++)
                closest[i] = q[i];
            return fabs(h) * sqrt(n2);
        }
    }
    double best = INFINITY, q[3];
    const double *v[4] = {a, b, c, a};
    for (int k = 0; k < 3; k++) {
        double d = segment(p, v[k], v[k + 1], q);
        if (d < best) {
            best = d;
            for (int i = 0; i < 3; i++)
                closest[i] = q[i];
        }
    }
    return best;
}

static void corners(const sdf_mesh *mesh, size_t t, double v[3][3])
{
    const float *pos = sdf_mesh_vertices(mesh);
    const uint32_t *tri = sdf_mesh_triangles(mesh);
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            v[k][i] = pos[3 * tri[3 * t + k] + i];
}

void ref_closest(const sdf_mesh *mesh, const float pf[3], ref_hit *hit)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    double p[3] = {pf[0], pf[1], pf[2]};
    hit->dist = INFINITY;
    for (size_t t = 0; t < r.triangles; t++) {
        double v[3][3], q[3];
        corners(mesh, t, v);
        double d = ref_point_triangle(p, v[0], v[1], v[2], q);
        if (d < hit->dist) {
            hit->dist = d;
            hit->triangle = t;
            for (int i = 0; i < 3; i++)
                hit->point[i] = q[i];
        }
    }
}

double ref_winding(const sdf_mesh *mesh, const float pf[3])
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    double sum = 0;
    for (size_t t = 0; t < r.triangles; t++) {
        double v[3][3], x[3][3], len[3];
        corners(mesh, t, v);
        for (int k = 0; k < 3; k++) {
            for (int i = 0; i < 3; i++)
                x[k][i] = v[k][i] - pf[i];
            len[k] = sqrt(dot(x[k], x[k]));
        }
        double yz[3];
        cross(x[1], x[2], yz);
        double det = dot(x[0], yz);
        double den = len[0] * len[1] * len[2] + dot(x[0], x[1]) * len[2] +
                     dot(x[1], x[2]) * len[0] + dot(x[2], x[0]) * len[1];
        sum += 2 * atan2(det, den);
    }
    return sum / (4 * M_PI);
}
