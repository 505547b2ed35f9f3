/* test_distance.c - differential test of distance, closest point, triangle id and
 * barycentric coordinates against the brute-force double-precision reference, on real
 * meshes and near-surface, uniform-box and far points, for both traversals (packets, whose
 * spread-out points go one at a time through our own BVH, and Embree's one query at a time),
 * which must also agree with each other bit for bit, and with the exact-only walk that
 * answers the points the float searches hand back (sdf__closest_exact). Tolerance:
 * 1e-5 x the bbox diagonal. At a vertex that walk names the lowest-numbered of the tied
 * triangles (the searches' tie rule).
 * Also: results are identical for 1 and 2 threads, for a strided point layout, and for
 * several caller threads sharing one mesh; a NaN point is reported by index before any
 * output is written. A cone whose apex touches 48 triangles exercises the packets' path for
 * more near-equal candidates than a lane holds. Embree's scene, committed on first use, is
 * first asked for by several threads at once. */
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"
#include "mesh/mesh.h"
#include "points/packet.h"

static double dist3(const double a[3], const float b[3])
{
    double d2 = 0;
    for (int i = 0; i < 3; i++)
        d2 += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(d2);
}

/* Every output for one point agrees with the reference: the distance, the closest point
 * being that far from p and lying on the reported triangle, and the barycentric weights
 * reproducing it. (Ties may pick another triangle, so the point is not compared directly.) */
static void check_point(const sdf_mesh *mesh, const float *p, float d, const float *c,
                        uint32_t tri, const float *w, double tol, const char *what)
{
    ref_hit ref;
    ref_closest(mesh, p, &ref);
    const float *v = sdf_mesh_vertices(mesh);
    const uint32_t *t = sdf_mesh_triangles(mesh);
    double pd[3] = {p[0], p[1], p[2]}, corner[3][3], on[3], cd[3] = {c[0], c[1], c[2]};
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            corner[k][i] = v[3 * t[3 * tri + k] + i];
    double err_d = fabs(d - ref.dist);
    double err_c = fabs(dist3(pd, c) - ref.dist);
    double off_tri = ref_point_triangle(cd, corner[0], corner[1], corner[2], on);
    double err_w = 0, wsum = w[0] + w[1] + w[2];
    for (int i = 0; i < 3; i++) {
        double x = w[0] * corner[0][i] + w[1] * corner[1][i] + w[2] * corner[2][i];
        err_w = fmax(err_w, fabs(x - c[i]));
    }
    CHECK(err_d <= tol, "%s: distance %.9g vs reference %.9g", what, d, ref.dist);
    CHECK(err_c <= tol, "%s: closest point is %.9g away, reference distance %.9g", what,
          dist3(pd, c), ref.dist);
    CHECK(off_tri <= tol, "%s: closest point lies %.3g off its triangle %u", what, off_tri, tri);
    CHECK(err_w <= tol && fabs(wsum - 1) < 1e-5 && w[0] >= -1e-6 && w[1] >= -1e-6 && w[2] >= -1e-6,
          "%s: barycentric (%g %g %g) do not reproduce the closest point (err %g)", what, w[0],
          w[1], w[2], err_w);
}

static void test_mesh(const char *name, sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const double tol = 1e-5 * r.diagonal;
    const char *kinds[] = {"band", "box", "far"};
    const size_t counts[] = {1200, 1200, 300};
    for (int k = 0; k < 3; k++) {
        size_t n = counts[k];
        float *p = malloc(3 * n * sizeof *p), *d = malloc(n * sizeof *d);
        float *c = malloc(3 * n * sizeof *c), *w = malloc(3 * n * sizeof *w);
        uint32_t *t = malloc(n * sizeof *t);
        CHECK(sdf_workload(mesh, kinds[k], &n, 11 + (uint64_t)k, p) == 0, "workload");
        float *single = malloc(n * sizeof *single);
        /* Both traversals against the reference, and against each other bit for bit. */
        const sdf_traversal traversals[] = {SDF_TRAVERSAL_PACKETS, SDF_TRAVERSAL_SINGLE};
        for (int v = 0; v < 2; v++) {
            sdf_query_options o = {.sign = SDF_SIGN_NONE, .threads = 2, .traversal = traversals[v]};
            sdf_query_result res = {.distance = d, .closest = c, .triangle = t, .barycentric = w};
            CHECK(sdf_query(mesh, p, n, &o, &res) == 0, "query");
            int before = check_failures;
            char what[96];
            for (size_t i = 0; i < n && check_failures - before < 5; i++) {
                snprintf(what, sizeof what, "%s %s %s point %zu", name, kinds[k],
                         v ? "single" : "packets", i);
                check_point(mesh, p + 3 * i, d[i], c + 3 * i, t[i], w + 3 * i, tol, what);
            }
            if (v == 0)
                memcpy(single, d, n * sizeof *d);
        }
        size_t differ = 0, exact_differ = 0;
        for (size_t i = 0; i < n; i++) {
            differ += memcmp(&single[i], &d[i], sizeof *d) != 0;
            sdf__hit hit;
            sdf__closest_exact(&mesh->tree, mesh->positions, mesh->triangles, p + 3 * i, &hit);
            float exact = (float)sqrt(hit.dist2);
            exact_differ += memcmp(&exact, &single[i], sizeof exact) != 0;
        }
        CHECK(differ == 0, "%s %s: packets and single traversal differ on %zu points", name,
              kinds[k], differ);
        CHECK(exact_differ == 0, "%s %s: the exact-only walk differs from packets on %zu points",
              name, kinds[k], exact_differ);
        free(p), free(d), free(c), free(w), free(t), free(single);
    }
}

