/* test_filter.c - the convolution-filtered field (sdf_query_filtered) against its paper's
 * properties and against direct evaluation, on fandisk.off:
 *  - the zero level set is kept: |g| <= 1e-6 x diagonal at points on the surface;
 *  - where |f| >= f_c (h = 1) g is f convolved with the Gaussian: it matches a reference
 *    average of f over 20,000 independent kernel samples drawn here, within 4 standard
 *    errors of both estimates;
 *  - the analytic gradient matches central differences of g (relative error <= 1e-3) where
 *    the stencil does not straddle a kink of a sample (forward and backward differences
 *    agree), on at least 80 % of the points, both far (h = 1) and in the transition (h < 1);
 *  - the same request gives the same floats on 1, 2 and 3 threads (plain, adaptive, inside a
 *    smoothing sphere) and for the same seed;
 *  - smoothness (Fig. 13): the edge detector on the gradient field responds far less to the
 *    filtered field than to the raw one beyond f_c from the surface;
 *  - no extra zero crossings: with a bump within eq. (7)'s bound and with the unsigned
 *    integrand, g has the sign of f along lines through the mesh;
 *  - adaptive quality (sec. 5.2): N_min = N_max gives the fixed-count floats, the gradient
 *    (with the n_a term) matches central differences, and g has no jumps where n_a crosses
 *    an integer;
 *  - localized smoothing (sec. 6.1): outside the volume g = f bit for bit, deep inside it g
 *    is the global filter's value, its gradient matches central differences, and a box given
 *    as a box and as a mesh gives the same field;
 *  - bad parameters are refused with a message (the bump bound states its value). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/workload.h"

static double diagonal_of(const sdf_mesh *m)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    return r.diagonal;
}

static int filtered(const sdf_mesh *m, const float *p, size_t n, const sdf_filter_options *f,
                    int threads, float *g, float *grad)
{
    sdf_query_options o = {.threads = threads};
    sdf_query_result r = {.distance = g, .gradient = grad};
    sdf_diag diag = {0};
    int rc = sdf_query_filtered(m, p, n, &o, f, &r, &diag);
    CHECK(rc == 0, "sdf_query_filtered: %s", diag.message);
    return rc;
}

static void raw(const sdf_mesh *m, const float *p, size_t n, float *f, float *closest)
{
    sdf_query_result r = {.distance = f, .closest = closest};
    CHECK(sdf_query(m, p, n, NULL, &r) == 0, "sdf_query");
}

static void test_surface_kept(const sdf_mesh *m, double diag)
{
    size_t n = 500;
    float *p = malloc(3 * n * sizeof *p), *c = malloc(3 * n * sizeof *c);
    float *f = malloc(n * sizeof *f), *g = malloc(n * sizeof *g);
    sdf_workload(m, "band", &n, 5, p);
    raw(m, p, n, f, c); /* the closest points lie on the surface */
    sdf_filter_options opt = {.samples = 64, .seed = 3};
    filtered(m, c, n, &opt, 2, g, NULL);
    double worst = 0;
    for (size_t i = 0; i < n; i++)
        worst = fmax(worst, fabs(g[i]));
    CHECK(worst <= 1e-6 * diag, "on the surface |g| reaches %g (diagonal %g)", worst, diag);
    free(p), free(c), free(f), free(g);
}

