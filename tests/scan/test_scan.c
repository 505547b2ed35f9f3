/* test_scan.c - closest-feature scan conversion (lib/scan/scan.c) against the slow, obvious
 * computations:
 *  - zero-order bakes: every node holds exactly sdf_query's float at the node's position,
 *    asked one Embree query per point (itself tested against brute force), on closed meshes
 *    signed by pseudonormals and unsigned, over default, anisotropic, off-centre and far-away
 *    boxes; on sampled nodes |f| equals brute force over every triangle in double precision;
 *  - nodes lying exactly on faces, edges and corners (a cube on an aligned grid) are 0;
 *  - 1 and 2 threads give the same bits; the sign methods the scan does not take (winding,
 *    raycast) and open meshes still bake sdf_query's values;
 *  - zero order in several calls, as a large bake makes them (the first call records each
 *    region's z-span, the later ones skip regions outside their slices): the same bits;
 *  - first order: the fine samples of every node (H = 1..2) match sdf_query at the same float
 *    points to float rounding, signs included;
 *  - sdf_query on a batch laid out as a lattice (which takes the scan; uneven float axes)
 *    gives every output the packets give on the same points in reverse order, up to which of
 *    exactly tied triangles is named; lattices are recognised exactly. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"
#include "query/query.h"
#include "scan/scan.h"

static size_t node_count(const sdf_volume_info *in)
{
    return in->dims[0] * in->dims[1] * in->dims[2];
}

static void node_position(const sdf_volume_info *in, size_t n, float p[3])
{
    size_t ijk[3] = {n % in->dims[0], n / in->dims[0] % in->dims[1],
                     n / in->dims[0] / in->dims[1]};
    for (int a = 0; a < 3; a++)
        p[a] = (float)(in->origin[a] + (double)ijk[a] * in->spacing[a]);
}

/* sdf_query at the n points p, one Embree query per point (sdf_query would take the scan
 * itself for a lattice), with qo's sign and threads: the same bits as `values` at every
 * point. */
static void compare_with_query(const char *what, const sdf_mesh *mesh,
                               const sdf_query_options *qo, const float *p, size_t n,
                               const float *values)
{
    float *f = malloc(n * sizeof *f);
    sdf_query_options single = *qo;
    single.traversal = SDF_TRAVERSAL_SINGLE;
    sdf_query_result res = {.distance = f};
    CHECK(sdf_query(mesh, p, n, &single, &res) == 0, "%s: query", what);
    size_t differ = 0, first = n;
    for (size_t q = 0; q < n; q++)
        if (memcmp(&values[q], &f[q], sizeof *f) && differ++ == 0)
            first = q;
    CHECK(differ == 0, "%s: %zu of %zu nodes differ from sdf_query (first: node %zu, %.9g vs %.9g)",
          what, differ, n, first, first < n ? values[first] : 0.0, first < n ? f[first] : 0.0);
    free(f);
}

/* Bake with `o`, query every node with the same sign and threads, compare bits; brute force
 * on `samples` nodes. Returns the volume (or NULL). */
static sdf_volume *bake_and_compare(const char *what, const sdf_mesh *mesh,
                                    const sdf_bake_options *o, int samples)
{
    sdf_volume *v = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_bake(mesh, o, &v, &diag) == 0, "%s: bake: %s", what, diag.message);
    if (!v)
        return NULL;
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    size_t n = node_count(&in);
    float *p = malloc(n * 3 * sizeof *p);
    for (size_t q = 0; q < n; q++)
        node_position(&in, q, p + 3 * q);
    const float *baked = sdf_volume_data(v);
    compare_with_query(what, mesh, &o->query, p, n, baked);
    /* Brute force: every triangle, double precision. */
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const float *vert = sdf_mesh_vertices(mesh);
    const uint32_t *tri = sdf_mesh_triangles(mesh);
    sdf_rng rng = {11};
    double worst = 0;
    for (int k = 0; k < samples; k++) {
        size_t q = (size_t)(sdf_rng_uniform(&rng) * (double)n) % n;
        double x[3] = {p[3 * q], p[3 * q + 1], p[3 * q + 2]}, best = INFINITY;
        for (size_t t = 0; t < r.triangles; t++) {
            double c[3][3], closest[3];
            for (int i = 0; i < 3; i++)
                for (int a = 0; a < 3; a++)
                    c[i][a] = vert[3 * (size_t)tri[3 * t + i] + a];
            best = fmin(best, ref_point_triangle(x, c[0], c[1], c[2], closest));
        }
        /* The float answer rounds the distance: by up to half an ulp, far away more than
         * 1e-6 diagonals. */
        worst = fmax(worst, fabs(fabs((double)baked[q]) - best) - FLT_EPSILON * best);
    }
    CHECK(worst <= 1e-6 * r.diagonal, "%s: brute force differs by %g more than the float "
          "rounding (diagonal %g)", what, worst, r.diagonal);
    free(p);
    return v;
}