/* At a vertex every incident triangle is at distance 0: the exact-only walk names the
 * lowest-numbered of them (ties go to the lower id, as in every search). */
static void test_exact_ties(const char *name, const sdf_mesh *mesh)
{
    size_t vertices = mesh->report.vertices, tris = mesh->report.triangles;
    size_t step = vertices / 200 + 1, wrong = 0, tested = 0;
    for (size_t v = 0; v < vertices; v += step) {
        uint32_t lowest = UINT32_MAX;
        for (size_t t = 0; t < 3 * tris && lowest == UINT32_MAX; t++)
            if (mesh->triangles[t] == v)
                lowest = (uint32_t)(t / 3);
        if (lowest == UINT32_MAX)
            continue; /* a vertex no triangle uses */
        sdf__hit hit;
        sdf__closest_exact(&mesh->tree, mesh->positions, mesh->triangles,
                           mesh->positions + 3 * v, &hit);
        wrong += hit.dist2 != 0 || hit.triangle != lowest;
        tested++;
    }
    CHECK(tested > 0 && wrong == 0, "%s: %zu of %zu vertices not named by their lowest triangle",
          name, wrong, tested);
}

/* A closed cone of 48 slices: its apex and base centre each touch 48 triangles, more
 * near-equal candidates than a packet lane holds, so points above the apex and below the
 * base centre take the packet's overflow path (asked again one at a time). */
static sdf_mesh *make_cone(void)
{
    enum { SLICES = 48 };
    float v[3 * (SLICES + 2)];
    uint32_t t[3 * 2 * SLICES];
    for (int i = 0; i < SLICES; i++) {
        double a = 2 * M_PI * i / SLICES;
        v[3 * i] = (float)cos(a), v[3 * i + 1] = (float)sin(a), v[3 * i + 2] = 0;
    }
    v[3 * SLICES] = 0, v[3 * SLICES + 1] = 0, v[3 * SLICES + 2] = 1.5f;            /* apex */
    v[3 * SLICES + 3] = 0, v[3 * SLICES + 4] = 0, v[3 * SLICES + 5] = 0;            /* base */
    for (uint32_t i = 0; i < SLICES; i++) {
        uint32_t j = (i + 1) % SLICES;
        uint32_t *side = t + 6 * i, *base = side + 3;
        side[0] = i, side[1] = j, side[2] = SLICES;
        base[0] = j, base[1] = i, base[2] = SLICES + 1;
    }
    sdf_mesh *mesh = NULL;
    CHECK(sdf_mesh_create(v, SLICES + 2, t, 2 * SLICES, NULL, &mesh, NULL) == 0, "cone");
    return mesh;
}

