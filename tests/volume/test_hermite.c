/* test_hermite.c - the tricubic Hermite reconstruction of first-order volumes
 * (SDF_VOLUME_HERMITE, lib/volume/hermite.h) and the default filter:
 *  - its gradient is the derivative of its value: central differences in double precision
 *    of sdf__hermite_eval on random planes, inside and outside the volume, with and without
 *    the node-value limit; and through sdf_volume_eval on a baked volume;
 *  - a plane field (one plane at every node, unit or not) is reproduced to float rounding,
 *    and a cubic's exact tangent planes reproduce it inside the volume;
 *  - C0 and C1 across cell faces: values and gradients one float step either side of a face
 *    agree, where the same probe finds trilinear first order's gradient jumping;
 *  - the limit lowers an inflated node value to its neighbour's foot and never raises one;
 *  - SDF_VOLUME_DEFAULT is trilinear for order 0 and hermite for order 1, bit for bit;
 *    hermite on a zero-order volume is refused; names parse. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/workload.h"
#include "volume/hermite.h"

typedef struct grid {
    size_t dims[3];
    double origin[3], spacing[3];
    double (*planes)[4]; /* x fastest */
} grid;

/* sdf__hermite_eval at p on g, gathering the block as volume.c does. */
static void hermite_at(const grid *g, const double p[3], int limit, double *value,
                       double grad[3])
{
    sdf__hermite_axis ax[3];
    for (int a = 0; a < 3; a++)
        sdf__hermite_locate(p[a], g->origin[a], g->spacing[a], g->dims[a], &ax[a]);
    double planes[64][4];
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++) {
                size_t idx = (ax[2].node[z] * g->dims[1] + ax[1].node[y]) * g->dims[0] +
                             ax[0].node[x];
                memcpy(planes[(z * 4 + y) * 4 + x], g->planes[idx], sizeof planes[0]);
            }
    sdf__hermite_eval(ax, planes, limit, value, grad);
}

/* Random planes: normals of length 0.5..1.5, values up to +-1 at the nodes. */
static grid random_grid(sdf_rng *rng)
{
    grid g = {{5, 4, 6}, {-0.3, 0.1, 0.2}, {0.25, 0.3, 0.2}, NULL};
    size_t n = g.dims[0] * g.dims[1] * g.dims[2];
    g.planes = malloc(n * sizeof *g.planes);
    for (size_t i = 0; g.planes && i < n; i++) {
        double v[3] = {sdf_rng_normal(rng), sdf_rng_normal(rng), sdf_rng_normal(rng)};
        double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]),
               s = (0.5 + sdf_rng_uniform(rng)) / len;
        size_t ijk[3] = {i % g.dims[0], i / g.dims[0] % g.dims[1], i / g.dims[0] / g.dims[1]};
        double value = 2 * sdf_rng_uniform(rng) - 1, dot = 0;
        for (int a = 0; a < 3; a++) {
            g.planes[i][a] = v[a] * s;
            dot += g.planes[i][a] * (g.origin[a] + (double)ijk[a] * g.spacing[a]);
        }
        g.planes[i][3] = value - dot;
    }
    return g;
}

static void test_gradient_is_derivative(void)
{
    sdf_rng rng = {11};
    grid g = random_grid(&rng);
    CHECK(g.planes != NULL, "memory");
    size_t bad = 0, checked = 0;
    for (int i = 0; g.planes && i < 4000; i++) {
        double p[3], value, grad[3];
        /* a margin of two cells around the volume: the linear continuation too */
        for (int a = 0; a < 3; a++)
            p[a] = g.origin[a] +
                   ((double)(g.dims[a] + 3) * sdf_rng_uniform(&rng) - 2) * g.spacing[a];
        int limit = i & 1;
        hermite_at(&g, p, limit, &value, grad);
        for (int a = 0; a < 3; a++) {
            double step = 1e-6 * g.spacing[a], q[3] = {p[0], p[1], p[2]}, r[3] = {p[0], p[1], p[2]};
            q[a] += step, r[a] -= step;
            double vq, vr, unused[3];
            hermite_at(&g, q, limit, &vq, unused);
            hermite_at(&g, r, limit, &vr, unused);
            double fd = (vq - vr) / (2 * step);
            bad += fabs(fd - grad[a]) > 1e-6 * (1 + fabs(grad[a]));
            checked++;
        }
    }
    CHECK(bad == 0, "%zu of %zu gradient components differ from central differences", bad,
          checked);
    free(g.planes);
}