static void test_mesh(const char *file, sdf_sign_method sign, size_t dim)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    char what[128];
    sdf_bake_options o = {.dims = {dim, dim, dim}, .query = {.sign = sign, .threads = 2}};
    snprintf(what, sizeof what, "%s sign %s %zu^3", file, sdf_sign_name(sign), dim);
    sdf_volume_destroy(bake_and_compare(what, mesh, &o, 300));

    /* Anisotropic and off-centre: a box that cuts through the mesh. */
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_bake_options cut = o;
    size_t dims[3] = {dim + 7, dim / 2 + 3, dim / 3 + 2};
    for (int a = 0; a < 3; a++) {
        double span = r.bbox_max[a] - r.bbox_min[a];
        cut.dims[a] = dims[a];
        cut.lo[a] = r.bbox_min[a] + 0.3 * span;
        cut.hi[a] = r.bbox_max[a] + (a == 1 ? 0.4 : 0.02) * span;
    }
    snprintf(what, sizeof what, "%s sign %s, a cut-through anisotropic box", file,
             sdf_sign_name(sign));
    sdf_volume_destroy(bake_and_compare(what, mesh, &cut, 100));

    /* Far away: every node farther than the mesh is wide. */
    sdf_bake_options far = o;
    for (int a = 0; a < 3; a++) {
        far.dims[a] = dim / 2;
        far.lo[a] = r.bbox_max[a] + 1.5 * r.diagonal * (a + 1);
        far.hi[a] = far.lo[a] + r.diagonal;
    }
    snprintf(what, sizeof what, "%s sign %s, a box far away", file, sdf_sign_name(sign));
    sdf_volume_destroy(bake_and_compare(what, mesh, &far, 30));

    /* Long and thin: 2e5 diagonals along x, the mesh's middle across. Regions reach ~1e5
     * diagonals, and their truncation marched a coarse cell of the short axes at a time:
     * millions of steps each, a bake of many minutes. */
    sdf_bake_options thin = o;
    thin.dims[0] = dim, thin.dims[1] = thin.dims[2] = dim / 4;
    for (int a = 0; a < 3; a++) {
        double mid = 0.5 * (r.bbox_min[a] + r.bbox_max[a]);
        double half = a == 0 ? 1e5 * r.diagonal : 0.1 * (r.bbox_max[a] - r.bbox_min[a]);
        thin.lo[a] = mid - half, thin.hi[a] = mid + half;
    }
    snprintf(what, sizeof what, "%s sign %s, a long thin box", file, sdf_sign_name(sign));
    sdf_volume_destroy(bake_and_compare(what, mesh, &thin, 30));
    sdf_mesh_release(mesh);
}

/* Nodes on the faces, edges and corners of a cube ([-1, 1]^3 in cube.ply), where the
 * features' regions meet. */
static void test_on_surface(void)
{
    sdf_mesh *mesh = load_data_mesh("cube.ply");
    if (!mesh)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_bake_options o = {.dims = {13, 13, 13}, .query.threads = 2};
    for (int a = 0; a < 3; a++) { /* spacing a quarter of the half-width: nodes on the faces */
        double mid = 0.5 * (r.bbox_min[a] + r.bbox_max[a]);
        double half = 0.5 * (r.bbox_max[a] - r.bbox_min[a]);
        o.lo[a] = mid - 1.5 * half, o.hi[a] = mid + 1.5 * half;
    }
    sdf_volume *v = bake_and_compare("cube.ply, nodes on its surface", mesh, &o, 100);
    if (v) {
        sdf_volume_info in;
        sdf_volume_get_info(v, &in);
        const float *f = sdf_volume_data(v);
        size_t zeros = 0;
        for (size_t q = 0; q < node_count(&in); q++)
            zeros += f[q] == 0;
        /* A 13^3 grid over 1.5x the cube: its 9^3 nodes from -1 to 1, the 7^3 inner ones off
         * the surface. */
        CHECK(zeros == 9 * 9 * 9 - 7 * 7 * 7, "%zu nodes on the cube's surface, expected %d", zeros,
              9 * 9 * 9 - 7 * 7 * 7);
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(mesh);
}

static void test_threads(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    if (!mesh)
        return;
    sdf_bake_options o = {.dims = {40, 33, 29}, .query.threads = 1};
    sdf_volume *one = NULL, *two = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_bake(mesh, &o, &one, &diag) == 0, "bake: %s", diag.message);
    o.query.threads = 2;
    CHECK(sdf_volume_bake(mesh, &o, &two, &diag) == 0, "bake: %s", diag.message);
    if (one && two)
        CHECK(!memcmp(sdf_volume_data(one), sdf_volume_data(two), sdf_volume_data_bytes(one)),
              "1 and 2 threads bake different bits");
    sdf_volume_destroy(one), sdf_volume_destroy(two);
    sdf_mesh_release(mesh);
}