/* Far points: g = f * w_a; compare with a reference average over the test's own samples. */
static void test_far_matches_convolution(const sdf_mesh *m, double diag)
{
    enum { POINTS = 40, REF = 20000, N = 256 };
    double cap = 0.02 * diag, a = 8 / (cap * cap), sigma = 1 / sqrt(2 * a);
    size_t n = 400;
    float *cand = malloc(3 * n * sizeof *cand), *fc = malloc(n * sizeof *fc);
    sdf_workload(m, "box", &n, 8, cand);
    raw(m, cand, n, fc, NULL);
    float p[3 * POINTS];
    int k = 0;
    for (size_t i = 0; i < n && k < POINTS; i++)
        if (fabs(fc[i]) >= 1.5 * cap) /* h = 1 even at the farthest sample that matters */
            memcpy(p + 3 * k++, cand + 3 * i, 3 * sizeof(float));
    CHECK(k == POINTS, "only %d far points", k);
    float g[POINTS];
    sdf_filter_options opt = {.samples = N, .seed = 11};
    filtered(m, p, (size_t)k, &opt, 2, g, NULL);
    float *q = malloc(3 * REF * sizeof *q), *fq = malloc(REF * sizeof *fq);
    sdf_rng rng = {12345};
    int worst_i = -1;
    double worst = 0;
    for (int i = 0; i < k; i++) {
        for (int j = 0; j < REF; j++)
            for (int c = 0; c < 3; c++)
                q[3 * j + c] = (float)(p[3 * i + c] - sigma * sdf_rng_normal(&rng));
        raw(m, q, REF, fq, NULL);
        double mean = 0, var = 0;
        for (int j = 0; j < REF; j++)
            mean += fq[j];
        mean /= REF;
        for (int j = 0; j < REF; j++)
            var += (fq[j] - mean) * (fq[j] - mean);
        double sd = sqrt(var / (REF - 1));
        double tol = 4 * sd * (1 / sqrt((double)N) + 1 / sqrt((double)REF)) + 1e-6 * diag;
        double err = fabs(g[i] - mean) / tol;
        if (err > worst)
            worst = err, worst_i = i;
    }
    CHECK(worst <= 1, "far point %d: g differs from the reference convolution by %.2f x the "
          "statistical tolerance", worst_i, worst);
    free(cand), free(fc), free(q), free(fq);
}

/* Central differences of g itself (same samples) against the analytic gradient. g is smooth
 * except where a displaced sample crosses a kink of f; such a point is recognised and skipped
 * because its differences are not linear in the step: for smooth g, D+ - D- (the forward
 * minus the backward difference) doubles when the step doubles. */