/* A random cubic polynomial in x, y, z (all 20 monomials of degree <= 3) and its gradient. */
static double cubic(const double c[20], const double p[3], double grad[3])
{
    double value = 0;
    int m = 0;
    grad[0] = grad[1] = grad[2] = 0;
    for (int i = 0; i <= 3; i++)
        for (int j = 0; i + j <= 3; j++)
            for (int k = 0; i + j + k <= 3; k++, m++) {
                value += c[m] * pow(p[0], i) * pow(p[1], j) * pow(p[2], k);
                grad[0] += i ? c[m] * i * pow(p[0], i - 1) * pow(p[1], j) * pow(p[2], k) : 0;
                grad[1] += j ? c[m] * j * pow(p[0], i) * pow(p[1], j - 1) * pow(p[2], k) : 0;
                grad[2] += k ? c[m] * k * pow(p[0], i) * pow(p[1], j) * pow(p[2], k - 1) : 0;
            }
    return value;
}

/* Exact tangent planes of a cubic at every node: without the limit, cells whose 4 x 4 x 4
 * block lies inside the volume (central differences there give exact cross derivatives)
 * reproduce the cubic and its gradient. */
static void test_cubic(void)
{
    sdf_rng rng = {17};
    grid g = random_grid(&rng);
    CHECK(g.planes != NULL, "memory");
    double c[20];
    for (int m = 0; m < 20; m++)
        c[m] = sdf_rng_normal(&rng);
    size_t n = g.dims[0] * g.dims[1] * g.dims[2];
    for (size_t i = 0; g.planes && i < n; i++) {
        size_t ijk[3] = {i % g.dims[0], i / g.dims[0] % g.dims[1], i / g.dims[0] / g.dims[1]};
        double x[3], grad[3];
        for (int a = 0; a < 3; a++)
            x[a] = g.origin[a] + (double)ijk[a] * g.spacing[a];
        double v = cubic(c, x, grad);
        for (int a = 0; a < 3; a++)
            g.planes[i][a] = grad[a];
        g.planes[i][3] = v - (grad[0] * x[0] + grad[1] * x[1] + grad[2] * x[2]);
    }
    size_t bad = 0;
    for (int i = 0; g.planes && i < 2000; i++) {
        double p[3], value, grad[3], want[3];
        for (int a = 0; a < 3; a++) /* cells 1 .. dims - 3 */
            p[a] = g.origin[a] +
                   (1 + (double)(g.dims[a] - 3) * sdf_rng_uniform(&rng)) * g.spacing[a];
        hermite_at(&g, p, 0, &value, grad);
        double exact = cubic(c, p, want);
        int off = fabs(value - exact) > 1e-9 * (1 + fabs(exact));
        for (int a = 0; a < 3; a++)
            off |= fabs(grad[a] - want[a]) > 1e-9 * (1 + fabs(want[a]));
        bad += (size_t)off;
    }
    CHECK(bad == 0, "%zu of 2000 points off the cubic", bad);
    free(g.planes);
}

/* One plane at every node, through the public API: values and gradients reproduced. */
static void test_plane_field(const double plane[4], sdf_tdf_normalize normalize)
{
    sdf_volume_info in = {.dims = {5, 6, 7}, .origin = {-1.3, 0.2, 0.7},
                          .spacing = {0.3, 0.25, 0.41}, .order = 1, .normalize = normalize};
    size_t n = 5 * 6 * 7;
    float *data = malloc(n * 16);
    for (size_t i = 0; data && i < 4 * n; i++)
        data[i] = (float)plane[i % 4];
    sdf_volume *v = NULL;
    CHECK(data && sdf_volume_create(&in, data, &v, NULL) == 0, "plane volume");
    sdf_rng rng = {3};
    size_t bad = 0;
    for (int i = 0; v && i < 3000; i++) {
        float p[3], value, grad[3];
        double exact = (float)plane[3];
        for (int a = 0; a < 3; a++) {
            double extent = in.spacing[a] * (double)(in.dims[a] - 1);
            p[a] = (float)(in.origin[a] + extent * (1.6 * sdf_rng_uniform(&rng) - 0.3));
            exact += (double)(float)plane[a] * p[a];
        }
        sdf_volume_eval(v, p, 1, SDF_VOLUME_HERMITE, &value, grad, NULL);
        int off = fabs(value - exact) > 1e-6 * (1 + fabs(exact));
        for (int a = 0; a < 3; a++)
            off |= fabs(grad[a] - (float)plane[a]) > 1e-6;
        bad += (size_t)off;
    }
    CHECK(bad == 0, "plane (%g, %g, %g, %g), %s: %zu of 3000 points not reproduced", plane[0],
          plane[1], plane[2], plane[3], sdf_normalize_name(normalize), bad);
    sdf_volume_destroy(v);
    free(data);
}

