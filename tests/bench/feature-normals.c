/* feature-normals - how well a surface extracted from a first-order volume keeps a mesh's
 * sharp edges, dual contouring against marching cubes (docs/volumes.md, "Meshes from
 * volumes"). The mesh (default tests/data/fandisk.off) is baked at first order on N^3 nodes
 * and extracted both ways; for each extracted triangle, the angle between its normal and the
 * mesh's at its centroid's closest point (where that point lies on an edge of the mesh, the
 * nearer of the two faces' normals), over the triangles whose centroid lies within 2 cells of
 * a sharp edge (faces meeting at more than 30 degrees), and over all. Prints a Markdown table.
 * Not a test: it asserts nothing.
 *
 *   feature-normals [MESH] [--resolution N] [--threads T] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "sdf/sdf.h"

#define SHARP_DEGREES 30.0
#define NEAR_CELLS 2.0

typedef struct edge_ref {
    uint32_t a, b, tri;
} edge_ref;

static int by_edge(const void *x, const void *y)
{
    const edge_ref *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

static void normal_of(const float *v, const uint32_t *t, double n[3])
{
    double u[3], w[3], len = 0;
    for (int r = 0; r < 3; r++)
        u[r] = v[3 * t[1] + r] - v[3 * t[0] + r], w[r] = v[3 * t[2] + r] - v[3 * t[0] + r];
    n[0] = u[1] * w[2] - u[2] * w[1], n[1] = u[2] * w[0] - u[0] * w[2];
    n[2] = u[0] * w[1] - u[1] * w[0];
    for (int r = 0; r < 3; r++)
        len += n[r] * n[r];
    for (int r = 0; r < 3; r++)
        n[r] = len > 0 ? n[r] / sqrt(len) : 0;
}

static double angle(const double a[3], const double b[3])
{
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return acos(fmax(-1, fmin(1, d))) * 180 / M_PI;
}

typedef struct model {
    const float *v;
    const uint32_t *t;
    size_t nt;
    double (*normal)[3];
    int32_t (*across)[3]; /* the triangle across the edge opposite each corner, or -1 */
    float *sharp;         /* 6 per sharp edge: its two ends */
    size_t nsharp;
} model;

static void build(model *m, size_t nt)
{
    edge_ref *e = malloc(3 * nt * sizeof *e);
    m->nt = nt;
    m->normal = malloc(nt * sizeof *m->normal);
    m->across = malloc(nt * sizeof *m->across);
    m->sharp = malloc(3 * nt * 6 * sizeof(float));
    m->nsharp = 0;
    for (size_t i = 0; i < nt; i++) {
        normal_of(m->v, m->t + 3 * i, m->normal[i]);
        for (int c = 0; c < 3; c++) {
            uint32_t a = m->t[3 * i + (c + 1) % 3], b = m->t[3 * i + (c + 2) % 3];
            e[3 * i + c] = (edge_ref){a < b ? a : b, a < b ? b : a, (uint32_t)i};
            m->across[i][c] = -1;
        }
    }
    qsort(e, 3 * nt, sizeof *e, by_edge);
    for (size_t i = 0; i + 1 < 3 * nt; i++) {
        if (e[i].a != e[i + 1].a || e[i].b != e[i + 1].b)
            continue;
        uint32_t p = e[i].tri, q = e[i + 1].tri;
        for (int c = 0; c < 3; c++) {
            uint32_t x = m->t[3 * p + c], y = m->t[3 * q + c];
            if (x != e[i].a && x != e[i].b)
                m->across[p][c] = (int32_t)q;
            if (y != e[i].a && y != e[i].b)
                m->across[q][c] = (int32_t)p;
        }
        if (angle(m->normal[p], m->normal[q]) > SHARP_DEGREES) {
            memcpy(m->sharp + 6 * m->nsharp, m->v + 3 * e[i].a, 12);
            memcpy(m->sharp + 6 * m->nsharp++ + 3, m->v + 3 * e[i].b, 12);
        }
    }
    free(e);
}

static double segment_distance(const float *s, const double p[3])
{
    double d[3], w[3], dd = 0, t = 0, out = 0;
    for (int r = 0; r < 3; r++)
        d[r] = s[3 + r] - s[r], w[r] = p[r] - s[r], dd += d[r] * d[r], t += d[r] * w[r];
    t = dd > 0 ? fmax(0, fmin(1, t / dd)) : 0;
    for (int r = 0; r < 3; r++)
        out += (w[r] - t * d[r]) * (w[r] - t * d[r]);
    return sqrt(out);
}