/* sdf__scan_slices in uneven runs of slices, as a bake larger than one call's scratch makes
 * them, against sdf_query one Embree query per node: the same bits at every node. */
static void test_slices_in_calls(const char *file, sdf_sign_method sign, size_t dim)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_volume_info in = {.dims = {dim + 2, dim - 1, dim}};
    for (int a = 0; a < 3; a++) {
        in.origin[a] = r.bbox_min[a] - 0.05 * r.diagonal;
        in.spacing[a] =
            (r.bbox_max[a] - r.bbox_min[a] + 0.1 * r.diagonal) / (double)(in.dims[a] - 1);
    }
    sdf_query_options qo = {.sign = sign, .threads = 2};
    size_t n = node_count(&in), slice = in.dims[0] * in.dims[1];
    float *p = malloc(n * 3 * sizeof *p), *f = malloc(n * sizeof *f);
    for (size_t q = 0; q < n; q++)
        node_position(&in, q, p + 3 * q);
    sdf__scan *scan = NULL;
    CHECK(sdf__scan_create(mesh, &in, &qo, &scan) == 0, "%s: scan", file);
    /* Runs of 1, dim / 3 and the rest of the slices. */
    size_t cut[4] = {0, 1, 1 + dim / 3, in.dims[2]};
    for (int c = 0; c < 3 && scan; c++) {
        sdf_query_result out = {.distance = f + cut[c] * slice};
        CHECK(sdf__scan_slices(scan, cut[c], cut[c + 1], &out) == 0, "%s: slices %zu-%zu", file,
              cut[c], cut[c + 1]);
    }
    sdf__scan_destroy(scan);
    char what[128];
    snprintf(what, sizeof what, "%s in 3 calls", file);
    compare_with_query(what, mesh, &qo, p, n, f);
    free(p), free(f);
    sdf_mesh_release(mesh);
}

typedef struct copy_ctx {
    float *all;
    size_t m;
} copy_ctx;

/* sdf__sample_fn: keep every node's samples. */
static int copy_samples(void *user, size_t first, size_t count, float *f, int worker)
{
    (void)worker;
    copy_ctx *c = user;
    memcpy(c->all + first * c->m, f, count * c->m * sizeof *f);
    return 0;
}

