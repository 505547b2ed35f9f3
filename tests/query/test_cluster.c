/* test_cluster.c - clusters of nearby points answered from one candidate list
 * (lib/points/cluster.c) and the filtered field that uses them, against slow, obvious
 * computations:
 *  - clusters of 1..64 points spread like filter samples (a Gaussian around a centre, each
 *    bounded by |f(centre)| + |x - centre|) around band, box and on-surface centres: the
 *    triangle named for every point is closest up to float rounding (brute force over all
 *    triangles in double precision); an exact hit is that triangle's exact closest point and
 *    distance, a float hit its distance to float rounding; a point never goes unanswered;
 *  - a capacity smaller than the candidates is reported, never answered wrongly;
 *  - sdf_query_filtered equals direct evaluation of eq. (10): the test draws the same samples
 *    (sdf__samples_draw), displaces them by eq. (4)'s kernel size, asks sdf_query for each
 *    and averages (also 1e-7 x diagonal off the surface, to 1e-3 relative); g's value is
 *    the same floats whether or not its gradient is asked; and the samples' mean gradient
 *    (sample_gradient) is the same average of sdf_query's gradients at the samples (1e-5
 *    apart at 95 % of the points, a float near-tie's 2e-3 / n at most), and near the
 *    surface, where h varies, not the analytic gradient. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"
#include "mesh/mesh.h"
#include "points/cluster.h"
#include "query/samples.h"
#include "geom/triangle.h"

static double diagonal_of(const sdf_mesh *m)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    return r.diagonal;
}

/* The exact distance from p to one triangle of the mesh, by the reference's own test. */
static double triangle_distance(const sdf_mesh *m, uint32_t tri, const float *p)
{
    double q[3] = {p[0], p[1], p[2]}, v[3][3], closest[3];
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++)
            v[k][a] = m->positions[3 * (size_t)m->triangles[3 * (size_t)tri + k] + a];
    return ref_point_triangle(q, v[0], v[1], v[2], closest);
}

/* `clusters` clusters around centres of workload `kind` (or on the surface), their points
 * spread N(0, (spread x diagonal)^2) per axis, each asking for a random `want`. */