/* Planes of a sphere's distance with noise in the values: the limit is busy. Spacing 1/4
 * and origin 0 put every face on a float. */
static sdf_volume *noisy_sphere(void)
{
    sdf_volume_info in = {.dims = {9, 8, 7}, .spacing = {0.25, 0.25, 0.25}, .order = 1};
    size_t n = 9 * 8 * 7;
    float *data = malloc(n * 16);
    sdf_rng rng = {9};
    const double centre[3] = {1.05, 0.9, 0.8};
    for (size_t i = 0; data && i < n; i++) {
        size_t ijk[3] = {i % 9, i / 9 % 8, i / 72};
        double x[3], d[3], r = 0;
        for (int a = 0; a < 3; a++) {
            x[a] = 0.25 * (double)ijk[a], d[a] = x[a] - centre[a];
            r += d[a] * d[a];
        }
        r = sqrt(r);
        double value = r - 0.6 + 0.05 * (sdf_rng_uniform(&rng) - 0.5), dot = 0;
        for (int a = 0; a < 3; a++) {
            data[4 * i + a] = (float)(d[a] / r);
            dot += (double)data[4 * i + a] * x[a];
        }
        data[4 * i + 3] = (float)(value - dot);
    }
    sdf_volume *v = NULL;
    CHECK(data && sdf_volume_create(&in, data, &v, NULL) == 0, "sphere volume");
    free(data);
    return v;
}

/* The largest jumps of value and gradient one float step either side of cell faces. */
static void face_jumps(const sdf_volume *v, sdf_volume_filter filter, double *value_jump,
                       double *grad_jump)
{
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    sdf_rng rng = {21};
    *value_jump = *grad_jump = 0;
    for (int i = 0; i < 3000; i++) {
        int axis = i % 3;
        float p[6];
        for (int a = 0; a < 3; a++)
            p[a] = (float)(in.spacing[a] * (double)(in.dims[a] - 1) * sdf_rng_uniform(&rng));
        /* an inner face: node 1 .. dims - 2 along the axis */
        double face = in.spacing[axis] * (double)(1 + sdf_rng_next(&rng) % (in.dims[axis] - 2));
        memcpy(p + 3, p, 12);
        p[axis] = nextafterf((float)face, -INFINITY);
        p[3 + axis] = nextafterf((float)face, INFINITY);
        float val[2], g[6];
        sdf_volume_eval(v, p, 2, filter, val, g, NULL);
        *value_jump = fmax(*value_jump, fabs((double)val[0] - val[1]));
        for (int a = 0; a < 3; a++)
            *grad_jump = fmax(*grad_jump, fabs((double)g[a] - g[3 + a]));
    }
}

static void test_continuity(const sdf_volume *v)
{
    double hv, hg, tv, tg;
    face_jumps(v, SDF_VOLUME_HERMITE, &hv, &hg);
    face_jumps(v, SDF_VOLUME_TRILINEAR, &tv, &tg);
    printf("  across faces: hermite value %.2e gradient %.2e; trilinear value %.2e gradient "
           "%.2e\n", hv, hg, tv, tg);
    CHECK(hv < 1e-5, "hermite is not C0 across faces: a jump of %g", hv);
    CHECK(hg < 1e-4, "hermite is not C1 across faces: a gradient jump of %g", hg);
    CHECK(tv < 1e-5, "trilinear is not C0 across faces: a jump of %g", tv);
    CHECK(tg > 1e-2, "the probe misses trilinear's gradient jumps (largest %g)", tg);
}

/* One inflated node in a plane field: the limit brings it to its neighbours' foot distance
 * (here its true value, a node straight above along the normal), and leaves the others. */