static void test_many_ties(void)
{
    sdf_mesh *cone = make_cone();
    if (!cone)
        return;
    test_mesh("cone", cone);
    /* A column of points over the apex and under the base centre, packed into packets. */
    enum { N = 2000 };
    float *p = malloc(3 * N * sizeof *p), *d = malloc(N * sizeof *d);
    float *c = malloc(3 * N * sizeof *c), *w = malloc(3 * N * sizeof *w);
    uint32_t *t = malloc(N * sizeof *t);
    for (int i = 0; i < N; i++) {
        double h = 0.001 + 0.5 * i / N;
        p[3 * i] = 0, p[3 * i + 1] = 0, p[3 * i + 2] = (float)(i % 2 ? 1.5 + h : -h);
    }
    const sdf_traversal traversals[] = {SDF_TRAVERSAL_PACKETS, SDF_TRAVERSAL_SINGLE};
    for (int v = 0; v < 2; v++) {
        sdf_query_options o = {.sign = SDF_SIGN_NONE, .threads = 2, .traversal = traversals[v]};
        sdf_query_result res = {.distance = d, .closest = c, .triangle = t, .barycentric = w};
        CHECK(sdf_query(cone, p, N, &o, &res) == 0, "cone query");
        int before = check_failures;
        for (int i = 0; i < N && check_failures - before < 5; i++)
            check_point(cone, p + 3 * i, d[i], c + 3 * i, t[i], w + 3 * i, 1e-6,
                        v ? "cone apex single" : "cone apex packets");
    }
    free(p), free(d), free(c), free(w), free(t);
    sdf_mesh_release(cone);
}

/* Same answers, bit for bit, whatever the thread count and point layout. */
static void test_threads_and_stride(sdf_mesh *mesh)
{
    size_t n = 5000;
    float *p = malloc(3 * n * sizeof *p), *strided = malloc(4 * n * sizeof *strided);
    float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *s = malloc(n * sizeof *s);
    sdf_workload(mesh, "box", &n, 5, p);
    for (size_t i = 0; i < n; i++) {
        memcpy(strided + 4 * i, p + 3 * i, 3 * sizeof(float));
        strided[4 * i + 3] = NAN; /* padding must never be read */
    }
    sdf_query_options one = {.threads = 1}, two = {.threads = 2},
                      stride = {.threads = 2, .point_stride = 16};
    sdf_query_result ra = {.distance = a}, rb = {.distance = b}, rs = {.distance = s};
    CHECK(sdf_query(mesh, p, n, &one, &ra) == 0, "1 thread");
    CHECK(sdf_query(mesh, p, n, &two, &rb) == 0, "2 threads");
    CHECK(sdf_query(mesh, strided, n, &stride, &rs) == 0, "strided");
    CHECK(!memcmp(a, b, n * sizeof *a), "1 and 2 threads differ");
    CHECK(!memcmp(a, s, n * sizeof *a), "strided layout differs");
    free(p), free(strided), free(a), free(b), free(s);
}

/* Several caller threads query one shared mesh at once, each with all sign methods and
 * outputs; every answer must equal the single-threaded one bit for bit. */
typedef struct concurrent_job {
    sdf_mesh *mesh;
    const float *points;
    size_t n;
    float *distance; /* 4 sign methods x n */
} concurrent_job;

static void run_all_signs(sdf_mesh *mesh, const float *p, size_t n, float *out)
{
    const sdf_sign_method signs[] = {SDF_SIGN_PSEUDONORMAL, SDF_SIGN_WINDING, SDF_SIGN_RAYCAST,
                                     SDF_SIGN_NONE};
    for (int s = 0; s < 4; s++) {
        sdf_query_options o = {.sign = signs[s], .threads = 1};
        sdf_query_result r = {.distance = out + s * n};
        CHECK(sdf_query(mesh, p, n, &o, &r) == 0, "query with sign %d", (int)signs[s]);
    }
}

static void *concurrent_worker(void *arg)
{
    concurrent_job *j = arg;
    sdf_mesh *mine = sdf_mesh_retain(j->mesh);
    run_all_signs(mine, j->points, j->n, j->distance);
    sdf_mesh_release(mine);
    return NULL;
}

/* `mesh` fresh: the callers race to its first raycast (Embree's scene, built on first use);
 * the answers they get are compared with one caller's afterwards. */
static void test_concurrent_callers(sdf_mesh *mesh)
{
    enum { THREADS = 4 };
    size_t n = 2000;
    float *p = malloc(3 * n * sizeof *p), *expect = malloc(4 * n * sizeof *expect);
    sdf_workload(mesh, "band", &n, 9, p);
    pthread_t tid[THREADS];
    concurrent_job jobs[THREADS];
    for (int i = 0; i < THREADS; i++) {
        jobs[i] = (concurrent_job){mesh, p, n, malloc(4 * n * sizeof(float))};
        CHECK(pthread_create(&tid[i], NULL, concurrent_worker, &jobs[i]) == 0, "thread");
    }
    for (int i = 0; i < THREADS; i++)
        pthread_join(tid[i], NULL);
    run_all_signs(mesh, p, n, expect);
    for (int i = 0; i < THREADS; i++) {
        CHECK(!memcmp(jobs[i].distance, expect, 4 * n * sizeof(float)),
              "caller thread %d got different answers", i);
        free(jobs[i].distance);
    }
    free(p), free(expect);
}

