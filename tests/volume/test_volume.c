/* test_volume.c - baked distance volumes (sdf_volume_* in sdf.h) against slow, obvious
 * computations, on fandisk.off:
 *  - packing: octahedral normals decode within the 10-bit bound, values within half a
 *    12-bit step, out-of-range values clamp;
 *  - zero order: every node holds exactly sdf_query's distance at its position;
 *  - first order (Algorithm 1): on sampled nodes, the plane from brute-force distances on
 *    the fine grid (every triangle, double precision) and the closed-form least squares of a
 *    symmetric grid matches the baked coefficients; 1 and 2 threads give the same bits;
 *  - evaluation: nodes reproduce their values, trilinear first order equals evaluating the
 *    interpolated coefficients (sec. 3), gradients match central differences, outside the
 *    box lookups clamp as documented, a NaN is refused;
 *  - files: EXR round trips are exact for every encoding, exrheader lists the attributes,
 *    every truncated or corrupted EXR is refused without a crash; npy and raw carry the words;
 *  - progress reaches 1, cancellation stops the bake, bad options are refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/accuracy.h"
#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"
#include "volume/pack.h"

static double angle_between(const double a[3], const double b[3])
{
    double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2],
           cz = a[0] * b[1] - a[1] * b[0];
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), dot);
}

static void test_packing(void)
{
    sdf_rng rng = {7};
    double worst = 0;
    for (int i = 0; i < 200000; i++) {
        double n[3] = {sdf_rng_normal(&rng), sdf_rng_normal(&rng), sdf_rng_normal(&rng)};
        if (i < 6) /* the axes, where the octahedron folds */
            n[0] = i / 2 == 0 ? (i % 2 ? -1 : 1) : 0, n[1] = i / 2 == 1 ? (i % 2 ? -1 : 1) : 0,
            n[2] = i / 2 == 2 ? (i % 2 ? -1 : 1) : 0;
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int a = 0; a < 3; a++)
            n[a] /= len;
        double value = (sdf_rng_uniform(&rng) * 2 - 1) * 3.5, m[3], back;
        sdf__unpack_plane(sdf__pack_plane(n, value, 3.5), 3.5, m, &back);
        worst = fmax(worst, angle_between(n, m));
        CHECK(fabs(back - value) <= 3.5 / 2047 / 2 * (1 + 1e-9), "value %.9g -> %.9g", value, back);
        CHECK(fabs(m[0] * m[0] + m[1] * m[1] + m[2] * m[2] - 1) < 1e-12, "decoded normal not unit");
    }
    /* A (u, v) cell of the 10-bit grid is 1/511 wide; its centre is 0.7/511 from a corner and
     * the octahedral map stretches lengths by less than 2.5: the best corner is within
     * 0.0035 rad (0.2 degrees). */
    CHECK(worst < 0.0035, "octahedral error %.5f rad", worst);
    printf("packing: worst normal error %.5f rad (%.3f deg)\n", worst, worst * 180 / M_PI);
    double n[3] = {0, 0, 1}, m[3], back;
    sdf__unpack_plane(sdf__pack_plane(n, 9, 2), 2, m, &back);
    CHECK(back == 2, "value beyond the range must clamp to it, got %g", back);
    sdf__unpack_plane(sdf__pack_plane(n, -9, 2), 2, m, &back);
    CHECK(back == -2, "value beyond the range must clamp to it, got %g", back);
}

static size_t node_count(const sdf_volume_info *in) { return in->dims[0] * in->dims[1] * in->dims[2]; }

static void node_position(const sdf_volume_info *in, size_t q, float p[3])
{
    size_t ijk[3] = {q % in->dims[0], q / in->dims[0] % in->dims[1], q / in->dims[0] / in->dims[1]};
    for (int a = 0; a < 3; a++)
        p[a] = (float)(in->origin[a] + (double)ijk[a] * in->spacing[a]);
}