static void test_gradient(const sdf_mesh *m, double diag, const char *kind,
                          const sdf_filter_options *options)
{
    /* Adaptive quality makes g only C0 where n_a crosses an integer (the derivative switches
     * from one last sample to the next), a kink the stencil test cannot always see: there a
     * few points may differ, and fewer are smooth. */
    int adaptive = options && options->min_samples > 0;
    double min_checked = adaptive ? 0.5 : 0.8, max_bad = adaptive ? 0.02 : 0;
    size_t n = 300;
    float *p = malloc(3 * n * sizeof *p), *g = malloc(n * sizeof *g);
    float *grad = malloc(3 * n * sizeof *grad), *s = malloc(3 * n * sizeof *s);
    float *gs = malloc(n * sizeof *gs);
    sdf_workload(m, kind, &n, 21, p);
    sdf_filter_options opt = options ? *options : (sdf_filter_options){.samples = 32, .seed = 5};
    filtered(m, p, n, &opt, 2, g, grad);
    const double h = 1e-4 * diag;
    const double steps[4] = {h, -h, 2 * h, -2 * h};
    double *diff = calloc(4 * 3 * n, sizeof *diff); /* [step][point][axis] */
    for (int axis = 0; axis < 3; axis++) {
        for (int k = 0; k < 4; k++) {
            memcpy(s, p, 3 * n * sizeof *s);
            for (size_t i = 0; i < n; i++)
                s[3 * i + axis] += (float)steps[k];
            filtered(m, s, n, &opt, 2, gs, NULL);
            for (size_t i = 0; i < n; i++) {
                double step = (double)s[3 * i + axis] - p[3 * i + axis]; /* after rounding */
                diff[(k * n + i) * 3 + axis] = (gs[i] - g[i]) / step;
            }
        }
    }
    size_t checked = 0, bad = 0;
    for (size_t i = 0; i < n; i++) {
        double len = sqrt(grad[3 * i] * grad[3 * i] + grad[3 * i + 1] * grad[3 * i + 1] +
                          grad[3 * i + 2] * grad[3 * i + 2]);
        /* rounding of g to float, magnified by the step */
        double noise = 8 * 6e-8 * (fabs(g[i]) + 1e-3 * diag) / h;
        double nonlinear = 0, err = 0;
        for (int a = 0; a < 3; a++) {
            double d1 = diff[(0 * n + i) * 3 + a] - diff[(1 * n + i) * 3 + a];
            double d2 = diff[(2 * n + i) * 3 + a] - diff[(3 * n + i) * 3 + a];
            nonlinear = fmax(nonlinear, fabs(d2 - 2 * d1));
            double central = 0.5 * (diff[(0 * n + i) * 3 + a] + diff[(1 * n + i) * 3 + a]);
            err = fmax(err, fabs(central - grad[3 * i + a]));
        }
        if (nonlinear > 1e-3 * len + noise) /* a kink inside the stencil */
            continue;
        checked++;
        if (err > 1e-3 * len + noise && bad++ < 5 && !adaptive)
            CHECK(0, "%s point %zu: gradient (%g %g %g) vs central differences off by %g "
                  "(|grad| %g)", kind, i, grad[3 * i], grad[3 * i + 1], grad[3 * i + 2], err, len);
    }
    CHECK(checked >= min_checked * (double)n, "%s: only %zu of %zu points were smooth enough to "
          "check", kind, checked, n);
    CHECK((double)bad <= max_bad * (double)checked, "%s: %zu of %zu gradients off", kind, bad,
          checked);
    printf("filtered gradient, %s points: %zu of %zu checked, %zu off\n", kind, checked, n, bad);
    free(p), free(g), free(grad), free(s), free(gs), free(diff);
}