/* sdf__scan_samples against sdf_query at every fine sample of a small lattice. */
static void test_samples(const char *file, sdf_sign_method sign, int half, double spacing_cells,
                         size_t dim)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    sdf_volume_info in = {.dims = {dim, dim - 3, dim + 2}};
    for (int a = 0; a < 3; a++) {
        in.origin[a] = r.bbox_min[a] - 0.1 * r.diagonal;
        in.spacing[a] =
            (r.bbox_max[a] - r.bbox_min[a] + 0.2 * r.diagonal) / (double)(in.dims[a] - 1);
    }
    sdf_query_options qo = {.sign = sign, .threads = 2};
    sdf__scan *scan = NULL;
    CHECK(sdf__scan_create(mesh, &in, &qo, &scan) == 0, "%s: scan", file);
    size_t w = (size_t)(2 * half + 1), m = w * w * w;
    size_t nodes = in.dims[0] * in.dims[1] * in.dims[2];
    float *f = malloc(nodes * m * sizeof *f), *p = malloc(nodes * m * 3 * sizeof *p);
    float *g = malloc(nodes * m * sizeof *g);
    /* In two calls, as a bake makes them. */
    size_t split = in.dims[2] / 2;
    copy_ctx copy = {f, m};
    CHECK(scan &&
              sdf__scan_samples(scan, 0, split, half, spacing_cells, copy_samples, &copy) == 0 &&
              sdf__scan_samples(scan, split, in.dims[2], half, spacing_cells, copy_samples,
                                &copy) == 0,
          "%s: samples", file);
    for (size_t n = 0, q = 0; n < nodes; n++) {
        size_t ijk[3] = {n % in.dims[0], n / in.dims[0] % in.dims[1], n / in.dims[0] / in.dims[1]};
        for (int z = -half; z <= half; z++)
            for (int y = -half; y <= half; y++)
                for (int x = -half; x <= half; x++, q++) {
                    int o[3] = {x, y, z};
                    for (int a = 0; a < 3; a++) {
                        float node = (float)(in.origin[a] + (double)ijk[a] * in.spacing[a]);
                        p[3 * q + a] = (float)((double)node + o[a] * spacing_cells * in.spacing[a]);
                    }
                }
    }
    sdf_query_options single = qo;
    single.traversal = SDF_TRAVERSAL_SINGLE;
    sdf_query_result res = {.distance = g};
    CHECK(sdf_query(mesh, p, nodes * m, &single, &res) == 0, "%s: query", file);
    size_t bad = 0, first = 0;
    for (size_t q = 0; q < nodes * m; q++)
        if (!(fabsf(f[q] - g[q]) <= 1e-6f * fabsf(g[q]) + 1e-7f * (float)r.diagonal) && bad++ == 0)
            first = q;
    CHECK(bad == 0, "%s H=%d: %zu of %zu samples differ from sdf_query (first %zu: %.9g vs %.9g)",
          file, half, bad, nodes * m, first, bad ? f[first] : 0.0, bad ? g[first] : 0.0);
    free(f), free(p), free(g);
    sdf__scan_destroy(scan);
    sdf_mesh_release(mesh);
}

/* A lattice batch: axis a runs from lo to hi in n[a] steps computed in double and rounded
 * to float (numpy's linspace does the same: the floats are not evenly spaced). */
static float *lattice(const double lo[3], const double hi[3], const size_t n[3])
{
    float *p = malloc(n[0] * n[1] * n[2] * 3 * sizeof *p);
    for (size_t k = 0, q = 0; k < n[2]; k++)
        for (size_t j = 0; j < n[1]; j++)
            for (size_t i = 0; i < n[0]; i++, q++) {
                size_t idx[3] = {i, j, k};
                for (int a = 0; a < 3; a++)
                    p[3 * q + a] =
                        (float)(lo[a] + (hi[a] - lo[a]) * (double)idx[a] / (double)(n[a] - 1));
            }
    return p;
}