static void test_zero_order(const sdf_mesh *mesh)
{
    sdf_bake_options o = {.dims = {17, 13, 11}, .query.threads = 2};
    sdf_volume *v = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_bake(mesh, &o, &v, &diag) == 0, "bake: %s", diag.message);
    if (!v)
        return;
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    double margin = 0.05 * r.diagonal;
    for (int a = 0; a < 3; a++) {
        CHECK(fabs(in.origin[a] - (r.bbox_min[a] - margin)) < 1e-9, "default box origin");
        CHECK(fabs(in.origin[a] + in.spacing[a] * (double)(in.dims[a] - 1) -
                   (r.bbox_max[a] + margin)) < 1e-9, "default box end");
    }
    size_t n = node_count(&in);
    float *p = malloc(n * 3 * sizeof *p), *f = malloc(n * sizeof *f);
    for (size_t q = 0; q < n; q++)
        node_position(&in, q, p + 3 * q);
    sdf_query_result res = {.distance = f};
    sdf_query(mesh, p, n, NULL, &res);
    CHECK(memcmp(f, sdf_volume_data(v), n * sizeof *f) == 0, "node values differ from sdf_query");
    CHECK(sdf_volume_data_bytes(v) == n * 4, "zero order holds one float per node");
    /* Reconstruction reproduces the nodes. */
    float *e = malloc(n * sizeof *e), *g = malloc(3 * n * sizeof *g);
    sdf_volume_eval(v, p, n, SDF_VOLUME_TRILINEAR, e, g, NULL);
    size_t bad = 0;
    for (size_t q = 0; q < n; q++)
        bad += fabsf(e[q] - f[q]) > 1e-6f * (1 + fabsf(f[q]));
    CHECK(bad == 0, "trilinear differs from the node value at %zu nodes", bad);
    sdf_volume_eval(v, p, n, SDF_VOLUME_NEAREST, e, g, NULL);
    CHECK(memcmp(e, f, n * sizeof *e) == 0, "nearest differs from the node values");
    /* Its gradient: central differences of the node values (one-sided on the boundary). */
    bad = 0;
    for (size_t q = 0; q < n; q++) {
        size_t ijk[3] = {q % in.dims[0], q / in.dims[0] % in.dims[1], q / in.dims[0] / in.dims[1]};
        size_t step[3] = {1, in.dims[0], in.dims[0] * in.dims[1]};
        for (int a = 0; a < 3; a++) {
            size_t lo = ijk[a] > 0 ? q - step[a] : q, hi = ijk[a] + 1 < in.dims[a] ? q + step[a] : q;
            double width = (double)((hi - lo) / step[a]) * in.spacing[a];
            double expect = ((double)f[hi] - (double)f[lo]) / width;
            bad += fabs(expect - g[3 * q + a]) > 1e-6 * (1 + fabs(expect));
        }
    }
    CHECK(bad == 0, "nearest zero-order gradient differs from node differences at %zu", bad);
    free(p), free(f), free(e), free(g);
    sdf_volume_destroy(v);
}

/* Brute-force the fine-grid samples of node q and fit the plane in closed form: on a grid
 * symmetric about the node, X^T X is diagonal, so a = sum f s_x / sum s_x^2 (and so on) and
 * the constant is the mean of f. Returns the normalised plane in the global basis. */
static double reference_plane(const sdf_mesh *mesh, const sdf_volume_info *in, size_t q,
                              double plane[4])
{
    float x[3];
    node_position(in, q, x);
    int h = in->fine_half;
    double sum_f = 0, sum_fs[3] = {0, 0, 0}, sum_ss[3] = {0, 0, 0};
    int count = 0;
    for (int k = -h; k <= h; k++)
        for (int j = -h; j <= h; j++)
            for (int i = -h; i <= h; i++) {
                double s[3] = {i * in->fine_spacing * in->spacing[0],
                               j * in->fine_spacing * in->spacing[1],
                               k * in->fine_spacing * in->spacing[2]};
                float p[3];
                for (int a = 0; a < 3; a++)
                    p[a] = (float)(x[a] + s[a]);
                ref_hit hit;
                ref_closest(mesh, p, &hit);
                /* The sign from the one-point path (the distance is the brute force's). */
                float signed_f;
                sdf_query_options so = {.traversal = SDF_TRAVERSAL_SINGLE, .threads = 1};
                sdf_query_result sr = {.distance = &signed_f};
                sdf_query(mesh, p, 1, &so, &sr);
                double f = signed_f < 0 ? -hit.dist : hit.dist;
                sum_f += f;
                for (int a = 0; a < 3; a++)
                    sum_fs[a] += f * s[a], sum_ss[a] += s[a] * s[a];
                count++;
            }
    double c[4] = {sum_fs[0] / sum_ss[0], sum_fs[1] / sum_ss[1], sum_fs[2] / sum_ss[2],
                   sum_f / count};
    double len = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    for (int a = 0; a < (in->normalize == SDF_NORMALIZE_PLANE ? 4 : 3); a++)
        c[a] /= len;
    plane[0] = c[0], plane[1] = c[1], plane[2] = c[2];
    plane[3] = c[3] - (c[0] * x[0] + c[1] * x[1] + c[2] * x[2]);
    return len;
}

