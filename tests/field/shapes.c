/* shapes.c - the analytic cases of shapes.h. Each truth is exact:
 *  - sphere offset: | p | - (R + r);
 *  - box rounding: the opening of a box by a ball of radius r is the box shrunk by r then
 *    grown by r: the rounded box's exact distance;
 *  - L fillet: the closing of an L-shaped prism fills its concave edge with a quarter
 *    cylinder of radius r tangent to both walls; measured at |z| < Z - 2r - band, where the
 *    prism's end caps are out of the closing's reach (2r) and of the band, so the 2D
 *    distance to the filleted L (segments and the arc) is the answer;
 *  - ellipsoids (re-distancing): the distance to an ellipsoid by Eberly's root of
 *    sum (e_i p_i / (t + e_i^2))^2 = 1 (bisection), for the quadratic implicit and for a
 *    scaled, non-uniformly stretched sphere distance;
 *  - cube with a cylindrical hole, smoothed: it has no concave edge and its hole's radius is
 *    above r, so the closing leaves the opening as it is; the opening is E grown by r, E the
 *    eroded solid (cube shrunk by r, hole widened by r), whose distance outside E is
 *    dist(p, E) - r. Nodes inside E lie deeper than r, outside the measured band. */
#include "shapes.h"

#include <math.h>
#include <stdlib.h>

#include "../common/check.h"

static double len3(double x, double y, double z)
{
    return sqrt(x * x + y * y + z * z);
}

static double box_sdf(const double p[3], const double b[3])
{
    double q[3], out = 0, in = -INFINITY;
    for (int a = 0; a < 3; a++) {
        q[a] = fabs(p[a]) - b[a];
        out += q[a] > 0 ? q[a] * q[a] : 0;
        in = fmax(in, q[a]);
    }
    return sqrt(out) + fmin(in, 0);
}

/* --- sphere offset ------------------------------------------------------------------- */
#define SPHERE_R 0.45
#define SPHERE_OFFSET 0.2
static double sphere_in(const double p[3])
{
    return p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - SPHERE_R * SPHERE_R; /* not a distance */
}
static double sphere_out(const double p[3])
{
    return len3(p[0], p[1], p[2]) - (SPHERE_R + SPHERE_OFFSET);
}

/* --- box rounding -------------------------------------------------------------------- */
static const double box_b[3] = {0.65, 0.5, 0.4};
#define BOX_R 0.2
static double box_in(const double p[3])
{
    double m = -INFINITY; /* the max-norm box: a distance inside only */
    for (int a = 0; a < 3; a++)
        m = fmax(m, fabs(p[a]) - box_b[a]);
    return m;
}
static double box_out(const double p[3])
{
    double b[3] = {box_b[0] - BOX_R, box_b[1] - BOX_R, box_b[2] - BOX_R};
    return box_sdf(p, b) - BOX_R;
}

/* --- L fillet ------------------------------------------------------------------------ */
#define L_LO (-0.6)
#define L_HI 0.6
#define L_IN (-0.15) /* the concave corner at (L_IN, L_IN) */
#define L_Z 0.75
#define L_R 0.15
static double l_in(const double p[3])
{
    double a[3] = {p[0], p[1] - (L_LO + L_IN) / 2, p[2]};
    double ba[3] = {(L_HI - L_LO) / 2, (L_IN - L_LO) / 2, L_Z};
    double b[3] = {p[0] - (L_LO + L_IN) / 2, p[1], p[2]};
    double bb[3] = {(L_IN - L_LO) / 2, (L_HI - L_LO) / 2, L_Z};
    return fmin(box_sdf(a, ba), box_sdf(b, bb)); /* a union: not a distance inside */
}
static double seg_dist(double px, double py, double ax, double ay, double bx, double by)
{
    double dx = bx - ax, dy = by - ay;
    double t = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy);
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    return hypot(px - ax - t * dx, py - ay - t * dy);
}
static double l_out(const double p[3])
{
    double x = p[0], y = p[1], c = L_IN + L_R, band = 4 * 2.0 / 63;
    if (fabs(p[2]) > L_Z - 2 * L_R - band)
        return NAN;
    /* the filleted L's outline: five segments and the arc from (c, L_IN) to (L_IN, c) */
    double v[6][2] = {{L_LO, L_LO}, {L_HI, L_LO}, {L_HI, L_IN}, {c, L_IN}, {L_IN, c}, {L_IN, L_HI}};
    double d = seg_dist(x, y, v[5][0], v[5][1], L_LO, L_HI);
    d = fmin(d, seg_dist(x, y, L_LO, L_HI, v[0][0], v[0][1]));
    for (int i = 0; i < 5; i++)
        if (i != 3)
            d = fmin(d, seg_dist(x, y, v[i][0], v[i][1], v[i + 1][0], v[i + 1][1]));
    double ang = atan2(y - c, x - c); /* the arc spans angles [-pi, -pi/2] around (c, c) */
    if (ang <= -M_PI / 2)
        d = fmin(d, fabs(hypot(x - c, y - c) - L_R));
    else
        d = fmin(d, fmin(hypot(x - c, y - L_IN), hypot(x - L_IN, y - c)));
    int in_l = x >= L_LO && y >= L_LO && ((x <= L_HI && y <= L_IN) || (x <= L_IN && y <= L_HI));
    int in_fillet = x >= L_IN && y >= L_IN && x <= c && y <= c && hypot(x - c, y - c) > L_R;
    return in_l || in_fillet ? -d : d;
}

