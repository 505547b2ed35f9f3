/* test_sign.c - signs against brute-force generalized winding numbers (Jacobson et al.
 * 2013: inside where the sum of solid angles / 4 pi exceeds 1/2).
 *  - closed meshes: pseudonormal, winding and raycast agree with the reference on 100 % of
 *    points farther than 1e-4 x diagonal from the surface;
 *  - open / defective meshes: winding agrees on >= 99.9 %;
 *  - the hierarchical winding number stays close to the brute-force value, and evaluated per
 *    packet it gives the same signed distances as per point;
 *  - auto picks pseudonormal for closed meshes that do not intersect themselves, winding
 *    otherwise (cow.off is closed once welded, but self-intersecting);
 *  - the stored edge and vertex pseudonormals equal their definition, computed here the
 *    slow way (every mesh above);
 *  - down to the last float step every method agrees on closed meshes: the unit cube's faces
 *    one float step in and out (along the shared diagonals too), and points a few float steps
 *    off fandisk's every edge and vertex. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"
#include "mesh/mesh.h"
#include "mesh/topology.h"
#include "sign/pseudonormal.h"

#define N_BAND 1500
#define N_BOX 1500

typedef struct sample {
    float *p;
    size_t n;
    int *inside;    /* reference sign */
    double *w;      /* reference winding number */
    float *dist;    /* unsigned distance */
} sample;

static sample make_sample(const sdf_mesh *mesh)
{
    sample s = {0};
    s.p = malloc(3 * (N_BAND + N_BOX) * sizeof *s.p);
    size_t nb = N_BAND, nx = N_BOX;
    sdf_workload(mesh, "band", &nb, 21, s.p);
    sdf_workload(mesh, "box", &nx, 22, s.p + 3 * N_BAND);
    s.n = nb + nx;
    s.inside = malloc(s.n * sizeof *s.inside);
    s.w = malloc(s.n * sizeof *s.w);
    s.dist = malloc(s.n * sizeof *s.dist);
    for (size_t i = 0; i < s.n; i++) {
        s.w[i] = ref_winding(mesh, s.p + 3 * i);
        s.inside[i] = s.w[i] > 0.5;
    }
    sdf_query_options o = {.sign = SDF_SIGN_NONE};
    sdf_query_result r = {.distance = s.dist};
    sdf_query(mesh, s.p, s.n, &o, &r);
    return s;
}

static void free_sample(sample *s)
{
    free(s->p), free(s->inside), free(s->w), free(s->dist);
}

/* Fraction of points beyond `margin` from the surface whose sign matches the reference. */
static double agreement(const sdf_mesh *mesh, const sample *s, sdf_sign_method method,
                        double margin, size_t *first_bad)
{
    float *d = malloc(s->n * sizeof *d);
    sdf_query_options o = {.sign = method, .threads = 2};
    sdf_query_result r = {.distance = d};
    CHECK(sdf_query(mesh, s->p, s->n, &o, &r) == 0, "query");
    size_t agree = 0, counted = 0;
    *first_bad = SIZE_MAX;
    for (size_t i = 0; i < s->n; i++) {
        if (s->dist[i] <= margin)
            continue;
        counted++;
        if ((d[i] < 0) == s->inside[i])
            agree++;
        else if (*first_bad == SIZE_MAX)
            *first_bad = i;
    }
    free(d);
    return counted ? (double)agree / (double)counted : 0;
}

static void test_closed(const char *name, sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    CHECK(r.closed && !r.self_intersecting, "%s should be closed, not self-intersecting", name);
    CHECK(r.auto_sign == SDF_SIGN_PSEUDONORMAL, "%s: auto should be pseudonormal", name);
    sample s = make_sample(mesh);
    size_t insiders = 0;
    for (size_t i = 0; i < s.n; i++)
        insiders += s.inside[i];
    CHECK(insiders > s.n / 10, "%s: too few inside points (%zu) for a meaningful test", name, insiders);
    const sdf_sign_method methods[] = {SDF_SIGN_PSEUDONORMAL, SDF_SIGN_WINDING, SDF_SIGN_RAYCAST,
                                       SDF_SIGN_AUTO};
    for (int m = 0; m < 4; m++) {
        size_t bad;
        double a = agreement(mesh, &s, methods[m], 1e-4 * r.diagonal, &bad);
        CHECK(a == 1.0, "%s %s: %.4f%% agreement; first disagreement at (%g %g %g), w = %g", name,
              sdf_sign_name(methods[m]), 100 * a, bad < s.n ? s.p[3 * bad] : 0,
              bad < s.n ? s.p[3 * bad + 1] : 0, bad < s.n ? s.p[3 * bad + 2] : 0,
              bad < s.n ? s.w[bad] : 0);
        printf("%s %-12s agreement %.4f%%\n", name, sdf_sign_name(methods[m]), 100 * a);
    }
    free_sample(&s);
}