/* A closed axis-aligned box as a mesh (12 triangles, outward). */
static sdf_mesh *box_mesh(const double lo[3], const double hi[3])
{
    float v[24];
    for (int i = 0; i < 8; i++)
        for (int k = 0; k < 3; k++)
            v[3 * i + k] = (float)((i >> k & 1) ? hi[k] : lo[k]);
    static const uint32_t t[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    sdf_mesh *box = NULL;
    CHECK(sdf_mesh_create(v, 8, t, 12, NULL, &box, NULL) == 0, "box mesh");
    return box;
}

/* Sec. 6.1: filtering only inside a smoothing volume. */
static void test_localized(const sdf_mesh *m, double diag)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    double c[3], radius = 0.25 * diag;
    for (int k = 0; k < 3; k++)
        c[k] = 0.5 * (r.bbox_min[k] + r.bbox_max[k]);
    size_t n = 4000;
    float *p = malloc(3 * n * sizeof *p), *f = malloc(n * sizeof *f), *fg = malloc(3 * n * sizeof *fg);
    float *g = malloc(n * sizeof *g), *gg = malloc(3 * n * sizeof *gg), *global = malloc(n * sizeof *global);
    sdf_workload(m, "box", &n, 41, p);
    sdf_query_result raw_r = {.distance = f, .gradient = fg};
    CHECK(sdf_query(m, p, n, NULL, &raw_r) == 0, "raw");
    sdf_filter_options local = {.samples = 24, .seed = 2,
                                .smooth = {.shape = SDF_VOLUME_SPHERE, .center = {c[0], c[1], c[2]},
                                           .radius = radius, .depth = 0.05 * diag}};
    filtered(m, p, n, &local, 2, g, gg);
    sdf_filter_options everywhere = {.samples = 24, .seed = 2};
    filtered(m, p, n, &everywhere, 2, global, NULL);
    double cap = 0.02 * diag;
    size_t outside = 0, deep = 0, outside_bad = 0, deep_bad = 0;
    for (size_t i = 0; i < n; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++)
            d2 += (p[3 * i + k] - c[k]) * (p[3 * i + k] - c[k]);
        double fs = sqrt(d2) - radius;
        if (fs > 1e-6 * diag) { /* outside the volume: the raw field, bit for bit */
            outside++;
            outside_bad += memcmp(&g[i], &f[i], 4) || memcmp(gg + 3 * i, fg + 3 * i, 12);
        } else if (-fs > 0.05 * diag * 1.001 && fabs(f[i]) >= 1.5 * cap) {
            deep++; /* full kernel size, where eq. (4) also gives 1: the same floats */
            deep_bad += memcmp(&g[i], &global[i], 4) != 0;
        }
    }
    CHECK(outside > 100 && outside_bad == 0, "outside the volume %zu of %zu differ from f",
          outside_bad, outside);
    CHECK(deep > 20 && deep_bad == 0, "deep inside %zu of %zu differ from the global filter",
          deep_bad, deep);
    test_gradient(m, diag, "box", &local);
    test_gradient(m, diag, "band", &local);

    /* A box volume and the same box as a mesh volume agree (to float rounding of f_s). */
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++)
        lo[k] = c[k] - 0.2 * diag, hi[k] = c[k] + 0.15 * diag;
    sdf_mesh *box = box_mesh(lo, hi);
    if (box) {
        sdf_filter_options as_box = {.samples = 8, .seed = 4,
                                     .smooth = {.shape = SDF_VOLUME_BOX, .lo = {lo[0], lo[1], lo[2]},
                                                .hi = {hi[0], hi[1], hi[2]}, .scale = 2}};
        sdf_filter_options as_mesh = as_box;
        as_mesh.smooth.shape = SDF_VOLUME_MESH;
        as_mesh.smooth.mesh = box;
        filtered(m, p, n, &as_box, 2, g, NULL);
        filtered(m, p, n, &as_mesh, 2, global, NULL);
        double worst = 0;
        for (size_t i = 0; i < n; i++)
            worst = fmax(worst, fabs(g[i] - global[i]));
        CHECK(worst <= 1e-4 * diag, "box volume vs the same box as a mesh: %g apart", worst);
        sdf_mesh_release(box);
    }
    free(p), free(f), free(fg), free(g), free(gg), free(global);
}

/* Fig. 13: an edge detector on the gradient field (3^3 stencil, weight n - 1 = 26 at the
 * centre and -1 at the neighbours) finds the gradient's discontinuities. Beyond f_c from the
 * surface (h = 1) the filtered field's largest response must be well below the raw field's. */
static double largest_edge(const float *grad, const float *f, int k, double cap)
{
    double worst = 0;
    for (int z = 1; z < k - 1; z++)
        for (int y = 1; y < k - 1; y++)
            for (int x = 1; x < k - 1; x++) {
                size_t c = ((size_t)z * k + y) * k + x;
                if (fabs(f[c]) < cap)
                    continue;
                double e[3] = {0, 0, 0};
                for (int dz = -1; dz <= 1; dz++)
                    for (int dy = -1; dy <= 1; dy++)
                        for (int dx = -1; dx <= 1; dx++) {
                            size_t q = ((size_t)(z + dz) * k + (y + dy)) * k + (x + dx);
                            double w = q == c ? 26 : -1;
                            for (int a = 0; a < 3; a++)
                                e[a] += w * grad[3 * q + a];
                        }
                worst = fmax(worst, sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]));
            }
    return worst;
}