static void test_clusters(const char *file, const char *kind, double spread, int clusters)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    double diag = diagonal_of(m), tol = 1e-6 * diag;
    size_t n = (size_t)clusters;
    float *centre = malloc(3 * n * sizeof *centre), *fc = malloc(n * sizeof *fc);
    float *on = malloc(3 * n * sizeof *on);
    sdf_workload(m, !strcmp(kind, "surface") ? "band" : kind, &n, 17, centre);
    sdf_query_result r = {.distance = fc, .closest = on};
    CHECK(sdf_query(m, centre, n, NULL, &r) == 0, "sdf_query");
    if (!strcmp(kind, "surface")) { /* centres on the surface: their own closest points */
        memcpy(centre, on, 3 * n * sizeof *centre);
        CHECK(sdf_query(m, centre, n, NULL, &r) == 0, "sdf_query");
    }
    sdf_mesh_report report;
    sdf_mesh_get_report(m, &report);
    sdf__cluster *cluster = sdf__cluster_create((int)report.triangles); /* room for all */
    CHECK(cluster != NULL, "cluster scratch");
    sdf_rng rng = {99};
    size_t checked = 0, worst_at = 0;
    double worst = 0;
    for (size_t c = 0; cluster && c < n; c++) {
        int count = 1 + (int)(sdf_rng_next(&rng) % SDF__CLUSTER_MAX);
        float pts[3 * SDF__CLUSTER_MAX];
        double bound[SDF__CLUSTER_MAX];
        uint8_t want[SDF__CLUSTER_MAX];
        for (int i = 0; i < count; i++) {
            double gap2 = 0;
            for (int a = 0; a < 3; a++) {
                pts[3 * i + a] = (float)(centre[3 * c + a] + spread * diag * sdf_rng_normal(&rng));
                double d = pts[3 * i + a] - centre[3 * c + a];
                gap2 += d * d;
            }
            bound[i] = (fabs(fc[c]) + sqrt(gap2)) * (1 + 1e-6);
            want[i] = (uint8_t)(sdf_rng_next(&rng) % 3);
        }
        sdf__hit hits[SDF__CLUSTER_MAX];
        int rc = sdf__cluster_closest(cluster, &m->tree, m->positions, m->triangles, (float)diag,
                                      (const char *)pts, 3 * sizeof(float), bound, want, count,
                                      hits);
        CHECK(rc == 0, "%s %s cluster %zu: refused with room for every triangle", file, kind, c);
        for (int i = 0; rc == 0 && i < count; i++) {
            const float *p = pts + 3 * i;
            ref_hit ref;
            ref_closest(m, p, &ref);
            CHECK(isfinite(hits[i].dist2), "%s: a point went unanswered", file);
            if (!isfinite(hits[i].dist2))
                continue;
            double named = triangle_distance(m, hits[i].triangle, p), d = sqrt(hits[i].dist2);
            double off = fmax(fabs(named - ref.dist), fabs(d - ref.dist));
            if (off > worst)
                worst = off, worst_at = checked;
            if (want[i] != SDF__CLUSTER_FLOAT) { /* the exact closest point of that triangle */
                double e2 = 0;
                for (int a = 0; a < 3; a++)
                    e2 += (hits[i].point[a] - p[a]) * (hits[i].point[a] - p[a]);
                CHECK(fabs(sqrt(e2) - named) <= 1e-9 * diag, "%s: closest point off by %g",
                      file, fabs(sqrt(e2) - named));
            }
            if (want[i] == SDF__CLUSTER_EXACT)
                CHECK(fabs(d - named) <= 1e-9 * diag, "%s: exact distance off by %g", file,
                      fabs(d - named));
            checked++;
        }
    }
    CHECK(worst <= tol, "%s %s spread %g: point %zu is %g from the closest (tolerance %g)",
          file, kind, spread, worst_at, worst, tol);
    printf("clusters %s %s spread %g: %zu points, worst %.3g x diagonal from brute force\n",
           file, kind, spread, checked, worst / diag);

    /* A capacity of 2: clusters with more candidates are refused, never answered wrongly. */
    sdf__cluster *tiny = sdf__cluster_create(2);
    size_t refused = 0;
    for (size_t c = 0; tiny && c < n; c++) {
        float pts[3 * 8];
        double bound[8];
        for (int i = 0; i < 8; i++) {
            for (int a = 0; a < 3; a++)
                pts[3 * i + a] = centre[3 * c + a] + (float)(0.01 * diag * (i & (1 << a) ? 1 : -1));
            bound[i] = fabs(fc[c]) + 0.02 * diag;
        }
        sdf__hit hits[8];
        if (sdf__cluster_closest(tiny, &m->tree, m->positions, m->triangles, (float)diag,
                                 (const char *)pts, 3 * sizeof(float), bound, NULL, 8, hits)) {
            refused++;
            continue;
        }
        for (int i = 0; i < 8; i++) {
            ref_hit ref;
            ref_closest(m, pts + 3 * i, &ref);
            CHECK(fabs(sqrt(hits[i].dist2) - ref.dist) <= tol, "%s: capacity 2 answered wrongly",
                  file);
        }
    }
    CHECK(refused > n / 2, "%s: a capacity of 2 refused only %zu of %zu clusters", file, refused,
          n);
    sdf__cluster_destroy(tiny);
    sdf__cluster_destroy(cluster);
    free(centre), free(fc), free(on);
    sdf_mesh_release(m);
}

/* Eq. (4): the kernel size from f(p). */
static double kernel_size(double f, double cap)
{
    double r = fmin(fabs(f) / cap, 1);
    return r * r * (3 - 2 * r);
}

