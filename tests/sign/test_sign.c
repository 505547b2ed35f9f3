/* test_sign.c - signs against brute-force generalized winding numbers (Jacobson et al.
 * 2013: inside where the sum of solid angles / 4 pi exceeds 1/2).
 *  - closed meshes: pseudonormal, winding and raycast agree with the reference on 100 % of
 *    points farther than 1e-4 x diagonal from the surface;
 *  - open / defective meshes: winding agrees on >= 99.9 %;
 *  - the hierarchical winding number stays close to the brute-force value, and evaluated per
 *    packet it gives the same signed distances as per point;
 *  - auto picks pseudonormal for closed meshes that do not intersect themselves, winding
 *    otherwise (cow.off is closed once welded, but self-intersecting). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/reference.h"
#include "../common/workload.h"

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

int main(void)
{
    const char *closed[] = {"fandisk.off", "knot1.off"};
    const char *open[] = {"elephant-with-holes.off", "mech-holes-shark.off", "cow.off"};
    for (int i = 0; i < 2; i++) {
        sdf_mesh *m = load_data_mesh(closed[i]);
        if (m) {
            test_closed(closed[i], m);
            test_winding_values(closed[i], m);
        }
        sdf_mesh_release(m);
    }
    sdf_mesh *demo;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo");
    test_closed("demo", demo);
    sdf_mesh_release(demo);
    for (int i = 0; i < 3; i++) {
        sdf_mesh *m = load_data_mesh(open[i]);
        if (m) {
            test_open(open[i], m);
            test_winding_values(open[i], m);
        }
        sdf_mesh_release(m);
    }
    return check_finish("test_sign");
}