static void test_smoothness(const sdf_mesh *m, double diag)
{
    enum { K = 32 };
    size_t n = (size_t)K * K * K;
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    float *p = malloc(3 * n * sizeof *p), *f = malloc(n * sizeof *f);
    float *raw_grad = malloc(3 * n * sizeof *raw_grad), *g = malloc(n * sizeof *g);
    float *grad = malloc(3 * n * sizeof *grad);
    for (int z = 0; z < K; z++)
        for (int y = 0; y < K; y++)
            for (int x = 0; x < K; x++) {
                int ijk[3] = {x, y, z};
                for (int a = 0; a < 3; a++) {
                    double lo = r.bbox_min[a], ext = r.bbox_max[a] - lo;
                    p[3 * (((size_t)z * K + y) * K + x) + a] =
                        (float)(lo - 0.1 * ext + 1.2 * ext * ijk[a] / (K - 1));
                }
            }
    sdf_query_result rr = {.distance = f, .gradient = raw_grad};
    CHECK(sdf_query(m, p, n, NULL, &rr) == 0, "raw grid");
    /* The kernel must be about as wide as the stencil's spacing (1.2 x extent / 31) for the
     * detector to see it: a kink smoothed over a width far below the spacing still looks like
     * a jump. f_c = 0.1 x diagonal gives sigma = f_c / 4, about one spacing. Measured: ratio
     * 0.17 (n = 128); 0.39 with n = 32 (each sample's shifted kinks weigh 1/n); 0.80 with the
     * default f_c (sigma = 1/5 spacing). */
    double cap = 0.1 * diag;
    sdf_filter_options opt = {.samples = 128, .seed = 1, .cap = cap};
    filtered(m, p, n, &opt, 2, g, grad);
    double raw_edge = largest_edge(raw_grad, f, K, cap), filtered_edge = largest_edge(grad, f, K, cap);
    printf("Fig. 13 edge detector beyond f_c on a %d^3 grid over fandisk: raw %.3f, filtered "
           "%.3f (ratio %.3f)\n", K, raw_edge, filtered_edge, filtered_edge / raw_edge);
    CHECK(raw_edge > 1, "the raw field shows no gradient jumps (%g)", raw_edge);
    CHECK(filtered_edge < 0.3 * raw_edge, "filtered gradient jumps %g vs raw %g", filtered_edge,
          raw_edge);
    free(p), free(f), free(raw_grad), free(g), free(grad);
}

/* Sec. 5.2: adaptive sample counts. */
static void test_adaptive(const sdf_mesh *m, double diag)
{
    size_t n = 2000;
    float *p = malloc(3 * n * sizeof *p), *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    sdf_workload(m, "band", &n, 51, p);
    /* N_min = N_max: every point gets all samples, the same floats as without adaptivity. */
    sdf_filter_options fixed = {.samples = 16, .seed = 8};
    sdf_filter_options same = {.samples = 16, .min_samples = 16, .seed = 8};
    filtered(m, p, n, &fixed, 2, a, NULL);
    filtered(m, p, n, &same, 2, b, NULL);
    CHECK(!memcmp(a, b, n * sizeof *a), "min_samples = samples changes the values");
    /* The analytic gradient, including the term from n_a varying in space. */
    sdf_filter_options adaptive = {.samples = 48, .min_samples = 8, .seed = 8};
    test_gradient(m, diag, "band", &adaptive);
    test_gradient(m, diag, "box", &adaptive);
    /* Continuity: the last sample enters with the fractional part of n_a as its weight, so
     * g has no jumps along a line leaving the surface along its normal (where n_distance,
     * and n_a, sweep through ~20 integers): halving the step must (about) halve the largest
     * change between neighbours, which a jump would not. */
    enum { STEPS = 8000 };
    float *line = malloc(3 * STEPS * sizeof *line), *g = malloc(STEPS * sizeof *g);
    float c[3], fd[1], normal[3];
    sdf_query_result cr = {.distance = fd, .closest = c};
    CHECK(sdf_query(m, p, 1, NULL, &cr) == 0, "closest");
    sdf_query_result nr = {.distance = fd, .gradient = normal};
    CHECK(sdf_query(m, p, 1, NULL, &nr) == 0, "normal");
    for (int i = 0; i < STEPS; i++)
        for (int k = 0; k < 3; k++)
            line[3 * i + k] =
                (float)(c[k] + normal[k] * (fd[0] < 0 ? -1 : 1) * 0.03 * diag * i / STEPS);
    filtered(m, line, STEPS, &adaptive, 2, g, NULL);
    double fine = 0, coarse = 0;
    for (int i = 1; i < STEPS; i++)
        fine = fmax(fine, fabs((double)g[i] - g[i - 1]));
    for (int i = 2; i < STEPS; i += 2)
        coarse = fmax(coarse, fabs((double)g[i] - g[i - 2]));
    CHECK(fine <= 0.75 * coarse, "adaptive g jumps: halving the step leaves the largest change "
          "at %.3g of %.3g", fine, coarse);
    printf("adaptive: largest change between neighbours %.3g, at twice the step %.3g\n", fine,
           coarse);
    free(p), free(a), free(b), free(line), free(g);
}