static void test_first_order(const sdf_mesh *mesh, sdf_tdf_normalize normalize)
{
    sdf_bake_options o = {.dims = {24, 20, 16}, .order = 1, .query.threads = 2,
                          .normalize = normalize};
    sdf_volume *v = NULL, *one = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_bake(mesh, &o, &v, &diag) == 0, "bake: %s", diag.message);
    o.query.threads = 1;
    CHECK(sdf_volume_bake(mesh, &o, &one, &diag) == 0, "bake: %s", diag.message);
    if (!v || !one)
        return;
    CHECK(sdf_volume_data_bytes(v) == sdf_volume_data_bytes(one) &&
              !memcmp(sdf_volume_data(v), sdf_volume_data(one), sdf_volume_data_bytes(v)),
          "1 and 2 threads bake different volumes");
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    CHECK(in.fine_half == 1 && in.fine_spacing == 0.1, "defaults H = 1, Delta = 0.1");
    const float *data = sdf_volume_data(v);
    sdf_rng rng = {11};
    size_t n = node_count(&in), wrong = 0, tested = 0;
    for (int t = 0; t < 400; t++) {
        size_t q = (size_t)(sdf_rng_uniform(&rng) * (double)n);
        double ref[4];
        double len = reference_plane(mesh, &in, q, ref);
        float x[3];
        node_position(&in, q, x);
        /* Float distances carry ~1e-7 relative error; normalising divides it by len. */
        /* With the constant left alone, its error is the distances' own. */
        double tol = 2e-5 / len, scale = 1 + fabs(x[0]) + fabs(x[1]) + fabs(x[2]);
        if (normalize == SDF_NORMALIZE_GRADIENT)
            scale *= len;
        int ok = 1;
        for (int a = 0; a < 3; a++)
            ok = ok && fabs(data[4 * q + a] - ref[a]) <= tol;
        ok = ok && fabs(data[4 * q + 3] - ref[3]) <= tol * scale;
        if (!ok && wrong++ < 5)
            fprintf(stderr, "node %zu: baked %g %g %g %g, reference %g %g %g %g (len %g)\n", q,
                    data[4 * q], data[4 * q + 1], data[4 * q + 2], data[4 * q + 3], ref[0], ref[1],
                    ref[2], ref[3], len);
        tested++;
    }
    CHECK(wrong == 0, "%s: %zu of %zu first-order nodes differ from the brute-force fit",
          sdf_normalize_name(normalize), wrong, tested);
    sdf_volume_destroy(one);
    sdf_volume_destroy(v);
}

/* docs/volumes.md's claim: normalising only the gradient (keeping the fitted value) is more
 * accurate than the paper's step 6, here at 16^3 and 32^3 against a 64^3 reference. */
static void test_normalization_accuracy(const sdf_mesh *loaded)
{
    sdf_mesh *mesh = normalized_mesh(loaded);
    const size_t dims[] = {16, 32};
    accuracy_row rows[2];
    accuracy_grid grid = {0};
    CHECK(mesh && accuracy_grid_make(mesh, 64, 1, 0, 0, &grid) == 0, "reference grid");
    CHECK(mesh && accuracy_table(mesh, &grid, dims, 2, 0, 1, rows) == 0, "accuracy table");
    accuracy_grid_free(&grid);
    for (int r = 0; mesh && r < 2; r++)
        CHECK(rows[r].first_gradient < rows[r].first, "%zu^3: gradient-normalised %g, plane %g",
              rows[r].dim, rows[r].first_gradient, rows[r].first);
    sdf_mesh_release(mesh);
}

/* The first-order trilinear value from the coefficients interpolated by hand (sec. 3), and
 * gradients against central differences, for a volume `v`. */
