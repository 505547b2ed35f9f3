/* triangle.c - closest point on a triangle (see triangle.h). */
#include "geom/triangle.h"

#include <string.h>

static double dot(const double u[3], const double v[3])
{
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
}

static void sub(double out[3], const double u[3], const double v[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = u[i] - v[i];
}

static double finish(const double p[3], const double a[3], const double b[3], const double c[3],
                     double wa, double wb, double wc, double closest[3], double bary[3])
{
    double d2 = 0;
    for (int i = 0; i < 3; i++) {
        closest[i] = wa * a[i] + wb * b[i] + wc * c[i];
        double e = p[i] - closest[i];
        d2 += e * e;
    }
    bary[0] = wa;
    bary[1] = wb;
    bary[2] = wc;
    return d2;
}

/* Parameter in [0, 1] of the point of segment (u, v) closest to p. */
static double segment_param(const double p[3], const double u[3], const double v[3])
{
    double uv[3], up[3];
    sub(uv, v, u);
    sub(up, p, u);
    double len2 = dot(uv, uv);
    if (len2 <= 0)
        return 0;
    double t = dot(up, uv) / len2;
    return t < 0 ? 0 : (t > 1 ? 1 : t);
}

/* A zero-area triangle: the best of its three edges. */
static double closest_degenerate(const double p[3], const double *const v[3], double closest[3],
                                 double bary[3], int *feature)
{
    double best = -1;
    for (int k = 0; k < 3; k++) {
        int j = (k + 1) % 3;
        double t = segment_param(p, v[k], v[j]);
        double w[3] = {0, 0, 0}, c[3], b[3];
        w[k] = 1 - t;
        w[j] += t;
        double d2 = finish(p, v[0], v[1], v[2], w[0], w[1], w[2], c, b);
        if (best < 0 || d2 < best) {
            best = d2;
            for (int i = 0; i < 3; i++) {
                closest[i] = c[i];
                bary[i] = b[i];
            }
            *feature = t <= 0 ? SDF__VERT0 + k : t >= 1 ? SDF__VERT0 + j : SDF__EDGE0 + k;
        }
    }
    return best;
}

double sdf__closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                const double c[3], double closest[3], double bary[3],
                                int *feature)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    sub(ab, b, a);
    sub(ac, c, a);
    double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2],
                   ab[0] * ac[1] - ab[1] * ac[0]};
    if (dot(n, n) == 0) {
        const double *const v[3] = {a, b, c};
        return closest_degenerate(p, v, closest, bary, feature);
    }
    sub(ap, p, a);
    double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        *feature = SDF__VERT0;
        return finish(p, a, b, c, 1, 0, 0, closest, bary);
    }
    sub(bp, p, b);
    double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        *feature = SDF__VERT1;
        return finish(p, a, b, c, 0, 1, 0, closest, bary);
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        *feature = SDF__EDGE0;
        return finish(p, a, b, c, 1 - v, v, 0, closest, bary);
    }
    sub(cp, p, c);
    double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        *feature = SDF__VERT2;
        return finish(p, a, b, c, 0, 0, 1, closest, bary);
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        *feature = SDF__EDGE2;
        return finish(p, a, b, c, 1 - w, 0, w, closest, bary);
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        *feature = SDF__EDGE1;
        return finish(p, a, b, c, 0, 1 - w, w, closest, bary);
    }
    double denom = 1 / (va + vb + vc);
    double v = vb * denom, w = vc * denom;
    *feature = SDF__FACE;
    return finish(p, a, b, c, 1 - v - w, v, w, closest, bary);
}

void sdf__triangle_offer(const float *positions, const uint32_t *triangles, uint32_t tri,
                         const double p[3], sdf__hit *hit)
{
    const uint32_t *t = triangles + 3 * (size_t)tri;
    double v[3][3], closest[3], bary[3];
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++)
            v[k][a] = positions[3 * (size_t)t[k] + a];
    int feature;
    double d2 = sdf__closest_on_triangle(p, v[0], v[1], v[2], closest, bary, &feature);
    if (d2 < hit->dist2 || (d2 == hit->dist2 && tri < hit->triangle)) {
        hit->dist2 = d2;
        sdf__triangle_normal(v[0], v[1], v[2], hit->face_normal);
        hit->triangle = tri;
        hit->feature = feature;
        memcpy(hit->point, closest, sizeof closest);
        memcpy(hit->bary, bary, sizeof bary);
    }
}