static void test_deterministic(const sdf_mesh *m, double diag)
{
    size_t n = 3000;
    float *p = malloc(3 * n * sizeof *p), *a = malloc(4 * n * sizeof *a), *b = malloc(4 * n * sizeof *b);
    sdf_workload(m, "band", &n, 9, p);
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    /* Plain, adaptive (its stencil and medial measure run per point on the threads too),
     * and inside a smoothing sphere around the mesh's centre. */
    sdf_filter_options modes[3] = {
        {.samples = 16, .seed = 77},
        {.samples = 32, .min_samples = 8, .seed = 77},
        {.samples = 16, .seed = 77,
         .smooth = {.shape = SDF_VOLUME_SPHERE, .radius = 0.3 * diag, .depth = 0.05 * diag,
                    .center = {0.5 * (r.bbox_min[0] + r.bbox_max[0]),
                               0.5 * (r.bbox_min[1] + r.bbox_max[1]),
                               0.5 * (r.bbox_min[2] + r.bbox_max[2])}}},
    };
    for (int k = 0; k < 3; k++) {
        filtered(m, p, n, &modes[k], 1, a, a + n);
        for (int threads = 2; threads <= 3; threads++) {
            filtered(m, p, n, &modes[k], threads, b, b + n);
            CHECK(!memcmp(a, b, 4 * n * sizeof *a), "mode %d: 1 and %d threads give different "
                  "floats", k, threads);
        }
    }
    sdf_filter_options opt = modes[0];
    filtered(m, p, n, &opt, 1, a, a + n);
    opt.seed = 78;
    filtered(m, p, n, &opt, 2, b, b + n);
    CHECK(memcmp(a, b, n * sizeof *a), "another seed gives the same floats");
    free(p), free(a), free(b);
}

/* Along segments through the mesh, g keeps the sign of f wherever |f| is not tiny. */
static void test_no_extra_zeros(const sdf_mesh *m, double diag)
{
    enum { LINES = 60, STEPS = 200 };
    size_t n = LINES;
    float *ends = malloc(6 * LINES * sizeof *ends);
    size_t n2 = 2 * LINES;
    sdf_workload(m, "box", &n2, 31, ends);
    (void)n;
    float *p = malloc(3 * LINES * STEPS * sizeof *p), *f = malloc(LINES * STEPS * sizeof *f);
    float *g = malloc(LINES * STEPS * sizeof *g);
    for (int l = 0; l < LINES; l++)
        for (int t = 0; t < STEPS; t++)
            for (int c = 0; c < 3; c++) {
                double u = (double)t / (STEPS - 1);
                p[3 * (l * STEPS + t) + c] =
                    (float)((1 - u) * ends[6 * l + c] + u * ends[6 * l + 3 + c]);
            }
    raw(m, p, LINES * STEPS, f, NULL);
    const struct { const char *name; sdf_filter_options opt; } cases[] = {
        {"bump at the bound", {.kernel = SDF_KERNEL_BUMP, .samples = 32, .seed = 1}},
        {"unsigned Gaussian", {.unsigned_integrand = 1, .a = 0, .samples = 32, .seed = 1,
                               .cap = 0.005 * diag}},
    };
    for (size_t c = 0; c < 2; c++) {
        filtered(m, p, LINES * STEPS, &cases[c].opt, 2, g, NULL);
        size_t flips = 0;
        for (int i = 0; i < LINES * STEPS; i++)
            if (fabs(f[i]) > 1e-5 * diag && (g[i] < 0) != (f[i] < 0))
                flips++;
        CHECK(flips == 0, "%s: g and f differ in sign at %zu points", cases[c].name, flips);
    }
    free(ends), free(p), free(f), free(g);
}