static void test_evaluation(const sdf_volume *v, const char *name)
{
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    sdf_rng rng = {5};
    const int points = 2000;
    float *p = malloc(points * 3 * sizeof *p), *val = malloc(points * sizeof *val),
          *grad = malloc(points * 3 * sizeof *grad);
    for (int i = 0; i < points; i++)
        for (int a = 0; a < 3; a++) {
            /* Inside a cell, away from its faces, so the central differences stay in it. */
            double cell = floor(sdf_rng_uniform(&rng) * (double)(in.dims[a] - 1));
            double t = 0.1 + 0.8 * sdf_rng_uniform(&rng);
            p[3 * i + a] = (float)(in.origin[a] + (cell + t) * in.spacing[a]);
        }
    const sdf_volume_filter filters[] = {SDF_VOLUME_TRILINEAR, SDF_VOLUME_NEAREST};
    for (int fi = 0; fi < 2; fi++) {
        sdf_volume_filter filter = filters[fi];
        CHECK(sdf_volume_eval(v, p, points, filter, val, grad, NULL) == 0, "eval");
        size_t bad = 0;
        for (int i = 0; i < points; i++) {
            double step = 0.02 * fmin(in.spacing[0], fmin(in.spacing[1], in.spacing[2]));
            for (int a = 0; a < 3; a++) {
                if (filter == SDF_VOLUME_NEAREST && in.order == 0)
                    continue; /* nearest zero order: node differences, test_zero_order */
                float q[6];
                memcpy(q, p + 3 * i, 12), memcpy(q + 3, p + 3 * i, 12);
                q[a] = (float)(q[a] + step), q[3 + a] = (float)(q[3 + a] - step);
                float fq[2];
                sdf_volume_eval(v, q, 2, filter, fq, NULL, NULL);
                /* Nearest first order: the stencil must stay with one node. */
                double h = (double)q[a] - (double)q[3 + a];
                double fd = ((double)fq[0] - (double)fq[1]) / h;
                if (filter == SDF_VOLUME_NEAREST &&
                    floor(((double)q[a] - in.origin[a]) / in.spacing[a] + 0.5) !=
                        floor(((double)q[3 + a] - in.origin[a]) / in.spacing[a] + 0.5))
                    continue; /* the two steps fetch different nodes */
                if (fabs(fd - grad[3 * i + a]) > 2e-3 * (1 + fabs(fd)))
                    bad++;
            }
        }
        CHECK(bad == 0, "%s %s: %zu gradient components differ from central differences", name,
              filter == SDF_VOLUME_NEAREST ? "nearest" : "trilinear", bad);
    }
    if (in.order == 1 && in.encoding == SDF_ENCODING_FLOAT32) {
        const float *c = sdf_volume_data(v);
        sdf_volume_eval(v, p, points, SDF_VOLUME_TRILINEAR, val, NULL, NULL);
        size_t bad = 0;
        for (int i = 0; i < points; i++) {
            double coef[4] = {0, 0, 0, 0};
            size_t cell[3];
            double t[3];
            for (int a = 0; a < 3; a++) {
                double u = ((double)p[3 * i + a] - in.origin[a]) / in.spacing[a];
                cell[a] = (size_t)u, t[a] = u - (double)cell[a];
            }
            for (int corner = 0; corner < 8; corner++) {
                double w = 1;
                size_t ijk[3];
                for (int a = 0; a < 3; a++) {
                    int bit = corner >> a & 1;
                    w *= bit ? t[a] : 1 - t[a];
                    ijk[a] = cell[a] + (size_t)bit;
                }
                size_t idx = (ijk[2] * in.dims[1] + ijk[1]) * in.dims[0] + ijk[0];
                for (int k = 0; k < 4; k++)
                    coef[k] += w * c[4 * idx + k];
            }
            double direct = coef[0] * p[3 * i] + coef[1] * p[3 * i + 1] + coef[2] * p[3 * i + 2] + coef[3];
            bad += fabs(direct - val[i]) > 1e-5 * (1 + fabs(direct));
        }
        CHECK(bad == 0, "%s: %zu trilinear values differ from interpolated coefficients", name, bad);
    }
    /* Outside: clamp-to-edge lookups. */
    float out[3] = {(float)(in.origin[0] - 3 * in.spacing[0]), (float)in.origin[1],
                    (float)in.origin[2]};
    float edge[3] = {(float)in.origin[0], (float)in.origin[1], (float)in.origin[2]};
    float vo, ve, go[3], ge[3];
    sdf_volume_eval(v, out, 1, SDF_VOLUME_TRILINEAR, &vo, go, NULL);
    sdf_volume_eval(v, edge, 1, SDF_VOLUME_TRILINEAR, &ve, ge, NULL);
    if (in.order == 0) {
        CHECK(vo == ve, "%s: zero order outside must continue the boundary value", name);
        CHECK(go[0] == 0, "%s: no variation along a clamped axis", name);
    } else {
        double expect = ve - 3 * in.spacing[0] * ge[0];
        CHECK(fabs(vo - expect) < 1e-4 * (1 + fabs(expect)), "%s: first order outside extends the plane (%g vs %g)",
              name, vo, expect);
    }
    /* A batch big enough to be split over threads gives the floats of small batches. */
    size_t many = 100000;
    float *mp = malloc(many * 12), *mv = malloc(many * 4), *mg = malloc(many * 12),
          *sv = malloc(many * 4), *sg = malloc(many * 12);
    for (size_t i = 0; i < 3 * many; i++)
        mp[i] = p[i % (3 * points)] + (float)(i % 7) * 0.01f;
    sdf_volume_eval(v, mp, many, SDF_VOLUME_TRILINEAR, mv, mg, NULL);
    for (size_t i = 0; i < many; i += 1000)
        sdf_volume_eval(v, mp + 3 * i, 1000, SDF_VOLUME_TRILINEAR, sv + i, sg + 3 * i, NULL);
    CHECK(!memcmp(mv, sv, many * 4) && !memcmp(mg, sg, many * 12),
          "%s: a threaded batch differs from small ones", name);
    free(mp), free(mv), free(mg), free(sv), free(sg);
    float nan_point[6] = {0, 0, 0, 0, NAN, 0};
    size_t bad_index = 99;
    CHECK(sdf_volume_eval(v, nan_point, 2, SDF_VOLUME_TRILINEAR, val, NULL, &bad_index) ==
                  SDF_ENONFINITE && bad_index == 1, "NaN must be refused with its index");
    /* Finite but beyond +-SDF_MAX_COORDINATE: refused as sdf_query refuses it; the edge is not. */
    float far_points[9] = {0, 0, 0, 0, 0, 0, 0, 0, -2e18f};
    CHECK(sdf_volume_eval(v, far_points, 3, SDF_VOLUME_DEFAULT, val, NULL, &bad_index) ==
                  SDF_ENONFINITE && bad_index == 2, "-2e18 must be refused with its index");
    far_points[8] = -1e18f;
    CHECK(sdf_volume_eval(v, far_points, 3, SDF_VOLUME_DEFAULT, val, NULL, &bad_index) == 0 &&
                  isfinite(val[2]), "1e18 must be answered, finite");
    free(p), free(val), free(grad);
}