static void test_open(const char *name, sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    CHECK(!r.closed || r.self_intersecting, "%s should be open or self-intersecting", name);
    CHECK(r.auto_sign == SDF_SIGN_WINDING, "%s: auto should be winding", name);
    sample s = make_sample(mesh);
    size_t bad;
    double a = agreement(mesh, &s, SDF_SIGN_WINDING, 1e-4 * r.diagonal, &bad);
    CHECK(a >= 0.999, "%s winding: %.4f%% agreement", name, 100 * a);
    double a_auto = agreement(mesh, &s, SDF_SIGN_AUTO, 1e-4 * r.diagonal, &bad);
    CHECK(a_auto == a, "%s: auto differs from winding", name);
    printf("%s winding agreement %.4f%%\n", name, 100 * a);
    /* Winding numbers per packet (packet traversal) and per point (single traversal) are the
     * same numbers, so the signed distances agree bit for bit. */
    float *d[2];
    for (int v = 0; v < 2; v++) {
        d[v] = malloc(s.n * sizeof *d[v]);
        sdf_query_options o = {.sign = SDF_SIGN_WINDING, .threads = 2,
                               .traversal = v ? SDF_TRAVERSAL_SINGLE : SDF_TRAVERSAL_PACKETS};
        sdf_query_result res = {.distance = d[v]};
        CHECK(sdf_query(mesh, s.p, s.n, &o, &res) == 0, "query");
    }
    size_t differ = 0;
    for (size_t i = 0; i < s.n; i++)
        differ += memcmp(&d[0][i], &d[1][i], sizeof(float)) != 0;
    CHECK(differ == 0, "%s: winding signs per packet and per point differ on %zu points", name,
          differ);
    free(d[0]), free(d[1]);
    free_sample(&s);
}

/* The hierarchical value tracks the brute-force one everywhere (not just its sign). */
static void test_winding_values(const char *name, sdf_mesh *mesh)
{
    sample s = make_sample(mesh);
    float *w = malloc(s.n * sizeof *w);
    size_t bad;
    CHECK(sdf_winding_numbers(mesh, s.p, s.n, NULL, w, &bad) == 0, "winding numbers");
    double worst = 0;
    for (size_t i = 0; i < s.n; i++)
        worst = fmax(worst, fabs(w[i] - s.w[i]));
    CHECK(worst < 0.05, "%s: fast winding number off by %g", name, worst);
    /* Per packet (the default) and per point: the same numbers, bit for bit. */
    float *single = malloc(s.n * sizeof *single);
    sdf_query_options o = {.traversal = SDF_TRAVERSAL_SINGLE};
    CHECK(sdf_winding_numbers(mesh, s.p, s.n, &o, single, &bad) == 0, "winding numbers");
    size_t differ = 0;
    for (size_t i = 0; i < s.n; i++)
        differ += memcmp(&w[i], &single[i], sizeof *w) != 0;
    CHECK(differ == 0, "%s: winding numbers per packet and per point differ on %zu points", name,
          differ);
    free(single);
    printf("%s fast winding number max error %.2e\n", name, worst);
    free(w);
    free_sample(&s);
}

typedef struct edge_use {
    uint32_t lo, hi, tri;
} edge_use;

static int by_vertices(const void *a, const void *b)
{
    const edge_use *x = a, *y = b;
    if (x->lo != y->lo)
        return x->lo < y->lo ? -1 : 1;
    return x->hi < y->hi ? -1 : x->hi > y->hi;
}

static void unit(double v[3])
{
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; len > 0 && i < 3; i++)
        v[i] /= len;
}