static void test_bad_points(sdf_mesh *mesh)
{
    float p[12] = {0, 0, 0, 1, 1, 1, 2, NAN, 2, INFINITY, 0, 0};
    float d[4] = {7, 7, 7, 7};
    sdf_query_result res = {.distance = d};
    CHECK(sdf_query(mesh, p, 4, NULL, &res) == SDF_ENONFINITE, "NaN accepted");
    CHECK(res.bad_index == 2, "bad index %zu, expected 2", res.bad_index);
    CHECK(d[0] == 7 && d[1] == 7, "output written before the batch was checked");
    float w[4];
    size_t bad = 0;
    CHECK(sdf_winding_numbers(mesh, p, 4, NULL, w, &bad) == SDF_ENONFINITE && bad == 2,
          "winding: NaN not reported at 2 (%zu)", bad);
    sdf_query_options o = {.sign = (sdf_sign_method)42};
    CHECK(sdf_query(mesh, p, 1, &o, &res) == SDF_EINVAL, "bad sign method accepted");
    o = (sdf_query_options){.traversal = (sdf_traversal)9};
    CHECK(sdf_query(mesh, p, 1, &o, &res) == SDF_EINVAL, "bad traversal accepted");
    o = (sdf_query_options){.point_stride = 8};
    CHECK(sdf_query(mesh, p, 1, &o, &res) == SDF_EINVAL, "stride below 12 accepted");
    CHECK(sdf_query(NULL, p, 1, NULL, &res) == SDF_EINVAL, "NULL mesh accepted");
    CHECK(sdf_query(mesh, NULL, 0, NULL, &res) == 0, "empty batch refused");
}

/* Points up to SDF_MAX_COORDINATE away from a closed mesh ~3 units across: every path and
 * sign method says outside (at ~1e16 double precision cannot tell the mesh's features apart,
 * and before the box rule the pseudonormal of whichever one won said "inside" half the
 * time), with the distance |p - c| to float rounding; beyond it, points are refused (Embree
 * aborts on rays from there), also in every sign method. */
static void test_far_points(sdf_mesh *mesh)
{
    const float far[] = {1e6f, 1e12f, 1e15f, 1e16f, 1e17f, 1e18f};
    for (size_t k = 0; k < sizeof far / sizeof *far; k++) {
        float m = far[k];
        float p[15] = {m, 0, 0, -m, 0.5f, 0, 0, m, 0, 0.3f * m, -m, 0.7f * m, 0, 0, -m};
        for (int sign = SDF_SIGN_AUTO; sign <= SDF_SIGN_RAYCAST; sign++)
            for (int t = SDF_TRAVERSAL_PACKETS; t <= SDF_TRAVERSAL_SINGLE; t++) {
                float d[5];
                sdf_query_result res = {.distance = d};
                sdf_query_options o = {.sign = (sdf_sign_method)sign,
                                       .traversal = (sdf_traversal)t};
                CHECK(sdf_query(mesh, p, 5, &o, &res) == 0, "far points refused at %g", m);
                for (int i = 0; i < 5; i++) {
                    const float *q = p + 3 * i;
                    double r = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] +
                                    (double)q[2] * q[2]);
                    CHECK(d[i] > 0 && fabs(d[i] - r) <= 4 + 1e-6 * r,
                          "%g away, sign %d, traversal %d, point %d: %g", m, sign, t, i, d[i]);
                }
            }
    }
    float beyond[9] = {0, 0, 0, 1, 2, 3, 0, -1.5e18f, 0};
    for (int sign = SDF_SIGN_AUTO; sign <= SDF_SIGN_NONE; sign++) {
        float d[3];
        sdf_query_result res = {.distance = d};
        sdf_query_options o = {.sign = (sdf_sign_method)sign};
        CHECK(sdf_query(mesh, beyond, 3, &o, &res) == SDF_ENONFINITE && res.bad_index == 2,
              "a point beyond 1e18 accepted by sign method %d", sign);
    }
}

/* Each data mesh: the workloads against brute force, and exact ties. */
static void test_file(const char *file)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    test_mesh(file, mesh);
    test_exact_ties(file, mesh);
    sdf_mesh_release(mesh);
}

#define FILE_CASE(fn, file)                                                                \
    static void fn(void) { test_file(file); }