static void test_files(const sdf_volume *v, const char *name)
{
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    void *exr = NULL;
    size_t size = 0;
    sdf_diag diag;
    CHECK(sdf_volume_save_memory(v, SDF_VOLUME_EXR, &exr, &size, &diag) == 0, "%s: save: %s",
          name, diag.message);
    sdf_volume *back = NULL;
    CHECK(sdf_volume_load_exr_memory(exr, size, &back, &diag) == 0, "%s: load: %s", name,
          diag.message);
    if (back) {
        sdf_volume_info bi;
        sdf_volume_get_info(back, &bi);
        CHECK(!memcmp(&bi, &in, sizeof bi), "%s: description changed in the round trip", name);
        CHECK(sdf_volume_data_bytes(back) == sdf_volume_data_bytes(v) &&
                  !memcmp(sdf_volume_data(back), sdf_volume_data(v), sdf_volume_data_bytes(v)),
              "%s: EXR round trip is not exact", name);
        sdf_volume_destroy(back);
    }
    /* exrheader (OpenEXR's own tool) reads the file and lists our attributes. */
    char path[] = "/tmp/sdf-volume-XXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0, "mkstemp");
    if (fd >= 0) {
        close(fd);
        CHECK(sdf_volume_save_file(v, SDF_VOLUME_EXR, path, &diag) == 0, "save file: %s", diag.message);
        sdf_volume *from_file = NULL;
        CHECK(sdf_volume_load_exr_file(path, &from_file, &diag) == 0, "load file: %s", diag.message);
        sdf_volume_destroy(from_file);
        char cmd[128], line[512], all[8192] = "";
        snprintf(cmd, sizeof cmd, "exrheader %s 2>&1", path);
        FILE *pipe = popen(cmd, "r");
        CHECK(pipe != NULL, "cannot run exrheader");
        while (pipe && fgets(line, sizeof line, pipe))
            if (strlen(all) + strlen(line) < sizeof all)
                strcat(all, line);
        int status = pipe ? pclose(pipe) : -1;
        CHECK(status == 0 && strstr(all, "sdf.dims") && strstr(all, "sdf.encoding") &&
                  strstr(all, sdf_encoding_name(in.encoding)),
              "%s: exrheader did not list the volume (status %d):\n%s", name, status, all);
        remove(path);
    }
    /* Every truncation and many corruptions are refused cleanly (the sanitizers watch). */
    size_t refused = 0, tried = 0;
    for (size_t cut = 0; cut < size; cut += cut < 512 ? 1 : size / 97 + 1, tried++) {
        sdf_volume *t = NULL;
        refused += sdf_volume_load_exr_memory(exr, cut, &t, NULL) != 0 && !t;
        sdf_volume_destroy(t);
    }
    CHECK(refused == tried, "%s: %zu of %zu truncated files were accepted", name, tried - refused, tried);
    sdf_rng rng = {3};
    unsigned char *copy = malloc(size);
    for (int t = 0; t < 300; t++) {
        memcpy(copy, exr, size);
        for (int k = 0; k < 4; k++)
            copy[(size_t)(sdf_rng_uniform(&rng) * (double)size)] ^= (unsigned char)(1 + sdf_rng_next(&rng) % 255);
        sdf_volume *c = NULL;
        int rc = sdf_volume_load_exr_memory(copy, size, &c, NULL);
        CHECK(rc == 0 ? c != NULL : c == NULL, "corrupted load must give a volume or an error");
        sdf_volume_destroy(c);
    }
    free(copy);
    free(exr);
    /* npy: the header names the shape; the words follow. */
    void *npy = NULL;
    CHECK(sdf_volume_save_memory(v, SDF_VOLUME_NPY, &npy, &size, &diag) == 0, "npy: %s", diag.message);
    if (npy && in.encoding == SDF_ENCODING_FLOAT32) {
        sdf_npy_info ni;
        CHECK(sdf_npy_parse(npy, size, &ni, &diag) == 0, "npy parse: %s", diag.message);
        CHECK(ni.ndim == (in.order ? 4 : 3) && ni.shape[0] == in.dims[2] &&
                  ni.shape[1] == in.dims[1] && ni.shape[2] == in.dims[0] &&
                  !memcmp((char *)npy + ni.data_offset, sdf_volume_data(v), ni.data_bytes),
              "%s: npy shape or data wrong", name);
    } else if (npy) {
        CHECK(strstr((char *)npy + 10, "'<u4'") != NULL && size - sdf_volume_data_bytes(v) >= 64 &&
                  !memcmp((char *)npy + size - sdf_volume_data_bytes(v), sdf_volume_data(v),
                          sdf_volume_data_bytes(v)),
              "%s: packed npy must be uint32 words", name);
    }
    free(npy);
    void *raw = NULL;
    CHECK(sdf_volume_save_memory(v, SDF_VOLUME_RAW, &raw, &size, &diag) == 0, "raw");
    CHECK(raw && size == sdf_volume_data_bytes(v) && !memcmp(raw, sdf_volume_data(v), size),
          "%s: raw must be the words", name);
    free(raw);
    char json[1024];
    long len = sdf_volume_describe_json(v, json, sizeof json);
    CHECK(len > 0 && strstr(json, "\"dims\": [") && strstr(json, sdf_encoding_name(in.encoding)),
          "%s: metadata JSON: %s", name, json);
    CHECK(sdf_volume_describe_json(v, json, 20) == SDF_ELIMIT, "short buffer must be refused");
}