static void expect_refused(const sdf_mesh *m, sdf_filter_options opt, const char *needle)
{
    float p[3] = {0, 0, 0}, g[1];
    sdf_query_result r = {.distance = g};
    sdf_diag diag = {0};
    int rc = sdf_query_filtered(m, p, 1, NULL, &opt, &r, &diag);
    CHECK(rc == SDF_EINVAL && strstr(diag.message, needle),
          "expected EINVAL mentioning \"%s\", got %d \"%s\"", needle, rc, diag.message);
    /* No points only checks the options (sdfd validates requests this way): the same refusal */
    sdf_query_result none = {0};
    sdf_diag diag0 = {0};
    rc = sdf_query_filtered(m, NULL, 0, NULL, &opt, &none, &diag0);
    CHECK(rc == SDF_EINVAL && !strcmp(diag0.message, diag.message),
          "no points: expected \"%s\", got %d \"%s\"", diag.message, rc, diag0.message);
}

static void test_bad_parameters(const sdf_mesh *m, double diag)
{
    expect_refused(m, (sdf_filter_options){.kernel = SDF_KERNEL_BUMP, .cap = 0.01 * diag,
                                           .b = 0.02 * diag}, "8 f_c / 9");
    expect_refused(m, (sdf_filter_options){.samples = -1}, "samples");
    expect_refused(m, (sdf_filter_options){.samples = SDF_FILTER_MAX_SAMPLES + 1}, "samples");
    expect_refused(m, (sdf_filter_options){.cap = -1}, "cap");
    expect_refused(m, (sdf_filter_options){.a = NAN}, "a must");
    /* Caps whose default widths overflow or vanish are named as the cause. */
    expect_refused(m, (sdf_filter_options){.cap = 1e-300}, "cap (f_c) = 1e-300 is out of range");
    expect_refused(m, (sdf_filter_options){.cap = 1e300}, "cap (f_c) = 1e+300 is out of range");
    expect_refused(m, (sdf_filter_options){.cap = 1e308, .a = 1}, "default width b");
    expect_refused(m, (sdf_filter_options){.kernel = (sdf_kernel)7}, "kernel");
    expect_refused(m, (sdf_filter_options){.smooth = {.shape = SDF_VOLUME_SPHERE}}, "radius");
    expect_refused(m, (sdf_filter_options){.smooth = {.shape = SDF_VOLUME_BOX, .hi = {1, 1, 0}}},
                   "lo < hi");
    expect_refused(m, (sdf_filter_options){.smooth = {.shape = SDF_VOLUME_MESH}}, "mesh");
    expect_refused(m, (sdf_filter_options){.smooth = {.shape = SDF_VOLUME_SPHERE, .radius = 1,
                                                      .depth = -1}}, "depth");
    expect_refused(m, (sdf_filter_options){.smooth = {.shape = (sdf_volume_shape)9}}, "volume");
    expect_refused(m, (sdf_filter_options){.samples = 8, .min_samples = 9}, "min_samples");
    expect_refused(m, (sdf_filter_options){.min_samples = 4, .grid = 1}, "grid");
    expect_refused(m, (sdf_filter_options){.min_samples = 4, .medial = -1}, "medial");
    /* Opting in to a wide bump is allowed. */
    float p[3] = {0, 0, 0}, g[1];
    sdf_query_result r = {.distance = g};
    sdf_filter_options wide = {.kernel = SDF_KERNEL_BUMP, .cap = 0.01 * diag, .b = 0.02 * diag,
                               .allow_wide_bump = 1};
    CHECK(sdf_query_filtered(m, p, 1, NULL, &wide, &r, NULL) == 0, "wide bump with opt-in");
    sdf_query_result none = {0};
    CHECK(sdf_query_filtered(m, NULL, 0, NULL, &wide, &none, NULL) == 0, "no points, good options");
    /* Closest points are not part of the filtered field. */
    float c[3];
    sdf_query_result rc = {.distance = g, .closest = c};
    CHECK(sdf_query_filtered(m, p, 1, NULL, NULL, &rc, NULL) == SDF_EINVAL, "closest accepted");
    /* A NaN point is reported by index. */
    float bad[6] = {0, 0, 0, 0, NAN, 0}, gb[2];
    sdf_query_result rb = {.distance = gb};
    CHECK(sdf_query_filtered(m, bad, 2, NULL, NULL, &rb, NULL) == SDF_ENONFINITE &&
              rb.bad_index == 1, "NaN point");
}