static void test_lattice_queries(const char *file)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    double lo[3], hi[3];
    for (int a = 0; a < 3; a++)
        lo[a] = r.bbox_min[a] - 0.2 * r.diagonal, hi[a] = r.bbox_max[a] + 0.13 * r.diagonal;
    size_t n[3] = {41, 37, 33}, count = n[0] * n[1] * n[2], dims[3];
    float *p = lattice(lo, hi, n), *axis[3];
    CHECK(sdf__find_lattice(p, 0, count, dims, axis) == 1 && dims[0] == n[0] &&
              dims[1] == n[1] && dims[2] == n[2],
          "%s: the lattice is recognised", file);
    for (int a = 0; a < 3; a++)
        free(axis[a]);
    float *f[2], *g[2], *c[2], *w[2];
    uint32_t *t[2];
    /* The lattice path, then the packets on the same points in reverse order (no lattice);
     * both name the lowest-numbered of equally close triangles. */
    float *reversed = malloc(count * 3 * sizeof *reversed);
    for (size_t q = 0; q < count; q++)
        memcpy(reversed + 3 * (count - 1 - q), p + 3 * q, 3 * sizeof *p);
    for (int pass = 0; pass < 2; pass++) {
        f[pass] = malloc(count * sizeof(float)), t[pass] = malloc(count * sizeof(uint32_t));
        g[pass] = malloc(3 * count * sizeof(float)), c[pass] = malloc(3 * count * sizeof(float));
        w[pass] = malloc(3 * count * sizeof(float));
        sdf_query_options qo = {.threads = 2};
        sdf_query_result res = {.distance = f[pass], .gradient = g[pass], .closest = c[pass],
                                .triangle = t[pass], .barycentric = w[pass]};
        CHECK(sdf_query(mesh, pass ? reversed : p, count, &qo, &res) == 0, "%s: query", file);
    }
    for (size_t q = 0; q < count / 2; q++) { /* back to lattice order */
        size_t e = count - 1 - q;
        float tf = f[1][q];
        f[1][q] = f[1][e], f[1][e] = tf;
        uint32_t tt = t[1][q];
        t[1][q] = t[1][e], t[1][e] = tt;
        for (int a = 0; a < 3; a++) {
            float *arr[3] = {g[1], c[1], w[1]};
            for (int k = 0; k < 3; k++) {
                float x = arr[k][3 * q + a];
                arr[k][3 * q + a] = arr[k][3 * e + a], arr[k][3 * e + a] = x;
            }
        }
    }
    free(reversed);
    size_t differ = 0, other = 0;
    for (size_t q = 0; q < count; q++) {
        differ += memcmp(&f[0][q], &f[1][q], sizeof(float)) != 0;
        if (t[0][q] != t[1][q]) {
            /* An exact tie (two triangles sharing the closest vertex or edge) may name the
             * other triangle, as packets and single queries may: the same point, though. */
            other++;
            for (int a = 0; a < 3; a++)
                differ += fabsf(c[0][3 * q + a] - c[1][3 * q + a]) > 1e-6f * (float)r.diagonal;
        } else {
            differ += memcmp(g[0] + 3 * q, g[1] + 3 * q, 3 * sizeof(float)) ||
                      memcmp(c[0] + 3 * q, c[1] + 3 * q, 3 * sizeof(float)) ||
                      memcmp(w[0] + 3 * q, w[1] + 3 * q, 3 * sizeof(float));
        }
    }
    CHECK(differ == 0 && other < count / 20, "%s: lattice queries differ at %zu of %zu "
          "points (%zu name another, equally close triangle)", file, differ, count, other);
    for (int pass = 0; pass < 2; pass++)
        free(f[pass]), free(g[pass]), free(c[pass]), free(w[pass]), free(t[pass]);
    /* Not lattices: one point moved; a count that is not a whole number of slices. */
    p[3 * 1234 + 1] = nextafterf(p[3 * 1234 + 1], INFINITY);
    CHECK(sdf__find_lattice(p, 0, count, dims, axis) == 0 && !axis[0] && !axis[1] && !axis[2],
          "%s: a moved point is no lattice", file);
    CHECK(sdf__find_lattice(p, 0, count - 7, dims, axis) == 0, "%s: a cut lattice is none", file);
    free(p);
    sdf_mesh_release(mesh);
}

static void test_meshes(void)
{
    test_mesh("fandisk.off", SDF_SIGN_AUTO, 48);
    test_mesh("fandisk.off", SDF_SIGN_NONE, 32);
    test_mesh("knot1.off", SDF_SIGN_AUTO, 40);
    test_mesh("cow.off", SDF_SIGN_NONE, 36);           /* closed, self-intersecting */
}

/* Signs the scan does not give: the lattice goes the search path. */
static void test_search_path(void)
{
    test_mesh("cow.off", SDF_SIGN_AUTO, 24);           /* winding numbers */
    test_mesh("knot1.off", SDF_SIGN_RAYCAST, 20);
    test_mesh("mech-holes-shark.off", SDF_SIGN_NONE, 24); /* open */
}

static void test_slices(void)
{
    test_slices_in_calls("fandisk.off", SDF_SIGN_AUTO, 40);
    test_slices_in_calls("knot1.off", SDF_SIGN_NONE, 33);
}

static void test_sample_lattices(void)
{
    test_samples("fandisk.off", SDF_SIGN_AUTO, 1, 0.1, 28);
    test_samples("knot1.off", SDF_SIGN_AUTO, 2, 0.4, 20);
    test_samples("cow.off", SDF_SIGN_NONE, 1, 0.25, 22); /* self-intersecting: unsigned */
}

static void test_lattice_query_calls(void)
{
    test_lattice_queries("fandisk.off");
    test_lattice_queries("knot1.off");
}

static const check_case cases[] = {
    {"meshes", test_meshes},
    {"search_path", test_search_path},
    {"on_surface", test_on_surface},
    {"threads", test_threads},
    {"slices_in_calls", test_slices},
    {"samples", test_sample_lattices},
    {"lattice_queries", test_lattice_query_calls},
};

int main(int argc, char **argv)
{
    return check_main("scan", cases, CHECK_COUNT_OF(cases), argc, argv);
}