/* Baerentzen & Aanaes's pseudonormals from their definition: a triangle's unit normal and
 * its corner angles (acos of unit edge vectors; the library uses atan2); an edge's is the
 * sum of the normals of the triangles that use it (found by sorting every triangle's
 * (lower, upper) vertex pairs), a vertex's the sum of angle times normal over its triangles.
 * The library's float unit vectors must agree to 1e-5. */
static void test_pseudonormal_values(const char *name, const sdf_mesh *m)
{
    size_t nt = m->report.triangles, nv = m->report.vertices;
    double *normal = calloc(3 * nt, sizeof *normal), *angle = calloc(3 * nt, sizeof *angle);
    double *vertex = calloc(3 * nv, sizeof *vertex), *edge_sum = calloc(9 * nt, sizeof *edge_sum);
    edge_use *uses = malloc(3 * nt * sizeof *uses);
    size_t *use_of = malloc(3 * nt * sizeof *use_of); /* corner 3t + k -> its group's first use */
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *tri = m->triangles + 3 * t;
        double p[3][3], u[3], v[3];
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                p[k][a] = m->positions[3 * (size_t)tri[k] + a];
        for (int a = 0; a < 3; a++)
            u[a] = p[1][a] - p[0][a], v[a] = p[2][a] - p[0][a];
        double *n = normal + 3 * t;
        n[0] = u[1] * v[2] - u[2] * v[1], n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        unit(n);
        for (int k = 0; k < 3; k++) {
            double e1[3], e2[3];
            for (int a = 0; a < 3; a++)
                e1[a] = p[(k + 1) % 3][a] - p[k][a], e2[a] = p[(k + 2) % 3][a] - p[k][a];
            unit(e1), unit(e2);
            double c = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
            angle[3 * t + k] = acos(fmax(-1, fmin(1, c)));
            for (int a = 0; a < 3; a++)
                vertex[3 * (size_t)tri[k] + a] += angle[3 * t + k] * n[a];
            uint32_t x = tri[k], y = tri[(k + 1) % 3];
            uses[3 * t + k] = (edge_use){x < y ? x : y, x < y ? y : x, (uint32_t)(3 * t + k)};
        }
    }
    qsort(uses, 3 * nt, sizeof *uses, by_vertices);
    for (size_t i = 0, j; i < 3 * nt; i = j) {
        for (j = i; j < 3 * nt && !by_vertices(&uses[i], &uses[j]); j++) {
            use_of[uses[j].tri] = i;
            for (int a = 0; a < 3; a++)
                edge_sum[3 * i + a] += normal[3 * (uses[j].tri / 3) + a];
        }
    }
    double worst_edge = 0, worst_vertex = 0;
    size_t edges = 0;
    for (size_t c = 0; c < 3 * nt; c++) {
        uint32_t e = m->edge_of[c];
        const uint32_t *tri = m->triangles + 3 * (c / 3);
        if (e == SDF__NO_EDGE || tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0])
            continue;
        double ref[3] = {edge_sum[3 * use_of[c]], edge_sum[3 * use_of[c] + 1],
                         edge_sum[3 * use_of[c] + 2]};
        unit(ref);
        for (int a = 0; a < 3; a++)
            worst_edge = fmax(worst_edge, fabs(ref[a] - m->normals->edge[3 * (size_t)e + a]));
        edges++;
    }
    for (size_t v = 0; v < nv; v++) {
        unit(vertex + 3 * v);
        for (int a = 0; a < 3; a++)
            worst_vertex =
                fmax(worst_vertex, fabs(vertex[3 * v + a] - m->normals->vertex[3 * v + a]));
    }
    CHECK(edges > 0 && worst_edge <= 1e-5 && worst_vertex <= 1e-5,
          "%s: pseudonormals %g (edges, %zu checked) and %g (vertices) from their definition", name,
          worst_edge, edges, worst_vertex);
    printf("pseudonormals %s: edges within %.2g, vertices within %.2g of the definition\n", name,
           worst_edge, worst_vertex);
    free(normal), free(angle), free(vertex), free(edge_sum), free(uses), free(use_of);
}