static void test_filtered_direct(const char *file, const char *kind, int samples)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    double diag = diagonal_of(m);
    size_t n = 300;
    float *p = malloc(3 * n * sizeof *p), *f = malloc(n * sizeof *f), *g = malloc(n * sizeof *g);
    float *g2 = malloc(n * sizeof *g2), *grad = malloc(3 * n * sizeof *grad);
    sdf_workload(m, !strcmp(kind, "near") ? "band" : kind, &n, 23, p);
    float *on = malloc(3 * n * sizeof *on);
    sdf_query_result raw = {.distance = f, .closest = on};
    CHECK(sdf_query(m, p, n, NULL, &raw) == 0, "sdf_query");
    if (!strcmp(kind, "near")) { /* 1e-7 x diagonal off the surface, towards the point */
        for (size_t i = 0; i < n; i++) {
            double len = fmax(fabs(f[i]), 1e-30);
            for (int a = 0; a < 3; a++)
                p[3 * i + a] = (float)(on[3 * i + a] +
                                       1e-7 * diag * (p[3 * i + a] - on[3 * i + a]) / len);
        }
        CHECK(sdf_query(m, p, n, NULL, &raw) == 0, "sdf_query");
    }
    sdf_filter_options opt = {.samples = samples, .seed = 5}, resolved;
    CHECK(sdf__filter_resolve(m, &opt, &resolved, NULL) == 0, "resolve");
    sdf__samples s;
    CHECK(sdf__samples_draw(&resolved, &s) == 0, "draw");
    /* Direct: every displaced sample asked of sdf_query on its own batch, with gradients. */
    float *x = malloc(3 * (size_t)s.n * sizeof *x), *fx = malloc((size_t)s.n * sizeof *fx);
    float *gx = malloc(3 * (size_t)s.n * sizeof *gx);
    float *mean_grad = malloc(3 * n * sizeof *mean_grad);
    float gp[3];
    double worst = 0, worst_rel = 0;
    for (size_t i = 0; i < n; i++) {
        double h = kernel_size(f[i], resolved.cap), expect = 0, expect_grad[3] = {0, 0, 0};
        for (int k = 0; k < s.n; k++)
            for (int a = 0; a < 3; a++)
                x[3 * k + a] = (float)(p[3 * i + a] - s.offset[k][a] * h);
        sdf_query_result rx = {.distance = fx, .gradient = gx};
        CHECK(sdf_query(m, x, (size_t)s.n, &(sdf_query_options){.threads = 1}, &rx) == 0, "ask");
        for (int k = 0; k < s.n; k++) {
            expect += s.weight[k] * fx[k];
            for (int a = 0; a < 3; a++)
                expect_grad[a] += s.weight[k] * gx[3 * k + a];
        }
        if (h == 0) {
            sdf_query_result rp = {.distance = fx, .gradient = gp};
            CHECK(sdf_query(m, p + 3 * i, 1, NULL, &rp) == 0, "ask the point");
            expect = f[i];
            for (int a = 0; a < 3; a++)
                expect_grad[a] = gp[a];
        }
        g2[i] = (float)expect;
        for (int a = 0; a < 3; a++)
            mean_grad[3 * i + a] = (float)expect_grad[a];
    }
    sdf_query_result rf = {.distance = g};
    CHECK(sdf_query_filtered(m, p, n, NULL, &opt, &rf, NULL) == 0, "filtered");
    for (size_t i = 0; i < n; i++) {
        worst = fmax(worst, fabs((double)g[i] - g2[i]));
        if (g2[i] != 0)
            worst_rel = fmax(worst_rel, fabs((double)g[i] - g2[i]) / fabs(g2[i]));
    }
    CHECK(worst <= 1e-6 * diag, "%s %s: filtered differs from direct evaluation by %g", file,
          kind, worst);
    /* Just off the surface the float test's rounding would be large next to f itself. */
    if (!strcmp(kind, "near"))
        CHECK(worst_rel <= 1e-3, "%s near the surface: %g relative to direct", file, worst_rel);
    printf("filtered %s %s, %d samples: %zu points, worst %.3g x diagonal from direct, "
           "relative %.3g\n", file, kind, samples, n, worst / diag, worst_rel);
    /* The value does not depend on whether the gradient is asked for. */
    sdf_query_result rg = {.distance = g2, .gradient = grad};
    CHECK(sdf_query_filtered(m, p, n, NULL, &opt, &rg, NULL) == 0, "filtered gradient");
    CHECK(!memcmp(g, g2, n * sizeof *g), "%s %s: g's value changes when its gradient is asked",
          file, kind);
    /* The samples' mean gradient instead of g's: the direct average, the same value. */
    sdf_filter_options mean_opt = opt;
    mean_opt.sample_gradient = 1;
    float *grad_mean = malloc(3 * n * sizeof *grad_mean);
    sdf_query_result rm = {.distance = g2, .gradient = grad_mean};
    CHECK(sdf_query_filtered(m, p, n, NULL, &mean_opt, &rm, NULL) == 0, "sample gradient");
    CHECK(!memcmp(g, g2, n * sizeof *g), "%s %s: g's value changes with sample_gradient", file,
          kind);
    /* A sample's winner is closest up to float rounding (points/cluster.h): where two
     * triangles tie that closely over a flat stretch, their closest points may lie up to
     * ~sqrt(2e-6) of the distance apart, so that sample's direction may differ from
     * sdf_query's by ~1.4e-3 (seen: 1.2e-3, weighted 1/n in the mean). Elsewhere the mean is
     * sdf_query's to float rounding. */
    double worst_grad = 0, from_analytic = 0;
    size_t off = 0;
    for (size_t i = 0; i < n; i++) {
        double d = 0;
        for (size_t a = 3 * i; a < 3 * i + 3; a++) {
            d = fmax(d, fabs((double)grad_mean[a] - mean_grad[a]));
            from_analytic = fmax(from_analytic, fabs((double)grad_mean[a] - grad[a]));
        }
        worst_grad = fmax(worst_grad, d);
        off += d > 1e-5;
    }
    CHECK(worst_grad <= 2e-3 / s.n && off <= n / 20, "%s %s: the samples' mean gradient "
          "differs from direct evaluation by up to %g, by more than 1e-5 at %zu of %zu points",
          file, kind, worst_grad, off, n);
    if (!strcmp(kind, "band")) /* 0 < h < 1: the analytic gradient has grad h's term */
        CHECK(from_analytic > 1e-3, "%s band: the samples' mean gradient is the analytic one "
              "(%g apart)", file, from_analytic);
    printf("  samples' mean gradient: worst %.3g from direct (%zu points beyond 1e-5), %.3g "
           "from the analytic one\n", worst_grad, off, from_analytic);
    sdf__samples_free(&s);
    free(p), free(f), free(g), free(g2), free(grad), free(x), free(fx), free(on);
    free(gx), free(mean_grad), free(grad_mean);
    sdf_mesh_release(m);
}

static void test_clusters_fandisk(void)
{
    test_clusters("fandisk.off", "band", 0.005, 160);
    test_clusters("fandisk.off", "box", 0.02, 60);
    test_clusters("fandisk.off", "surface", 0.002, 100);
}

static void test_clusters_knot_and_cow(void)
{
    test_clusters("knot1.off", "band", 0.005, 100);
    test_clusters("cow.off", "band", 0.01, 80);
}

static void test_filtered_fandisk(void)
{
    test_filtered_direct("fandisk.off", "band", 64);
    test_filtered_direct("fandisk.off", "box", 32);
    test_filtered_direct("fandisk.off", "near", 64);
}

static void test_filtered_knot(void)
{
    test_filtered_direct("knot1.off", "band", 64);
}

static const check_case cases[] = {
    {"clusters_fandisk", test_clusters_fandisk},
    {"clusters_knot_and_cow", test_clusters_knot_and_cow},
    {"filtered_fandisk", test_filtered_fandisk},
    {"filtered_knot", test_filtered_knot},
};

int main(int argc, char **argv)
{
    return check_main("cluster", cases, CHECK_COUNT_OF(cases), argc, argv);
}