/* sdf_volume_create: a description and words in, the same out; bad descriptions and
 * non-finite floats refused. */
static void test_create(void)
{
    float words[2 * 3 * 2 * 4];
    for (size_t i = 0; i < sizeof words / sizeof words[0]; i++)
        words[i] = (float)i * 0.25f - 3;
    sdf_volume_info in = {.dims = {2, 3, 2}, .origin = {1, 2, 3}, .spacing = {0.5, 0.25, 1},
                          .order = 1, .fine_half = 1, .fine_spacing = 0.1};
    sdf_volume *v = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_create(&in, words, &v, &diag) == 0, "create: %s", diag.message);
    if (v) {
        sdf_volume_info back;
        sdf_volume_get_info(v, &back);
        CHECK(!memcmp(&back, &in, sizeof in) && sdf_volume_data_bytes(v) == sizeof words &&
                  !memcmp(sdf_volume_data(v), words, sizeof words),
              "create keeps the description and the words");
        /* At node (1, 2, 1) the nearest plane is that node's. */
        float p[3] = {1.5f, 2.5f, 4}, value;
        sdf_volume_eval(v, p, 1, SDF_VOLUME_NEAREST, &value, NULL, NULL);
        const float *c = words + 4 * ((1 * 3 + 2) * 2 + 1);
        CHECK(fabsf(value - (c[0] * p[0] + c[1] * p[1] + c[2] * p[2] + c[3])) < 1e-5f,
              "nearest plane at a node");
        sdf_volume_destroy(v);
    }
    struct {
        sdf_volume_info info;
        int code;
    } bad[] = {
        {{.dims = {1, 3, 2}, .spacing = {1, 1, 1}}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1, 0, 1}}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1, 1, 1}, .origin = {NAN, 0, 0}}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1, 1e308, 1}}, SDF_EINVAL},  /* far corner overflows */
        {{.dims = {2, 3, 2}, .spacing = {1, 1, 1e308}, .origin = {0, 0, 1e308}}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1e-310, 1, 1}}, SDF_EINVAL}, /* 1 / spacing overflows */
        {{.dims = {2, 3, 2}, .spacing = {1, 1, 1}, .order = 3}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1, 1, 1}, .encoding = SDF_ENCODING_PACKED32}, SDF_EINVAL},
        {{.dims = {2, 3, 2}, .spacing = {1, 1, 1}, .order = 1, .encoding = SDF_ENCODING_PACKED32},
         SDF_EINVAL}, /* no packed range */
        {{.dims = {4096, 4096, 4096}, .spacing = {1, 1, 1}}, SDF_ELIMIT},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        v = (sdf_volume *)1;
        CHECK(sdf_volume_create(&bad[i].info, words, &v, NULL) == bad[i].code && v == NULL,
              "bad description %zu", i);
    }
    words[5] = NAN;
    CHECK(sdf_volume_create(&in, words, &v, &diag) == SDF_ENONFINITE && v == NULL &&
              strstr(diag.message, "word 5"), "a NaN word: %s", diag.message);
}

