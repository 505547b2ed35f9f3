/* test_gradient.c - the gradient against central differences of the signed distance
 * (step h = 1e-4 x diagonal, at points at least 50 h from the surface, so the field's own
 * curvature near edges and vertices stays below the tolerance), away from the medial axis; unit length everywhere; and on the surface, the pseudonormal
 * of the closest feature (the face normal at a face's centroid, an outward unit vector at
 * a vertex).
 *
 * Medial-axis filter: a point is tested only when the closest points of p +- h e_i all lie
 * within 1.5h of p's closest point. Off the medial axis a step of h moves the closest point
 * by at most h R / (R - |d|) (R the local radius of curvature), while across it the closest
 * point jumps to another feature. */
#include <math.h>
#include <stdlib.h>

#include "../common/check.h"
#include "../common/workload.h"

static void test_central_differences(const char *name, sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const double h = 1e-4 * r.diagonal;
    size_t n = 1500;
    float *p = malloc(3 * n * sizeof *p);
    sdf_workload(mesh, "band", &n, 31, p);
    /* Each point with its 6 neighbours p +- h e_i, in one batch. */
    float *q = malloc(7 * 3 * n * sizeof *q), *d = malloc(7 * n * sizeof *d);
    float *g = malloc(7 * 3 * n * sizeof *g), *c = malloc(7 * 3 * n * sizeof *c);
    for (size_t i = 0; i < n; i++) {
        for (int j = 0; j < 7; j++) {
            float *x = q + 3 * (7 * i + j);
            for (int k = 0; k < 3; k++)
                x[k] = p[3 * i + k];
            if (j > 0)
                x[(j - 1) / 2] += (float)((j % 2 ? 1 : -1) * h);
        }
    }
    sdf_query_result res = {.distance = d, .gradient = g, .closest = c};
    CHECK(sdf_query(mesh, q, 7 * n, NULL, &res) == 0, "query");
    size_t tested = 0;
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        const float *c0 = c + 3 * 7 * i, *g0 = g + 3 * 7 * i;
        double len = sqrt(g0[0] * g0[0] + g0[1] * g0[1] + g0[2] * g0[2]);
        CHECK(fabs(len - 1) < 1e-5, "%s point %zu: |gradient| = %.7f", name, i, len);
        if (fabs(d[7 * i]) < 50 * h)
            continue; /* near the surface, the field curves too fast for a difference of h */
        int smooth = 1;
        for (int j = 1; j < 7; j++) {
            const float *cj = c + 3 * (7 * i + j);
            double jump = sqrt((cj[0] - c0[0]) * (cj[0] - c0[0]) + (cj[1] - c0[1]) * (cj[1] - c0[1]) +
                               (cj[2] - c0[2]) * (cj[2] - c0[2]));
            smooth &= jump < 1.5 * h;
        }
        if (!smooth)
            continue;
        tested++;
        for (int k = 0; k < 3; k++) {
            /* Divide by the step the float coordinates really took, not the nominal 2h. */
            double step = (double)q[3 * (7 * i + 1 + 2 * k) + k] - q[3 * (7 * i + 2 + 2 * k) + k];
            double fd = (d[7 * i + 1 + 2 * k] - d[7 * i + 2 + 2 * k]) / step;
            worst = fmax(worst, fabs(fd - g0[k]));
        }
    }
    CHECK(tested > n / 4, "%s: only %zu of %zu points away from the medial axis", name, tested, n);
    CHECK(worst < 5e-3, "%s: gradient differs from central differences by %g", name, worst);
    printf("%s: %zu points, max |gradient - central difference| = %.2e\n", name, tested, worst);
    free(p), free(q), free(d), free(g), free(c);
}

/* Points exactly on the surface get the pseudonormal: at a face centroid the face normal,
 * at a vertex an outward unit vector (it points away from the mesh's interior). */
static void test_on_surface(const char *name, sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const float *v = sdf_mesh_vertices(mesh);
    const uint32_t *t = sdf_mesh_triangles(mesh);
    size_t n = r.triangles < 500 ? r.triangles : 500;
    for (size_t i = 0; i < n; i++) {
        size_t tri = i * (r.triangles / n);
        const float *a = v + 3 * t[3 * tri], *b = v + 3 * t[3 * tri + 1], *cc = v + 3 * t[3 * tri + 2];
        float centroid[3], g[3], d, vg[3], vd;
        double e1[3], e2[3], nrm[3];
        for (int k = 0; k < 3; k++) {
            centroid[k] = (a[k] + b[k] + cc[k]) / 3;
            e1[k] = b[k] - a[k];
            e2[k] = cc[k] - a[k];
        }
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        sdf_query_result res = {.distance = &d, .gradient = g};
        CHECK(sdf_query(mesh, centroid, 1, NULL, &res) == 0, "query");
        double dotn = (g[0] * nrm[0] + g[1] * nrm[1] + g[2] * nrm[2]) / len;
        CHECK(fabs(d) < 1e-6 * r.diagonal && dotn > 0.9999,
              "%s triangle %zu centroid: d = %g, gradient . normal = %g", name, tri, d, dotn);
        /* At a vertex: unit, and stepping along it leaves the mesh (positive distance). */
        res = (sdf_query_result){.distance = &vd, .gradient = vg};
        CHECK(sdf_query(mesh, a, 1, NULL, &res) == 0 && vd == 0, "%s vertex: d = %g", name, vd);
        float out[3];
        for (int k = 0; k < 3; k++)
            out[k] = a[k] + (float)(1e-3 * r.diagonal) * vg[k];
        res = (sdf_query_result){.distance = &d};
        CHECK(sdf_query(mesh, out, 1, NULL, &res) == 0 && d > 0,
              "%s: stepping along a vertex's gradient gives d = %g", name, d);
    }
}

static void test_mesh(const char *name, sdf_mesh *mesh)
{
    if (!mesh)
        return;
    test_central_differences(name, mesh);
    test_on_surface(name, mesh);
    sdf_mesh_release(mesh);
}

static void test_fandisk(void)
{
    test_mesh("fandisk.off", load_data_mesh("fandisk.off"));
}

static void test_knot1(void)
{
    test_mesh("knot1.off", load_data_mesh("knot1.off"));
}

static void test_demo(void)
{
    sdf_mesh *demo = NULL;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo");
    test_mesh("demo", demo);
}

static const check_case cases[] = {
    {"fandisk", test_fandisk},
    {"knot1", test_knot1},
    {"demo", test_demo},
};

int main(int argc, char **argv)
{
    return check_main("gradient", cases, CHECK_COUNT_OF(cases), argc, argv);
}