static int by_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Angles of the surface's triangles to the mesh, near the sharp edges (near) and all. */
static void measure(const sdf_mesh *mesh, const model *m, const sdf_surface *s, double cell,
                    double *near, size_t *nn, double *all, size_t *na)
{
    size_t nv, nt;
    const float *v = sdf_surface_vertices(s, &nv);
    const uint32_t *t = sdf_surface_triangles(s, &nt);
    float *c = malloc(3 * nt * sizeof(float) + 1), *bary = malloc(3 * nt * sizeof(float) + 1);
    uint32_t *tri = malloc(nt * sizeof(uint32_t) + 1);
    for (size_t i = 0; i < nt; i++)
        for (int r = 0; r < 3; r++)
            c[3 * i + r] = (v[3 * t[3 * i] + r] + v[3 * t[3 * i + 1] + r] + v[3 * t[3 * i + 2] + r]) / 3;
    sdf_query_options qo = {.sign = SDF_SIGN_NONE};
    sdf_query_result qr = {.triangle = tri, .barycentric = bary};
    if (sdf_query(mesh, c, nt, &qo, &qr)) {
        fprintf(stderr, "feature-normals: the query failed\n");
        exit(1);
    }
    *nn = *na = 0;
    for (size_t i = 0; i < nt; i++) {
        double n[3], p[3] = {c[3 * i], c[3 * i + 1], c[3 * i + 2]};
        normal_of(v, t + 3 * i, n);
        if (n[0] == 0 && n[1] == 0 && n[2] == 0)
            continue;
        double err = angle(n, m->normal[tri[i]]);
        for (int k = 0; k < 3; k++) /* on the edge opposite corner k: its other face too */
            if (bary[3 * i + k] < 1e-4f && m->across[tri[i]][k] >= 0)
                err = fmin(err, angle(n, m->normal[m->across[tri[i]][k]]));
        all[(*na)++] = err;
        double nearest = INFINITY;
        for (size_t e = 0; e < m->nsharp && nearest >= NEAR_CELLS * cell; e++)
            nearest = fmin(nearest, segment_distance(m->sharp + 6 * e, p));
        if (nearest < NEAR_CELLS * cell)
            near[(*nn)++] = err;
    }
    free(c), free(bary), free(tri);
}

static void row(const char *name, double *a, size_t n)
{
    double mean = 0;
    for (size_t i = 0; i < n; i++)
        mean += a[i] / (double)n;
    qsort(a, n, sizeof *a, by_double);
    printf(" %zu | %.2f | %.2f | %.2f |", n, mean, n ? a[n / 2] : NAN,
           n ? a[(size_t)(0.9 * (double)(n - 1))] : NAN);
    (void)name;
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 && argv[1][0] != '-' ? argv[1] : data_path("fandisk.off");
    size_t res = 128;
    int threads = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--resolution") && i + 1 < argc)
            res = (size_t)atol(argv[++i]);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = atoi(argv[++i]);
    }
    sdf_mesh *mesh = NULL;
    sdf_diag d;
    if (sdf_mesh_load_file(path, NULL, &mesh, &d)) {
        fprintf(stderr, "feature-normals: %s: %s\n", path, d.message);
        return 1;
    }
    sdf_mesh_report rep;
    sdf_mesh_get_report(mesh, &rep);
    model m = {.v = sdf_mesh_vertices(mesh), .t = sdf_mesh_triangles(mesh)};
    build(&m, rep.triangles);
    sdf_bake_options bo = {.dims = {res, res, res}, .order = 1, .query.threads = threads};
    sdf_volume *vol = NULL;
    if (sdf_volume_bake(mesh, &bo, &vol, &d)) {
        fprintf(stderr, "feature-normals: bake: %s\n", d.message);
        return 1;
    }
    sdf_volume_info in;
    sdf_volume_get_info(vol, &in);
    double cell = fmax(in.spacing[0], fmax(in.spacing[1], in.spacing[2]));
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    printf("%s, first order at %zu^3 nodes; %zu sharp edges (> %g degrees); angles in degrees\n\n",
           base, res, m.nsharp, SHARP_DEGREES);
    printf("| extraction | near: triangles | mean | median | 90th pct | all: triangles | mean | "
           "median | 90th pct |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n");
    const sdf_extract_method methods[2] = {SDF_EXTRACT_MARCHING_CUBES, SDF_EXTRACT_DUAL};
    for (int k = 0; k < 2; k++) {
        sdf_extract_options o = {.method = methods[k], .threads = threads};
        sdf_surface *s = NULL;
        if (sdf_volume_extract(vol, &o, &s, &d)) {
            fprintf(stderr, "feature-normals: extract: %s\n", d.message);
            return 1;
        }
        size_t nt, nn, na;
        sdf_surface_triangles(s, &nt);
        double *near = malloc(nt * sizeof *near + 8), *all = malloc(nt * sizeof *all + 8);
        measure(mesh, &m, s, cell, near, &nn, all, &na);
        printf("| %s |", sdf_extract_method_name(methods[k]));
        row("near", near, nn);
        row("all", all, na);
        printf("\n");
        free(near), free(all);
        sdf_surface_destroy(s);
    }
    sdf_volume_destroy(vol);
    sdf_mesh_release(mesh);
    return 0;
}