FILE_CASE(test_fandisk, "fandisk.off")
FILE_CASE(test_knot1, "knot1.off")
FILE_CASE(test_cow, "cow.off")
FILE_CASE(test_elephant, "elephant-with-holes.off")
FILE_CASE(test_shark, "mech-holes-shark.off")
FILE_CASE(test_spider_stl, "Spider_binary.stl")
FILE_CASE(test_spider_obj, "spider.obj")

/* The demo mesh: the workloads, threads and strides, bad and far points. */
static void test_demo(void)
{
    sdf_mesh *demo;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo");
    test_mesh("demo", demo);
    test_threads_and_stride(demo);
    test_bad_points(demo);
    test_far_points(demo);
    sdf_mesh_release(demo);
}

static void test_concurrent(void)
{
    sdf_mesh *demo;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo");
    test_concurrent_callers(demo);
    sdf_mesh_release(demo);
}

/* The `normal` output: the unit normal of the triangle the query names, computed here from
 * the mesh's arrays; the same with and without the triangle ids asked for; on a box, the
 * faces' outward axes. */
static void check_normals(const char *file)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    size_t n = 20000;
    float *p = malloc(3 * n * sizeof *p), *nrm = malloc(3 * n * sizeof *nrm),
          *alone = malloc(3 * n * sizeof *alone);
    uint32_t *tri = malloc(n * sizeof *tri);
    CHECK(sdf_workload(m, "box", &n, 31, p) == 0, "workload");
    sdf_query_options o = {.threads = 2};
    sdf_query_result r = {.triangle = tri, .normal = nrm}, only = {.normal = alone};
    CHECK(sdf_query(m, p, n, &o, &r) == 0 && sdf_query(m, p, n, &o, &only) == 0, "query");
    size_t wrong = 0;
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = m->triangles + 3 * (size_t)tri[i];
        const float *a = m->positions + 3 * t[0], *b = m->positions + 3 * t[1],
                    *c = m->positions + 3 * t[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
               v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double w[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
        double len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), err = 0;
        for (int k = 0; k < 3; k++)
            err = fmax(err, fabs(nrm[3 * i + k] - (len > 0 ? w[k] / len : 0)));
        wrong += err > 1e-6;
    }
    CHECK(wrong == 0, "%s: %zu of %zu normals differ from their triangle's", file, wrong, n);
    CHECK(!memcmp(nrm, alone, 3 * n * sizeof *nrm), "%s: normals differ without the triangle ids",
          file);
    free(p), free(nrm), free(alone), free(tri);
    sdf_mesh_release(m);
}

static void test_normals(void)
{
    check_normals("fandisk.off");
    check_normals("elephant-with-holes.off");
    sdf_mesh *cube = load_data_mesh("cube.ply"); /* the unit cube [0, 1]^3 */
    if (!cube)
        return;
    const float p[6][3] = {{0.5f, 0.5f, 1.5f}, {0.5f, 0.5f, -0.5f}, {1.3f, 0.4f, 0.6f},
                           {-0.2f, 0.4f, 0.6f}, {0.4f, 1.2f, 0.3f}, {0.4f, -0.3f, 0.3f}};
    float nrm[18];
    sdf_query_result r = {.normal = nrm};
    CHECK(sdf_query(cube, &p[0][0], 6, NULL, &r) == 0, "cube");
    for (int i = 0; i < 6; i++) {
        static const int axis_of[6] = {2, 2, 0, 0, 1, 1}; /* the face each point is over */
        int axis = axis_of[i];
        float want = i % 2 ? -1.0f : 1.0f;
        for (int k = 0; k < 3; k++)
            CHECK(nrm[3 * i + k] == (k == axis ? want : 0.0f), "cube face %d: normal %g %g %g",
                  i, nrm[3 * i], nrm[3 * i + 1], nrm[3 * i + 2]);
    }
    sdf_filter_options f = {0};
    CHECK(sdf_query_filtered(cube, &p[0][0], 6, NULL, &f, &r, NULL) == SDF_EINVAL,
          "the filtered field has no normal output");
    sdf_mesh_release(cube);
}

static const check_case cases[] = {
    {"normals", test_normals},
    {"fandisk", test_fandisk},
    {"knot1", test_knot1},
    {"cow", test_cow},
    {"elephant", test_elephant},
    {"shark", test_shark},
    {"spider_stl", test_spider_stl},
    {"spider_obj", test_spider_obj},
    {"demo", test_demo},
    {"many_ties", test_many_ties},
    {"concurrent_callers", test_concurrent},
};

int main(int argc, char **argv)
{
    return check_main("distance", cases, CHECK_COUNT_OF(cases), argc, argv);
}