static void test_closed_file(const char *file)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    test_closed(file, m);
    test_winding_values(file, m);
    test_pseudonormal_values(file, m);
    sdf_mesh_release(m);
}

static void test_open_file(const char *file)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    test_open(file, m);
    test_winding_values(file, m);
    test_pseudonormal_values(file, m);
    sdf_mesh_release(m);
}

static void test_fandisk(void) { test_closed_file("fandisk.off"); }
static void test_knot1(void) { test_closed_file("knot1.off"); }
static void test_elephant(void) { test_open_file("elephant-with-holes.off"); }
static void test_shark(void) { test_open_file("mech-holes-shark.off"); }
static void test_cow(void) { test_open_file("cow.off"); }

static void test_demo(void)
{
    sdf_mesh *demo;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo");
    test_closed("demo", demo);
    sdf_mesh_release(demo);
}

/* ---- one float step from the surface ------------------------------------------------- */

static const sdf_sign_method METHODS[] = {SDF_SIGN_AUTO, SDF_SIGN_PSEUDONORMAL, SDF_SIGN_WINDING,
                                         SDF_SIGN_RAYCAST};
#define N_METHODS (sizeof METHODS / sizeof METHODS[0])

/* Signed distances of the n points by each method, into d[method][n]. */
static void by_method(const sdf_mesh *m, const float *p, size_t n, float *d[N_METHODS])
{
    for (size_t k = 0; k < N_METHODS; k++) {
        sdf_query_options o = {.sign = METHODS[k], .threads = 2};
        sdf_query_result r = {.distance = d[k]};
        CHECK(sdf_query(m, p, n, &o, &r) == 0, "query");
    }
}

/* The unit cube centred at the origin, each face split along a diagonal: points one float
 * step inside and outside each face along both its diagonals (one of them the triangles'
 * shared edge) are inside and outside by every method, and a point on a face answers 0. */
static void test_cube_last_step(void)
{
    float v[8][3];
    for (int i = 0; i < 8; i++)
        for (int a = 0; a < 3; a++)
            v[i][a] = (i >> a) & 1 ? 0.5f : -0.5f;
    static const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    uint32_t t[12][3];
    for (int f = 0; f < 6; f++) {
        const uint32_t *q = quads[f];
        memcpy(t[2 * f], (uint32_t[3]){q[0], q[1], q[2]}, sizeof t[0]);
        memcpy(t[2 * f + 1], (uint32_t[3]){q[0], q[2], q[3]}, sizeof t[0]);
    }
    sdf_mesh *m;
    CHECK(sdf_mesh_create(&v[0][0], 8, &t[0][0], 12, NULL, &m, NULL) == 0, "cube");
    enum { ALONG = 19, N = 6 * 2 * ALONG * 3 };
    float *p = malloc(3 * N * sizeof *p), *d[N_METHODS];
    int *want = malloc(N * sizeof *want);
    size_t n = 0;
    for (int axis = 0; axis < 3; axis++)
        for (int side = -1; side <= 1; side += 2)
            for (int diag = 0; diag < 2; diag++)
                for (int i = 1; i <= ALONG; i++)
                    for (int step = -1; step <= 1; step++, n++) {
                        float a = -0.5f + (float)i / (ALONG + 1), face = 0.5f * (float)side;
                        int u = (axis + 1) % 3, w = (axis + 2) % 3;
                        p[3 * n + u] = a, p[3 * n + w] = diag ? -a : a;
                        /* step -1: one float toward the centre, +1: away, 0: on the face */
                        p[3 * n + axis] = step ? nextafterf(face, step * side * 1.0f) : face;
                        want[n] = step;
                    }
    for (size_t k = 0; k < N_METHODS; k++)
        d[k] = malloc(N * sizeof(float));
    by_method(m, p, N, d);
    size_t wrong[N_METHODS] = {0};
    for (size_t k = 0; k < N_METHODS; k++)
        for (size_t i = 0; i < N; i++)
            wrong[k] += !(want[i] < 0 ? d[k][i] < 0 : want[i] > 0 ? d[k][i] > 0 : d[k][i] == 0);
    for (size_t k = 0; k < N_METHODS; k++)
        CHECK(wrong[k] == 0, "cube, %s: %zu of %d points one float step from a face get the "
              "wrong sign", sdf_sign_name(METHODS[k]), wrong[k], N);
    for (size_t k = 0; k < N_METHODS; k++)
        free(d[k]);
    free(p), free(want);
    sdf_mesh_release(m);
}