typedef struct progress_log {
    int calls, cancel_at;
    double last;
    int monotonic;
} progress_log;

static int on_progress(void *user, double fraction)
{
    progress_log *l = user;
    l->monotonic = l->monotonic && fraction > l->last;
    l->last = fraction;
    return ++l->calls == l->cancel_at;
}

static void test_progress_and_options(const sdf_mesh *mesh)
{
    /* The query path (winding signs) reports after every slab of nodes; the scan path
     * (pseudonormals) after every run of slices, here one. */
    progress_log log = {0, -1, 0, 1};
    sdf_bake_options o = {.dims = {40, 40, 40}, .order = 1, .progress = on_progress, .user = &log};
    sdf_volume *v = NULL;
    CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == 0, "bake with progress");
    CHECK(log.calls >= 1 && log.monotonic && log.last == 1, "scan progress: %d calls, last %g",
          log.calls, log.last);
    sdf_volume_destroy(v);
    log = (progress_log){0, 1, 0, 1};
    v = (sdf_volume *)1;
    CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == SDF_ECANCELED && v == NULL && log.calls == 1,
          "cancel must stop a scanned bake at its first report");
    o.query.sign = SDF_SIGN_WINDING;
    log = (progress_log){0, -1, 0, 1};
    CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == 0, "bake with progress");
    CHECK(log.calls > 1 && log.monotonic && log.last == 1, "progress: %d calls, last %g",
          log.calls, log.last);
    sdf_volume_destroy(v);
    log = (progress_log){0, 2, 0, 1};
    v = (sdf_volume *)1;
    CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == SDF_ECANCELED && v == NULL && log.calls == 2,
          "cancel must stop the bake after the second report");
    struct {
        sdf_bake_options o;
        int code;
        const char *says;
    } bad[] = {
        {{.dims = {1, 8, 8}}, SDF_EINVAL, "resolution x"},
        {{.dims = {8, 8, 5000}}, SDF_EINVAL, "resolution z"},
        {{.dims = {4096, 4096, 4096}}, SDF_ELIMIT, "nodes"},
        {{.order = 2}, SDF_EINVAL, "order"},
        {{.order = 1, .fine_half = 5}, SDF_EINVAL, "H"},
        {{.order = 1, .fine_spacing = 0.6}, SDF_EINVAL, "Delta"},
        {{.order = 1, .fine_spacing = -1}, SDF_EINVAL, "Delta"},
        {{.encoding = SDF_ENCODING_PACKED32}, SDF_EINVAL, "first-order"},
        {{.lo = {0, 0, 0}, .hi = {1, -1, 1}}, SDF_EINVAL, "lo < hi"},
        {{.lo = {0, 0, 0}, .hi = {1, NAN, 1}}, SDF_EINVAL, "finite"},
        {{.lo = {0, -2e18, 0}, .hi = {1, 1, 1}}, SDF_EINVAL, "within +-1e18"},
        {{.margin = -1}, SDF_EINVAL, "margin"},
        {{.margin = 2e18}, SDF_EINVAL, "default bounds"}, /* refused here, not mid-bake */
        {{.lo = {-1e18, 0, 0}, .hi = {1e18, 1, 1}, .order = 1}, SDF_EINVAL, "fitting grids"},
        {{.query.sign = (sdf_sign_method)9}, SDF_EINVAL, "sign"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sdf_diag diag = {0};
        v = (sdf_volume *)1;
        int rc = sdf_volume_bake(mesh, &bad[i].o, &v, &diag);
        CHECK(rc == bad[i].code && v == NULL && strstr(diag.message, bad[i].says),
              "bad option %zu: rc %d, message '%s'", i, rc, diag.message);
    }
    /* A mesh that reaches almost to +-1e18 is accepted, but its box grown by the default
       5 % margin is not: the bake is refused before it starts, not failed half-way. */
    const float far = 0.99e18f;
    const float tetra_v[4 * 3] = {-far, -far, -far, far, -far, -far, -far, far, -far,
                                  -far, -far, far};
    const uint32_t tetra_t[4 * 3] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    sdf_mesh *huge = NULL;
    CHECK(sdf_mesh_create(tetra_v, 4, tetra_t, 4, NULL, &huge, NULL) == 0, "a mesh near 1e18");
    if (huge) {
        sdf_bake_options defaults = {.dims = {4, 4, 4}};
        sdf_diag diag = {0};
        v = (sdf_volume *)1;
        int rc = sdf_volume_bake(huge, &defaults, &v, &diag);
        CHECK(rc == SDF_EINVAL && v == NULL && strstr(diag.message, "default bounds"),
              "default bounds past 1e18: rc %d, message '%s'", rc, diag.message);
        sdf_mesh_release(huge);
    }
    sdf_filter_options wide = {.kernel = SDF_KERNEL_BUMP, .cap = 0.01, .b = 0.5};
    sdf_bake_options fo = {.dims = {8, 8, 8}, .filter = &wide};
    sdf_diag diag;
    CHECK(sdf_volume_bake(mesh, &fo, &v, &diag) == SDF_EINVAL && strstr(diag.message, "8 f_c / 9"),
          "a bad filter is refused before baking: %s", diag.message);
}