static void test_limit(void)
{
    grid g = {{4, 4, 4}, {0, 0, 0}, {1, 1, 1}, NULL};
    g.planes = malloc(64 * sizeof *g.planes);
    CHECK(g.planes != NULL, "memory");
    if (!g.planes)
        return;
    for (int i = 0; i < 64; i++) /* f = z - 0.5 */
        g.planes[i][0] = 0, g.planes[i][1] = 0, g.planes[i][2] = 1, g.planes[i][3] = -0.5;
    int node = (2 * 4 + 1) * 4 + 1; /* (1, 1, 2): value 1.5, inflated to 4.5 */
    g.planes[node][3] = 4.5 - 2;
    double p[3] = {1, 1, 2}, value, grad[3];
    hermite_at(&g, p, 1, &value, grad);
    CHECK(fabs(value - 1.5) < 1e-12, "the inflated node must be limited to 1.5, got %.17g", value);
    hermite_at(&g, p, 0, &value, grad);
    CHECK(fabs(value - 4.5) < 1e-12, "without the limit the node keeps 4.5, got %.17g", value);
    g.planes[node][3] = 0.5 - 2; /* deflated to 0.5: a limit never raises a value */
    hermite_at(&g, p, 1, &value, grad);
    CHECK(fabs(value - 0.5) < 1e-12, "a short value must stay 0.5, got %.17g", value);
    free(g.planes);
}

static void test_default_and_names(const sdf_volume *first)
{
    sdf_volume_info zin = {.dims = {3, 3, 3}, .spacing = {1, 1, 1}};
    float zdata[27];
    for (int i = 0; i < 27; i++)
        zdata[i] = (float)(i % 5) - 2;
    sdf_volume *zero = NULL;
    CHECK(sdf_volume_create(&zin, zdata, &zero, NULL) == 0, "zero-order volume");
    float p[3 * 64], a[64], b[64], ga[192], gb[192];
    sdf_rng rng = {4};
    for (int i = 0; i < 3 * 64; i++)
        p[i] = (float)(2.6 * sdf_rng_uniform(&rng) - 0.3);
    const sdf_volume *vols[2] = {zero, first};
    const sdf_volume_filter resolved[2] = {SDF_VOLUME_TRILINEAR, SDF_VOLUME_HERMITE};
    for (int o = 0; zero && first && o < 2; o++) {
        sdf_volume_eval(vols[o], p, 64, SDF_VOLUME_DEFAULT, a, ga, NULL);
        sdf_volume_eval(vols[o], p, 64, resolved[o], b, gb, NULL);
        CHECK(!memcmp(a, b, sizeof a) && !memcmp(ga, gb, sizeof ga),
              "order %d: the default is not %s", o, o ? "hermite" : "trilinear");
    }
    CHECK(sdf_volume_eval(zero, p, 64, SDF_VOLUME_HERMITE, a, NULL, NULL) == SDF_EINVAL,
          "hermite on a zero-order volume must be refused");
    CHECK(sdf_volume_eval(zero, p, 64, (sdf_volume_filter)4, a, NULL, NULL) == SDF_EINVAL,
          "an unknown filter must be refused");
    const char *names[] = {"default", "nearest", "trilinear", "HERMITE"};
    const sdf_volume_filter want[] = {SDF_VOLUME_DEFAULT, SDF_VOLUME_NEAREST,
                                      SDF_VOLUME_TRILINEAR, SDF_VOLUME_HERMITE};
    for (int i = 0; i < 4; i++) {
        sdf_volume_filter f = (sdf_volume_filter)99;
        CHECK(sdf_volume_filter_from_name(names[i], &f) == 0 && f == want[i], "name %s",
              names[i]);
    }
    sdf_volume_filter f;
    CHECK(sdf_volume_filter_from_name("cubic", &f) == SDF_EINVAL, "'cubic' must be refused");
    sdf_volume_destroy(zero);
}

/* The central difference of `v` along `axis` at p with steps +-k step (k = 1, 2). */
static double difference(const sdf_volume *v, const float p[3], int axis, double step, int k)
{
    float q[6];
    memcpy(q, p, 12), memcpy(q + 3, p, 12);
    q[axis] = (float)(q[axis] + k * step), q[3 + axis] = (float)(q[3 + axis] - k * step);
    float fq[2];
    sdf_volume_eval(v, q, 2, SDF_VOLUME_HERMITE, fq, NULL, NULL);
    return ((double)fq[0] - fq[1]) / ((double)q[axis] - q[3 + axis]);
}