/* A closed mesh's edges and vertices: points a few float steps off each edge's midpoint and
 * each vertex, along each adjacent face's normal, in and out, get one sign from every method
 * (the pseudonormal's, exact there); the points that rounding puts on a face answer 0 up to
 * 1e-12 of the diagonal by every method. */
static void test_near_features(void)
{
    sdf_mesh *m = load_data_mesh("fandisk.off");
    if (!m)
        return;
    size_t nt = m->report.triangles, n = 0, cap = 3 * 2 * 2 * 3 * nt;
    float *p = malloc(3 * cap * sizeof *p), *d[N_METHODS];
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *tri = m->triangles + 3 * t;
        const float *a = m->positions + 3 * tri[0], *b = m->positions + 3 * tri[1],
                    *c = m->positions + 3 * tri[2];
        double e1[3], e2[3], nrm[3];
        for (int i = 0; i < 3; i++)
            e1[i] = b[i] - a[i], e2[i] = c[i] - a[i];
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1], nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        if (!(len > 0))
            continue;
        for (int corner = 0; corner < 3; corner++) {
            const float *x = m->positions + 3 * tri[corner],
                        *y = m->positions + 3 * tri[(corner + 1) % 3];
            for (int at = 0; at < 2; at++)         /* the vertex, then the edge's midpoint */
                for (int dir = -1; dir <= 1; dir += 2) /* inward, outward */
                    /* 1 and 32 steps: within the rays' fallback (points.c); 1024: past it */
                    for (int ulps = 1; ulps <= 1024; ulps *= 32, n++)
                        for (int i = 0; i < 3; i++) {
                            float q = at ? 0.5f * (x[i] + y[i]) : x[i];
                            float step = ulps * (nextafterf(fabsf(q) + 1e-30f, INFINITY) -
                                                 fabsf(q));
                            p[3 * n + i] = q + (float)(dir * step * 4 * nrm[i] / len);
                        }
        }
    }
    for (size_t k = 0; k < N_METHODS; k++)
        d[k] = malloc(n * sizeof(float));
    by_method(m, p, n, d);
    float on_face = (float)(1e-12 * m->report.diagonal);
    size_t disagree[N_METHODS] = {0};
    for (size_t k = 0; k < N_METHODS; k++)
        for (size_t i = 0; i < n; i++)
            /* rounding put some points on a face: those answer 0 up to rounding */
            disagree[k] += fabsf(d[1][i]) > on_face ? (d[k][i] < 0) != (d[1][i] < 0)
                                                    : !(fabsf(d[k][i]) <= on_face);
    for (size_t k = 0; k < N_METHODS; k++)
        CHECK(disagree[k] == 0, "fandisk, %s: %zu of %zu points a few float steps from an edge "
              "or vertex disagree with the pseudonormal's sign", sdf_sign_name(METHODS[k]),
              disagree[k], n);
    /* The pseudonormal's sign itself, on every 97th point, against the exact solid angles. */
    size_t checked = 0, wrong = 0;
    for (size_t i = 0; i < n; i += 97)
        if (fabsf(d[1][i]) > on_face)
            checked++, wrong += (ref_winding(m, p + 3 * i) > 0.5) != (d[1][i] < 0);
    CHECK(checked > 1000 && wrong == 0, "fandisk: the pseudonormal's sign is not the exact "
          "winding number's on %zu of %zu points", wrong, checked);
    for (size_t k = 0; k < N_METHODS; k++)
        free(d[k]);
    free(p);
    sdf_mesh_release(m);
}

static const check_case cases[] = {
    {"cube_last_step", test_cube_last_step},
    {"near_features", test_near_features},
    {"fandisk", test_fandisk},
    {"knot1", test_knot1},
    {"demo", test_demo},
    {"elephant", test_elephant},
    {"shark", test_shark},
    {"cow", test_cow},
};

int main(int argc, char **argv)
{
    return check_main("sign", cases, CHECK_COUNT_OF(cases), argc, argv);
}