/* A filtered bake's nodes are sdf_query_filtered's values. */
static void test_filtered(const sdf_mesh *mesh)
{
    sdf_filter_options f = {.samples = 16};
    sdf_bake_options o = {.dims = {9, 8, 7}, .filter = &f};
    sdf_volume *v = NULL;
    CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == 0, "filtered bake");
    if (!v)
        return;
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    CHECK(in.filtered == 1, "filtered flag");
    size_t n = node_count(&in);
    float *p = malloc(n * 12), *g = malloc(n * 4);
    for (size_t q = 0; q < n; q++)
        node_position(&in, q, p + 3 * q);
    sdf_query_result r = {.distance = g};
    sdf_query_filtered(mesh, p, n, NULL, &f, &r, NULL);
    CHECK(!memcmp(g, sdf_volume_data(v), n * 4), "filtered nodes differ from sdf_query_filtered");
    free(p), free(g);
    sdf_volume_destroy(v);
}

/* A case on fandisk: `call` sees the mesh `mesh`. */
#define FANDISK_CASE(fn, call)                                                             \
    static void fn(void)                                                                   \
    {                                                                                      \
        sdf_mesh *mesh = load_data_mesh("fandisk.off");                                    \
        if (!mesh)                                                                         \
            return;                                                                        \
        call;                                                                              \
        sdf_mesh_release(mesh);                                                            \
    }
FANDISK_CASE(test_zero, test_zero_order(mesh))
FANDISK_CASE(test_first_plane, test_first_order(mesh, SDF_NORMALIZE_PLANE))
FANDISK_CASE(test_first_gradient, test_first_order(mesh, SDF_NORMALIZE_GRADIENT))
FANDISK_CASE(test_normalization, test_normalization_accuracy(mesh))
FANDISK_CASE(test_filtered_bake, test_filtered(mesh))
FANDISK_CASE(test_progress, test_progress_and_options(mesh))

/* Evaluation and files of zero-order float32, first-order float32 and packed bakes. */
static void test_bakes(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    if (!mesh)
        return;
    const sdf_volume_encoding encodings[] = {SDF_ENCODING_FLOAT32, SDF_ENCODING_PACKED32};
    for (int order = 0; order < 2; order++)
        for (int e = 0; e < 1 + order; e++) {
            sdf_bake_options o = {.dims = {21, 18, 15}, .order = order, .encoding = encodings[e]};
            sdf_volume *v = NULL;
            CHECK(sdf_volume_bake(mesh, &o, &v, NULL) == 0, "bake");
            char name[64];
            snprintf(name, sizeof name, "order %d %s", order, sdf_encoding_name(encodings[e]));
            if (v) {
                test_evaluation(v, name);
                test_files(v, name);
            }
            sdf_volume_destroy(v);
        }
    sdf_mesh_release(mesh);
}

static const check_case cases[] = {
    {"packing", test_packing},
    {"zero_order", test_zero},
    {"first_order_plane", test_first_plane},
    {"first_order_gradient", test_first_gradient},
    {"normalization_accuracy", test_normalization},
    {"filtered", test_filtered_bake},
    {"bakes", test_bakes},
    {"progress_and_options", test_progress},
    {"create", test_create},
};

int main(int argc, char **argv)
{
    return check_main("volume", cases, CHECK_COUNT_OF(cases), argc, argv);
}