/* Through the public API on a baked volume: the gradient against value differences. Along a
 * line inside a cell the field is a cubic, so Richardson's (4 D(h) - D(2h)) / 3 of central
 * differences is exact there but for float rounding: the points keep the stencil in a cell. */
static void test_baked(const sdf_volume *v, const char *name)
{
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    sdf_rng rng = {5};
    size_t bad = 0;
    for (int i = 0; i < 2000; i++) {
        float p[3], value, g[3];
        for (int a = 0; a < 3; a++) {
            double cell = floor(sdf_rng_uniform(&rng) * (double)(in.dims[a] - 1));
            double t = 0.1 + 0.8 * sdf_rng_uniform(&rng);
            p[a] = (float)(in.origin[a] + (cell + t) * in.spacing[a]);
        }
        sdf_volume_eval(v, p, 1, SDF_VOLUME_HERMITE, &value, g, NULL);
        for (int a = 0; a < 3; a++) {
            double step = 0.02 * in.spacing[a];
            double fd = (4 * difference(v, p, a, step, 1) - difference(v, p, a, step, 2)) / 3;
            bad += fabs(fd - g[a]) > 1e-3 * (1 + fabs(fd));
        }
    }
    CHECK(bad == 0, "%s: %zu gradient components differ from central differences", name, bad);
    /* A batch big enough to be split over threads gives the floats of small batches. */
    size_t many = 60000;
    float *mp = malloc(many * 12), *mv = malloc(many * 4), *mg = malloc(many * 12),
          *sv = malloc(many * 4), *sg = malloc(many * 12);
    CHECK(mp && mv && mg && sv && sg, "memory");
    for (size_t i = 0; mp && mv && mg && sv && sg && i < 3 * many; i++)
        mp[i] = (float)(in.origin[i % 3] +
                        (double)in.dims[i % 3] * in.spacing[i % 3] * sdf_rng_uniform(&rng));
    if (mp && mv && mg && sv && sg) {
        sdf_volume_eval(v, mp, many, SDF_VOLUME_HERMITE, mv, mg, NULL);
        for (size_t i = 0; i < many; i += 1000)
            sdf_volume_eval(v, mp + 3 * i, 1000, SDF_VOLUME_HERMITE, sv + i, sg + 3 * i, NULL);
        CHECK(!memcmp(mv, sv, many * 4) && !memcmp(mg, sg, many * 12),
              "%s: a threaded batch differs from small ones", name);
    }
    free(mp), free(mv), free(mg), free(sv), free(sg);
}

static const double unit_plane[4] = {0.48, -0.6, 0.64, 0.35};
static const double steep_plane[4] = {0.6, -1.2, 0.9, -0.7};

static void test_plane_fields(void)
{
    test_plane_field(unit_plane, SDF_NORMALIZE_PLANE);
    test_plane_field(steep_plane, SDF_NORMALIZE_PLANE);
    test_plane_field(steep_plane, SDF_NORMALIZE_GRADIENT);
}

static void test_sphere(void)
{
    sdf_volume *sphere = noisy_sphere();
    CHECK(sphere != NULL, "the noisy sphere");
    if (sphere) {
        test_continuity(sphere);
        test_default_and_names(sphere);
    }
    sdf_volume_destroy(sphere);
}

static void test_fandisk_bakes(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    const sdf_volume_encoding encodings[] = {SDF_ENCODING_FLOAT32, SDF_ENCODING_PACKED32};
    for (int e = 0; mesh && e < 2; e++) {
        sdf_bake_options o = {.dims = {21, 18, 15}, .order = 1, .encoding = encodings[e]};
        sdf_volume *v = NULL;
        CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == 0, "bake");
        if (v)
            test_baked(v, sdf_encoding_name(encodings[e]));
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(mesh);
}

static const check_case cases[] = {
    {"gradient_is_derivative", test_gradient_is_derivative},
    {"cubic", test_cubic},
    {"plane_fields", test_plane_fields},
    {"limit", test_limit},
    {"sphere", test_sphere},
    {"fandisk_bakes", test_fandisk_bakes},
};

int main(int argc, char **argv)
{
    return check_main("hermite", cases, CHECK_COUNT_OF(cases), argc, argv);
}