/* --- ellipsoids ---------------------------------------------------------------------- */
static double ellipsoid_distance(const double p[3], const double e[3])
{
    double emin = fmin(e[0], fmin(e[1], e[2])), emax = fmax(e[0], fmax(e[1], e[2]));
    double lo = -emin * emin, hi = emax * len3(p[0], p[1], p[2]) + emax * emax;
    for (int it = 0; it < 200; it++) {
        double t = (lo + hi) / 2, s = 0;
        for (int a = 0; a < 3; a++)
            s += pow(e[a] * p[a] / (t + e[a] * e[a]), 2);
        if (s > 1)
            lo = t;
        else
            hi = t;
    }
    double t = (lo + hi) / 2, q[3];
    for (int a = 0; a < 3; a++)
        q[a] = e[a] * e[a] * p[a] / (t + e[a] * e[a]);
    double d = len3(p[0] - q[0], p[1] - q[1], p[2] - q[2]);
    double inside = pow(p[0] / e[0], 2) + pow(p[1] / e[1], 2) + pow(p[2] / e[2], 2) < 1;
    return inside ? -d : d;
}
static const double ell_e[3] = {0.7, 0.5, 0.35};
static double ell_in(const double p[3])
{
    return pow(p[0] / ell_e[0], 2) + pow(p[1] / ell_e[1], 2) + pow(p[2] / ell_e[2], 2) - 1;
}
static double ell_out(const double p[3])
{
    return ellipsoid_distance(p, ell_e);
}
static const double str_e[3] = {0.6, 0.45, 0.3};
#define STR_Z 0.1
static double str_in(const double p[3])
{
    return 3 * (len3(p[0] / str_e[0], p[1] / str_e[1], (p[2] - STR_Z) / str_e[2]) - 1);
}
static double str_out(const double p[3])
{
    double q[3] = {p[0], p[1], p[2] - STR_Z};
    return ellipsoid_distance(q, str_e);
}

/* --- cube with a cylindrical hole, smoothed -------------------------------------------- */
#define CUBE_B 0.7
#define HOLE_R 0.25
#define SMOOTH_R 0.15
static double holed_in(const double p[3])
{
    double b[3] = {CUBE_B, CUBE_B, CUBE_B};
    return fmax(box_sdf(p, b), HOLE_R - hypot(p[0], p[1]));
}
static double holed_out(const double p[3])
{
    double b = CUBE_B - SMOOTH_R, hole = HOLE_R + SMOOTH_R, rho = hypot(p[0], p[1]);
    double dist;
    if (rho < hole) {
        double dz = fmax(fabs(p[2]) - b, 0);
        dist = hypot(hole - rho, dz);
    } else {
        double o = 0;
        for (int a = 0; a < 3; a++)
            o += pow(fmax(fabs(p[a]) - b, 0), 2);
        dist = sqrt(o);
    }
    return dist > 0 ? dist - SMOOTH_R : NAN; /* inside E: deeper than r, not measured */
}

#define BAND4 (4 * 2.0 / 63) /* the default band on a 64^3 grid over [-1, 1] */

const field_case field_cases[] = {
    {"sphere offset", sphere_in, sphere_out, {{SDF_FIELD_OFFSET, SPHERE_OFFSET}}, 1, BAND4},
    {"box round", box_in, box_out, {{SDF_FIELD_ROUND, BOX_R}}, 1, BAND4},
    {"L fillet", l_in, l_out, {{SDF_FIELD_FILLET, L_R}}, 1, BAND4},
    {"ellipsoid redistance", ell_in, ell_out, {{SDF_FIELD_REDISTANCE, 0.15f}}, 1, 0.15},
    {"stretched redistance", str_in, str_out, {{SDF_FIELD_REDISTANCE, 0.15f}}, 1, 0.15},
    {"holed cube smooth", holed_in, holed_out, {{SDF_FIELD_SMOOTH, SMOOTH_R}}, 1, BAND4},
};
const size_t field_case_count = sizeof field_cases / sizeof field_cases[0];

sdf_volume *shape_volume(shape_fn f, size_t n)
{
    float *data = malloc(n * n * n * sizeof *data);
    if (!data)
        return NULL;
    double h = 2.0 / (double)(n - 1);
    for (size_t k = 0, at = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++, at++) {
                double p[3] = {-1 + (double)i * h, -1 + (double)j * h, -1 + (double)k * h};
                data[at] = (float)f(p);
            }
    sdf_volume_info info = {.dims = {n, n, n}, .origin = {-1, -1, -1}, .spacing = {h, h, h}};
    sdf_volume *v = NULL;
    sdf_diag diag;
    int rc = sdf_volume_create(&info, data, &v, &diag);
    CHECK(rc == 0, "sdf_volume_create: %s", diag.message);
    free(data);
    return v;
}

size_t shape_error(const sdf_volume *v, const field_case *c, double *mean, double *max)
{
    sdf_volume_info info;
    sdf_volume_get_info(v, &info);
    const float *d = sdf_volume_data(v);
    size_t n = info.dims[0], count = 0;
    double h = info.spacing[0], sum = 0, worst = 0, scale = 2.0 / 63 / h;
    for (size_t k = 0, at = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++, at++) {
                double p[3] = {-1 + (double)i * h, -1 + (double)j * h, -1 + (double)k * h};
                double t = c->truth(p);
                /* the band in 64^3 cells scales with the grid: the same cells at any n */
                if (isnan(t) || fabs(t) > c->band / scale)
                    continue;
                double e = fabs(d[at] - t) / h;
                sum += e, worst = fmax(worst, e), count++;
            }
    *mean = count ? sum / (double)count : 0;
    *max = worst;
    return count;
}