/* A case on fandisk: `call` sees the mesh `m` and its diagonal `diag`. */
#define FANDISK_CASE(fn, call)                                                             \
    static void fn(void)                                                                   \
    {                                                                                      \
        sdf_mesh *m = load_data_mesh("fandisk.off");                                       \
        if (!m)                                                                            \
            return;                                                                        \
        double diag = diagonal_of(m);                                                      \
        call;                                                                              \
        sdf_mesh_release(m);                                                               \
    }
FANDISK_CASE(case_surface_kept, test_surface_kept(m, diag))
FANDISK_CASE(case_far_matches_convolution, test_far_matches_convolution(m, diag))
FANDISK_CASE(case_gradient_box, test_gradient(m, diag, "box", NULL))
FANDISK_CASE(case_gradient_band, test_gradient(m, diag, "band", NULL))
FANDISK_CASE(case_localized, test_localized(m, diag))
FANDISK_CASE(case_deterministic, test_deterministic(m, diag))
FANDISK_CASE(case_adaptive, test_adaptive(m, diag))
FANDISK_CASE(case_smoothness, test_smoothness(m, diag))
FANDISK_CASE(case_no_extra_zeros, test_no_extra_zeros(m, diag))
FANDISK_CASE(case_bad_parameters, test_bad_parameters(m, diag))

/* cow.off is closed but crosses itself (sign: winding numbers): samples nearer to p than
 * |f(p)| take p's sign without a winding traversal; the values still match the reference
 * convolution built from sdf_query's own signs. */
static void case_cow(void)
{
    sdf_mesh *cow = load_data_mesh("cow.off");
    if (!cow)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(cow, &r);
    CHECK(r.closed && r.auto_sign == SDF_SIGN_WINDING, "cow: closed, winding sign");
    test_far_matches_convolution(cow, diagonal_of(cow));
    sdf_mesh_release(cow);
}

static const check_case cases[] = {
    {"surface_kept", case_surface_kept},
    {"far_matches_convolution", case_far_matches_convolution},
    {"gradient_box", case_gradient_box},
    {"gradient_band", case_gradient_band},
    {"localized", case_localized},
    {"deterministic", case_deterministic},
    {"adaptive", case_adaptive},
    {"smoothness", case_smoothness},
    {"no_extra_zeros", case_no_extra_zeros},
    {"bad_parameters", case_bad_parameters},
    {"cow", case_cow},
};

int main(int argc, char **argv)
{
    return check_main("filter", cases, CHECK_COUNT_OF(cases), argc, argv);
}
