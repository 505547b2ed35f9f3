/* test_extract.c - sdf_volume_extract (lib/contour) on analytic fields sampled at 64^3 over
 * [-1, 1]^3 and on baked volumes:
 *  - every surface is closed and edge-manifold with consistent orientation (each undirected
 *    edge used exactly twice, once each way), encloses a positive volume, and has no triangle
 *    that repeats a vertex or has zero area;
 *  - on signed distances (sphere, torus, box, two spheres 0.6 cells apart, a plate 1.5 cells
 *    thick, a torus cut by the grid with caps): every vertex within 0.5 cells of the surface,
 *    every sampled surface point within 0.5 cells of the mesh (sphere, torus, box), and the
 *    enclosed volume within 1 % of the exact one;
 *  - a saddle and 1,000 random smooth fields (16^3 .. 24^3, with caps) hold the topology;
 *  - without caps a surface that leaves the grid is open exactly along the grid's boundary;
 *  - the arrays are the same on 1 and on 2 threads; a first-order volume of fandisk (its
 *    planes at the nodes) and a volume with no crossing extract as they should;
 *  - sdf_mesh_write's four formats read back to the same triangles at the same floats;
 *  - dual contouring of first-order fields (planes from the fields' gradients): the same
 *    topology checks on the analytic fields and 500 noise fields, the box's edges within 0.15
 *    cells where marching cubes chamfers them by 0.3 (on a zero-order box, with normals from
 *    differences, within 0.25), the same arrays on 1 and 2 threads. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../field/shapes.h"

#define N 64
#define H (2.0 / (N - 1))

/* ---- the fields ---------------------------------------------------------------------- */

static double sphere(const double p[3]) { return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 0.6; }

static double torus(const double p[3])
{
    double q = sqrt(p[0] * p[0] + p[1] * p[1]) - 0.5;
    return sqrt(q * q + p[2] * p[2]) - 0.2;
}

static double box(const double p[3])
{
    static const double b[3] = {0.5, 0.4, 0.3};
    double q[3], out = 0, in = -INFINITY;
    for (int a = 0; a < 3; a++) {
        q[a] = fabs(p[a]) - b[a];
        out += q[a] > 0 ? q[a] * q[a] : 0;
        in = fmax(in, q[a]);
    }
    return out > 0 ? sqrt(out) : in;
}

static double two_spheres(const double p[3]) /* 0.6 cells apart */
{
    double c = 0.3 + 0.3 * H;
    double a = sqrt((p[0] - c) * (p[0] - c) + p[1] * p[1] + p[2] * p[2]) - 0.3;
    double b = sqrt((p[0] + c) * (p[0] + c) + p[1] * p[1] + p[2] * p[2]) - 0.3;
    return fmin(a, b);
}

static double plate(const double p[3]) /* 1.5 cells thick, 1.2 wide */
{
    double q[3] = {fabs(p[0]) - 0.6, fabs(p[1]) - 0.6, fabs(p[2] - 0.01) - 0.75 * H}, out = 0;
    double in = fmax(q[0], fmax(q[1], q[2]));
    for (int a = 0; a < 3; a++)
        out += q[a] > 0 ? q[a] * q[a] : 0;
    return out > 0 ? sqrt(out) : in;
}

static double cut_torus(const double p[3]) /* leaves the grid through x = 1 */
{
    double s[3] = {p[0] - 0.7, p[1], p[2]};
    return torus(s);
}

static double saddle(const double p[3]) { return p[2] - 0.8 * (p[0] * p[0] - p[1] * p[1]); }

/* ---- checks ---------------------------------------------------------------------------- */

typedef struct topo {
    size_t boundary;     /* undirected edges used once */
    size_t bad;          /* used more than twice, or twice the same way */
    size_t degenerate;   /* triangles repeating a vertex or of zero area */
    double volume;       /* enclosed (divergence theorem) */
} topo;

typedef struct edge_use {
    uint32_t a, b;       /* a < b */
    int dir;             /* +1 a->b, -1 b->a */
} edge_use;

static int by_edge(const void *x, const void *y)
{
    const edge_use *p = x, *q = y;
    if (p->a != q->a)
        return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

static double tri_area2(const float *v, const uint32_t *t)
{
    double u[3], w[3];
    for (int a = 0; a < 3; a++)
        u[a] = v[3 * t[1] + a] - v[3 * t[0] + a], w[a] = v[3 * t[2] + a] - v[3 * t[0] + a];
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    return n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
}

static topo topology(const sdf_surface *s)
{
    size_t nv, nt;
    const float *v = sdf_surface_vertices(s, &nv);
    const uint32_t *t = sdf_surface_triangles(s, &nt);
    topo r = {0};
    edge_use *e = malloc(3 * nt * sizeof *e + 1);
    for (size_t i = 0; i < nt; i++) {
        const uint32_t *x = t + 3 * i;
        if (x[0] == x[1] || x[1] == x[2] || x[0] == x[2] || !(tri_area2(v, x) > 0))
            r.degenerate++;
        const float *p = v + 3 * x[0], *q = v + 3 * x[1], *o = v + 3 * x[2];
        r.volume += (p[0] * ((double)q[1] * o[2] - (double)q[2] * o[1]) -
                     p[1] * ((double)q[0] * o[2] - (double)q[2] * o[0]) +
                     p[2] * ((double)q[0] * o[1] - (double)q[1] * o[0])) / 6;
        for (int c = 0; c < 3; c++) {
            uint32_t a = x[c], b = x[(c + 1) % 3];
            e[3 * i + c] = (edge_use){a < b ? a : b, a < b ? b : a, a < b ? 1 : -1};
        }
    }
    qsort(e, 3 * nt, sizeof *e, by_edge);
    for (size_t i = 0; i < 3 * nt;) {
        size_t j = i;
        while (j < 3 * nt && e[j].a == e[i].a && e[j].b == e[i].b)
            j++;
        if (j - i == 1)
            r.boundary++;
        else if (j - i > 2 || e[i].dir == e[i + 1].dir)
            r.bad++;
        i = j;
    }
    free(e);
    return r;
}

static sdf_extract_method method = SDF_EXTRACT_AUTO; /* what extract() asks for */

static sdf_surface *extract(const sdf_volume *v, int cap, int threads)
{
    sdf_extract_options o = {.cap = cap, .threads = threads, .method = method};
    sdf_surface *s = NULL;
    sdf_diag d;
    int rc = sdf_volume_extract(v, &o, &s, &d);
    CHECK(rc == 0, "extract: %s", d.message);
    return s;
}

static void check_closed(const char *name, const sdf_surface *s, size_t min_triangles)
{
    size_t nt;
    sdf_surface_triangles(s, &nt);
    topo t = topology(s);
    CHECK(nt >= min_triangles, "%s: %zu triangles", name, nt);
    CHECK(t.boundary == 0 && t.bad == 0, "%s: %zu boundary and %zu bad edges", name,
          t.boundary, t.bad);
    CHECK(t.degenerate == 0, "%s: %zu degenerate triangles", name, t.degenerate);
    CHECK(t.volume > 0, "%s: enclosed volume %g", name, t.volume);
}

/* Largest |f| at the vertices, in cells; a cap's vertices (beyond the grid) aside. */
static double vertex_error(const sdf_surface *s, shape_fn f)
{
    size_t nv;
    const float *v = sdf_surface_vertices(s, &nv);
    double worst = 0;
    for (size_t i = 0; i < nv; i++) {
        double p[3] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
        if (fabs(p[0]) <= 1 && fabs(p[1]) <= 1 && fabs(p[2]) <= 1)
            worst = fmax(worst, fabs(f(p)));
    }
    return worst / H;
}

typedef void (*surface_sampler)(unsigned seed, double out[3]);

static double uniform(unsigned *s)
{
    *s = *s * 1664525u + 1013904223u;
    return (*s >> 8) / 16777216.0;
}

static void on_sphere(unsigned seed, double p[3])
{
    double z = 2 * uniform(&seed) - 1, phi = 2 * M_PI * uniform(&seed), r = sqrt(1 - z * z);
    p[0] = 0.6 * r * cos(phi), p[1] = 0.6 * r * sin(phi), p[2] = 0.6 * z;
}

static void on_torus(unsigned seed, double p[3])
{
    double u = 2 * M_PI * uniform(&seed), w = 2 * M_PI * uniform(&seed);
    p[0] = (0.5 + 0.2 * cos(w)) * cos(u), p[1] = (0.5 + 0.2 * cos(w)) * sin(u);
    p[2] = 0.2 * sin(w);
}

static void on_box(unsigned seed, double p[3])
{
    static const double b[3] = {0.5, 0.4, 0.3};
    int a = (int)(uniform(&seed) * 3), side = uniform(&seed) < 0.5 ? -1 : 1;
    for (int c = 0; c < 3; c++)
        p[c] = (2 * uniform(&seed) - 1) * b[c];
    p[a] = side * b[a];
}

/* Largest distance from 2,000 points of the surface to the mesh, in cells. */
static double surface_error(const sdf_surface *s, surface_sampler sample)
{
    sdf_mesh *m = NULL;
    sdf_diag d;
    CHECK(sdf_surface_to_mesh(s, NULL, &m, &d) == 0, "to_mesh: %s", d.message);
    if (!m)
        return INFINITY;
    float pts[3 * 2000], dist[2000];
    for (unsigned i = 0; i < 2000; i++) {
        double p[3];
        sample(i * 7919u + 1, p);
        for (int a = 0; a < 3; a++)
            pts[3 * i + a] = (float)p[a];
    }
    sdf_query_options qo = {.sign = SDF_SIGN_NONE};
    sdf_query_result r = {.distance = dist};
    CHECK(sdf_query(m, pts, 2000, &qo, &r) == 0, "query");
    sdf_mesh_release(m);
    double worst = 0;
    for (int i = 0; i < 2000; i++)
        worst = fmax(worst, fabs(dist[i]));
    return worst / H;
}

/* ---- cases ---------------------------------------------------------------------------- */

typedef struct distance_case {
    const char *name;
    shape_fn f;
    double volume;            /* exact enclosed volume; 0: not checked */
    surface_sampler sample;   /* NULL: the vertices' side only */
    int cap;
} distance_case;

static void run_distance_case(const distance_case *c)
{
    sdf_volume *v = shape_volume(c->f, N);
    CHECK(v != NULL, "%s: volume", c->name);
    if (!v)
        return;
    sdf_surface *s = extract(v, c->cap, 2);
    if (s) {
        check_closed(c->name, s, 100);
        double ve = vertex_error(s, c->f), se = NAN, dv = NAN;
        CHECK(ve <= 0.5, "%s: a vertex %.3f cells off the surface", c->name, ve);
        if (c->sample) {
            se = surface_error(s, c->sample);
            CHECK(se <= 0.5, "%s: a surface point %.3f cells from the mesh", c->name, se);
        }
        if (c->volume > 0) {
            double got = topology(s).volume;
            dv = (got - c->volume) / c->volume;
            CHECK(fabs(dv) <= 0.01, "%s: volume %.5f, exact %.5f", c->name, got, c->volume);
        }
        size_t nt;
        sdf_surface_triangles(s, &nt);
        printf("  %s: %zu triangles; vertices within %.3f cells of the surface, the surface "
               "within %.3f cells of the mesh; volume %+.3f %%\n", c->name, nt, ve, se, 100 * dv);
    }
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

static void test_distances(void)
{
    const double pi = M_PI;
    const distance_case cases[] = {
        {"sphere", sphere, 4.0 / 3 * pi * 0.216, on_sphere, 0},
        {"torus", torus, 2 * pi * pi * 0.5 * 0.04, on_torus, 0},
        {"box", box, 8 * 0.5 * 0.4 * 0.3, on_box, 0},
        {"two_spheres", two_spheres, 2 * 4.0 / 3 * pi * 0.027, NULL, 0},
        {"plate", plate, 0, NULL, 0},
        {"cut_torus", cut_torus, 0, NULL, 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        run_distance_case(&cases[i]);
}

static void test_saddle(void)
{
    sdf_volume *v = shape_volume(saddle, N);
    sdf_surface *s = v ? extract(v, 1, 2) : NULL;
    if (s)
        check_closed("saddle", s, 100);
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

/* A smooth random field: a sum of 6 plane waves of wavelength 0.5 .. 2 and an offset. */
typedef struct noise {
    double k[6][3], phase[6], amp[6], offset;
} noise;

static noise noise_of(unsigned seed)
{
    noise n;
    for (int w = 0; w < 6; w++) {
        for (int a = 0; a < 3; a++)
            n.k[w][a] = (2 * uniform(&seed) - 1) * 2 * M_PI;
        n.phase[w] = 2 * M_PI * uniform(&seed);
        n.amp[w] = uniform(&seed);
    }
    n.offset = 2 * uniform(&seed) - 1;
    return n;
}

static sdf_volume *noise_volume(const noise *n, size_t dim)
{
    sdf_volume_info in = {.dims = {dim, dim, dim}, .origin = {-1, -1, -1}};
    for (int a = 0; a < 3; a++)
        in.spacing[a] = 2.0 / (double)(dim - 1);
    float *data = malloc(dim * dim * dim * sizeof(float));
    for (size_t k = 0; k < dim; k++)
        for (size_t j = 0; j < dim; j++)
            for (size_t i = 0; i < dim; i++) {
                double p[3] = {-1 + (double)i * in.spacing[0], -1 + (double)j * in.spacing[1],
                               -1 + (double)k * in.spacing[2]}, f = n->offset;
                for (int w = 0; w < 6; w++)
                    f += n->amp[w] * sin(n->k[w][0] * p[0] + n->k[w][1] * p[1] +
                                         n->k[w][2] * p[2] + n->phase[w]);
                data[(k * dim + j) * dim + i] = (float)f;
            }
    sdf_volume *v = NULL;
    sdf_diag d;
    CHECK(sdf_volume_create(&in, data, &v, &d) == 0, "noise volume: %s", d.message);
    free(data);
    return v;
}

static void test_noise(void)
{
    size_t open = 0, failures = 0, triangles = 0;
    for (unsigned seed = 1; seed <= 1000; seed++) {
        noise n = noise_of(seed);
        sdf_volume *v = noise_volume(&n, 16 + seed % 9);
        if (!v)
            return;
        sdf_surface *s = extract(v, seed % 2, 1);
        size_t nt = 0;
        if (s)
            sdf_surface_triangles(s, &nt);
        topo t = s ? topology(s) : (topo){.bad = 1};
        int ok = t.bad == 0 && t.degenerate == 0 && (seed % 2 ? t.boundary == 0 : 1) &&
                 (nt == 0 || seed % 2 == 0 || t.volume > 0);
        if (!ok && failures++ < 5)
            CHECK(ok, "noise %u: %zu boundary, %zu bad edges, %zu degenerate, volume %g", seed,
                  t.boundary, t.bad, t.degenerate, t.volume);
        open += seed % 2 == 0 && t.boundary > 0;
        triangles += nt;
        sdf_surface_destroy(s);
        sdf_volume_destroy(v);
    }
    CHECK(failures == 0, "%zu of 1000 noise fields failed", failures);
    CHECK(open > 100, "only %zu of the uncapped noise surfaces reach the grid's boundary", open);
    printf("  1000 noise fields: %zu triangles in all\n", triangles);
}

/* Without caps the torus cut by the grid is open, each boundary edge on the plane x = 1. */
static void test_open_boundary(void)
{
    sdf_volume *v = shape_volume(cut_torus, N);
    sdf_surface *s = v ? extract(v, 0, 2) : NULL;
    if (s) {
        topo t = topology(s);
        CHECK(t.boundary > 0 && t.bad == 0 && t.degenerate == 0, "%zu boundary, %zu bad",
              t.boundary, t.bad);
        size_t nv, nt;
        const float *p = sdf_surface_vertices(s, &nv);
        const uint32_t *tri = sdf_surface_triangles(s, &nt);
        size_t off_plane = 0;
        edge_use *e = malloc(3 * nt * sizeof *e);
        for (size_t i = 0; i < 3 * nt; i++) {
            uint32_t a = tri[i], b = tri[i % 3 == 2 ? i - 2 : i + 1];
            e[i] = (edge_use){a < b ? a : b, a < b ? b : a, 1};
        }
        qsort(e, 3 * nt, sizeof *e, by_edge);
        for (size_t i = 0; i < 3 * nt; i++) {
            int single = (i == 0 || by_edge(&e[i - 1], &e[i])) &&
                         (i + 1 == 3 * nt || by_edge(&e[i], &e[i + 1]));
            if (single && (fabs(p[3 * e[i].a] - 1) > 1e-5 || fabs(p[3 * e[i].b] - 1) > 1e-5))
                off_plane++;
        }
        free(e);
        CHECK(off_plane == 0, "%zu boundary edges are not on x = 1", off_plane);
    }
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

static int same_surface(const sdf_surface *a, const sdf_surface *b)
{
    size_t va, vb, ta, tb;
    const float *pa = sdf_surface_vertices(a, &va), *pb = sdf_surface_vertices(b, &vb);
    const uint32_t *xa = sdf_surface_triangles(a, &ta), *xb = sdf_surface_triangles(b, &tb);
    return va == vb && ta == tb && !memcmp(pa, pb, va * 12) && !memcmp(xa, xb, ta * 12);
}

static void test_threads(void)
{
    sdf_volume *v = shape_volume(torus, N);
    sdf_surface *one = v ? extract(v, 1, 1) : NULL, *two = v ? extract(v, 1, 2) : NULL,
                *many = v ? extract(v, 1, 7) : NULL;
    CHECK(one && two && many && same_surface(one, two) && same_surface(one, many),
          "the arrays differ between thread counts");
    sdf_surface_destroy(one), sdf_surface_destroy(two), sdf_surface_destroy(many);
    sdf_volume_destroy(v);
}

static void test_first_order(void)
{
    sdf_mesh *m = load_data_mesh("fandisk.off");
    if (!m)
        return;
    sdf_bake_options bo = {.dims = {40, 40, 40}, .order = 1};
    sdf_volume *v = NULL;
    sdf_diag d;
    CHECK(sdf_volume_bake(m, &bo, &v, &d) == 0, "bake: %s", d.message);
    sdf_surface *s = v ? extract(v, 0, 2) : NULL;
    if (s)
        check_closed("fandisk order 1", s, 1000);
    sdf_surface_destroy(s);
    bo.encoding = SDF_ENCODING_PACKED32;
    sdf_volume_destroy(v);
    v = NULL;
    CHECK(sdf_volume_bake(m, &bo, &v, &d) == 0, "bake packed: %s", d.message);
    s = v ? extract(v, 0, 2) : NULL;
    if (s)
        check_closed("fandisk packed", s, 1000);
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
    sdf_mesh_release(m);
}

static void test_no_crossing_and_errors(void)
{
    sdf_volume *v = shape_volume(sphere, 8);
    sdf_extract_options o = {.iso = 5};
    sdf_surface *s = NULL;
    sdf_diag d;
    CHECK(v && sdf_volume_extract(v, &o, &s, &d) == 0, "iso beyond every value");
    size_t nt = 1, nv = 1;
    if (s)
        sdf_surface_triangles(s, &nt), sdf_surface_vertices(s, &nv);
    CHECK(nt == 0 && nv == 0, "no crossing: %zu triangles", nt);
    sdf_surface_destroy(s);
    o.iso = NAN;
    s = NULL;
    CHECK(sdf_volume_extract(v, &o, &s, &d) == SDF_EINVAL && !s, "a NaN iso");
    o.iso = 0.1;
    CHECK(sdf_volume_extract(v, &o, &s, &d) == 0 && s, "iso 0.1");
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

/* Each file format, read back by the parsers: the same triangles at the same floats. */
static void test_files(void)
{
    sdf_volume *v = shape_volume(torus, 24);
    sdf_surface *s = v ? extract(v, 0, 2) : NULL;
    if (!s) {
        sdf_volume_destroy(v);
        return;
    }
    size_t nv, nt;
    const float *p = sdf_surface_vertices(s, &nv);
    const uint32_t *t = sdf_surface_triangles(s, &nt);
    const sdf_format formats[] = {SDF_FORMAT_PLY, SDF_FORMAT_OBJ, SDF_FORMAT_STL, SDF_FORMAT_OFF};
    for (int f = 0; f < 4; f++) {
        size_t cap = sdf_mesh_write_bound(nv, nt, formats[f]);
        char *buf = malloc(cap);
        size_t n = sdf_mesh_write(p, nv, t, nt, formats[f], buf, cap);
        CHECK(n > 0 && n <= cap, "%s: wrote %zu of %zu", sdf_format_name(formats[f]), n, cap);
        CHECK(sdf_mesh_write(p, nv, t, nt, formats[f], buf, cap - 1) == 0, "a short buffer");
        sdf_mesh_options mo = {.format = formats[f]};
        sdf_mesh *m = NULL;
        sdf_diag d;
        CHECK(sdf_mesh_load_memory(buf, n, &mo, &m, &d) == 0, "%s: %s",
              sdf_format_name(formats[f]), d.message);
        if (m) {
            sdf_mesh_report r;
            sdf_mesh_get_report(m, &r);
            const float *q = sdf_mesh_vertices(m);
            const uint32_t *x = sdf_mesh_triangles(m);
            size_t same = 0;
            for (size_t i = 0; i < nt && r.triangles == nt; i++)
                for (int c = 0; c < 3; c++)
                    same += !memcmp(q + 3 * x[3 * i + c], p + 3 * t[3 * i + c], 12);
            CHECK(r.triangles == nt && same == 3 * nt && r.closed, "%s: %zu of %zu corners",
                  sdf_format_name(formats[f]), same, 3 * nt);
            sdf_mesh_release(m);
        }
        free(buf);
    }
    CHECK(sdf_mesh_write_bound(nv, nt, SDF_FORMAT_AUTO) == 0, "auto has no writer");
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

/* ---- dual contouring ------------------------------------------------------------------- */

/* A first-order volume of f: each node's plane from f and its gradient there (central
 * differences), as a first-order bake of f's surface would hold. */
static sdf_volume *plane_volume(shape_fn f, size_t n)
{
    sdf_volume_info in = {.dims = {n, n, n}, .origin = {-1, -1, -1}, .order = 1,
                          .fine_half = 1, .fine_spacing = 0.1};
    for (int a = 0; a < 3; a++)
        in.spacing[a] = 2.0 / (double)(n - 1);
    float *data = malloc(n * n * n * 4 * sizeof(float));
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++) {
                double p[3] = {-1 + (double)i * in.spacing[0], -1 + (double)j * in.spacing[1],
                               -1 + (double)k * in.spacing[2]}, g[3], d = 0, v = f(p);
                for (int a = 0; a < 3; a++) {
                    double q[3] = {p[0], p[1], p[2]}, r[3] = {p[0], p[1], p[2]};
                    q[a] += 1e-6, r[a] -= 1e-6;
                    g[a] = (f(q) - f(r)) / 2e-6;
                    d += g[a] * p[a];
                }
                float *c = data + 4 * ((k * n + j) * n + i);
                c[0] = (float)g[0], c[1] = (float)g[1], c[2] = (float)g[2], c[3] = (float)(v - d);
            }
    sdf_volume *out = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_create(&in, data, &out, &diag) == 0, "plane volume: %s", diag.message);
    free(data);
    return out;
}

static void run_dual_case(const char *name, shape_fn f, surface_sampler sample, int cap,
                          double max_cells)
{
    sdf_volume *v = plane_volume(f, N);
    sdf_surface *s = v ? extract(v, cap, 2) : NULL;
    if (s) {
        size_t nt;
        sdf_surface_triangles(s, &nt);
        topo t = topology(s);
        CHECK(nt > 100 && t.boundary == 0 && t.bad == 0 && t.volume > 0,
              "%s: %zu boundary, %zu bad edges, volume %g", name, t.boundary, t.bad, t.volume);
        double ve = vertex_error(s, f), se = sample ? surface_error(s, sample) : NAN;
        CHECK(ve <= max_cells && !(se > max_cells), "%s: vertices %.3f, surface %.3f cells",
              name, ve, se);
        printf("  %s: %zu triangles (%zu degenerate); vertices within %.3f cells of the "
               "surface, the surface within %.3f cells of the mesh\n", name, nt, t.degenerate,
               ve, se);
    }
    sdf_surface_destroy(s);
    sdf_volume_destroy(v);
}

/* Dual contouring on first-order fields: closed and manifold, and on the box (whose edges
 * and corners marching cubes chamfers by 0.3 cells) the edges come back to within 0.15. */
static void test_dual(void)
{
    method = SDF_EXTRACT_DUAL;
    run_dual_case("sphere", sphere, on_sphere, 0, 0.05);
    run_dual_case("torus", torus, on_torus, 0, 0.05);
    run_dual_case("box", box, on_box, 0, 0.15); /* marching cubes: 0.3 (distances case) */
    run_dual_case("two_spheres", two_spheres, NULL, 0, 0.5);
    run_dual_case("cut_torus", cut_torus, NULL, 1, 0.25);
    /* a zero-order box: the normals from central differences bring its edges back too */
    sdf_volume *v0 = shape_volume(box, N);
    sdf_surface *s = v0 ? extract(v0, 0, 2) : NULL;
    double se = s ? surface_error(s, on_box) : INFINITY;
    topo t = s ? topology(s) : (topo){.bad = 1};
    CHECK(se <= 0.25 && t.boundary == 0 && t.bad == 0, "zero-order box: %.3f cells", se);
    printf("  box, zero order: the surface within %.3f cells of the mesh\n", se);
    sdf_surface_destroy(s);
    sdf_volume_destroy(v0);
    sdf_extract_options o = {.method = (sdf_extract_method)7};
    sdf_diag d;
    s = NULL;
    v0 = shape_volume(sphere, 8);
    CHECK(v0 && sdf_volume_extract(v0, &o, &s, &d) == SDF_EINVAL && !s, "an unknown method");
    sdf_volume_destroy(v0);
    method = SDF_EXTRACT_AUTO;
}

/* 500 noise fields as planes (gradients from differences along the grid): topology only. */
static void test_dual_noise(void)
{
    size_t failures = 0;
    method = SDF_EXTRACT_DUAL;
    for (unsigned seed = 1; seed <= 500; seed++) {
        noise n = noise_of(seed);
        sdf_volume *v0 = noise_volume(&n, 12 + seed % 9);
        if (!v0)
            break;
        sdf_volume_info in;
        sdf_volume_get_info(v0, &in);
        size_t nodes = in.dims[0] * in.dims[1] * in.dims[2];
        const float *f = sdf_volume_data(v0);
        float *planes = calloc(4 * nodes, sizeof(float));
        for (size_t q = 0; q < nodes; q++) { /* gradients by differences along the grid */
            size_t i = q % in.dims[0], j = q / in.dims[0] % in.dims[1], k = q / in.dims[0] / in.dims[1];
            size_t idx[3] = {i, j, k}, step[3] = {1, in.dims[0], in.dims[0] * in.dims[1]};
            double d = f[q];
            for (int a = 0; a < 3; a++) {
                size_t lo = idx[a] ? q - step[a] : q, hi = idx[a] + 1 < in.dims[a] ? q + step[a] : q;
                double g = (f[hi] - f[lo]) / (in.spacing[a] * (double)((hi - lo) / step[a]));
                planes[4 * q + (size_t)a] = (float)g;
                d -= g * (in.origin[a] + (double)idx[a] * in.spacing[a]);
            }
            planes[4 * q + 3] = (float)d;
        }
        in.order = 1, in.fine_half = 1, in.fine_spacing = 0.1;
        sdf_volume *v1 = NULL;
        sdf_diag diag;
        CHECK(sdf_volume_create(&in, planes, &v1, &diag) == 0, "noise planes: %s", diag.message);
        sdf_surface *s = v1 ? extract(v1, seed % 2, 1) : NULL;
        topo t = s ? topology(s) : (topo){.bad = 1};
        if ((t.bad || (seed % 2 && t.boundary)) && failures++ < 5)
            CHECK(0, "dual noise %u: %zu boundary, %zu bad edges", seed, t.boundary, t.bad);
        sdf_surface_destroy(s);
        sdf_volume_destroy(v1);
        sdf_volume_destroy(v0);
        free(planes);
    }
    CHECK(failures == 0, "%zu of 500 dual noise fields failed", failures);
    method = SDF_EXTRACT_AUTO;
}

static void test_dual_threads(void)
{
    sdf_volume *v = plane_volume(torus, 40);
    method = SDF_EXTRACT_DUAL;
    sdf_surface *one = v ? extract(v, 1, 1) : NULL, *two = v ? extract(v, 1, 2) : NULL;
    CHECK(one && two && same_surface(one, two), "dual: the arrays differ between thread counts");
    method = SDF_EXTRACT_AUTO;
    sdf_surface_destroy(one), sdf_surface_destroy(two);
    sdf_volume_destroy(v);
}

/* ---- round trips ------------------------------------------------------------------------ */

/* Largest unsigned distance from `count` points to `mesh`. */
static double farthest(const sdf_mesh *mesh, const float *points, size_t count)
{
    float *d = malloc(count * sizeof *d + 4);
    sdf_query_options qo = {.sign = SDF_SIGN_NONE};
    sdf_query_result r = {.distance = d};
    double worst = sdf_query(mesh, points, count, &qo, &r) ? INFINITY : 0;
    for (size_t i = 0; worst < INFINITY && i < count; i++)
        worst = fmax(worst, fabs(d[i]));
    free(d);
    return worst;
}

/* Bake `file` (closed) at n^3 nodes, order 0 and 1, extract by both methods: the surface
 * closed and manifold, and the Hausdorff distance over vertices (each surface's to the mesh,
 * the mesh's to the surface) at most `bound` cells. */
static void round_trip(const char *file, size_t n, double bound)
{
    sdf_mesh *m = load_data_mesh(file);
    if (!m)
        return;
    sdf_mesh_report rep;
    sdf_mesh_get_report(m, &rep);
    for (int order = 0; order <= 1; order++) {
        sdf_bake_options bo = {.dims = {n, n, n}, .order = order};
        sdf_volume *v = NULL;
        sdf_diag d;
        CHECK(sdf_volume_bake(m, &bo, &v, &d) == 0, "%s: bake: %s", file, d.message);
        sdf_volume_info in;
        sdf_volume_get_info(v, &in);
        double cell = fmax(in.spacing[0], fmax(in.spacing[1], in.spacing[2]));
        for (method = SDF_EXTRACT_MARCHING_CUBES; v && method <= SDF_EXTRACT_DUAL; method++) {
            if (method == SDF_EXTRACT_DUAL && order == 0)
                continue;
            sdf_surface *s = extract(v, 0, 2);
            sdf_mesh *back = NULL;
            size_t nv;
            const float *p = s ? sdf_surface_vertices(s, &nv) : NULL;
            CHECK(s && sdf_surface_to_mesh(s, NULL, &back, &d) == 0, "%s: to_mesh", file);
            if (!back) {
                sdf_surface_destroy(s);
                continue;
            }
            double out = farthest(m, p, nv) / cell;
            double in_ = farthest(back, sdf_mesh_vertices(m), rep.vertices) / cell;
            topo t = topology(s);
            CHECK(out <= bound && in_ <= bound && t.boundary == 0 && t.bad == 0,
                  "%s %zu^3 order %d %s: Hausdorff %.3f / %.3f cells, %zu boundary, %zu bad",
                  file, n, order, sdf_extract_method_name(method), out, in_, t.boundary, t.bad);
            printf("  %s %zu^3 order %d %s: Hausdorff over vertices %.3f cells (surface to "
                   "mesh), %.3f (mesh to surface)\n", file, n, order,
                   sdf_extract_method_name(method), out, in_);
            sdf_mesh_release(back);
            sdf_surface_destroy(s);
        }
        method = SDF_EXTRACT_AUTO;
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(m);
}

/* The cow's horns and tail are thinner than two cells at 128^3: their tips, which no node
 * inside them samples, are 1.8 cells from the surface (docs/volumes.md). */
static void test_round_trip(void)
{
    round_trip("fandisk.off", 128, 1);
    round_trip("knot1.off", 128, 1);
    round_trip("fandisk.off", 256, 1);
    round_trip("cow.off", 128, 2);
}

static const check_case cases[] = {
    {"round_trip", test_round_trip},
    {"dual", test_dual}, {"dual_noise", test_dual_noise}, {"dual_threads", test_dual_threads},
    {"files", test_files},
    {"distances", test_distances},     {"saddle", test_saddle},
    {"noise", test_noise},             {"open_boundary", test_open_boundary},
    {"threads", test_threads},         {"first_order", test_first_order},
    {"no_crossing_and_errors", test_no_crossing_and_errors},
};

int main(int argc, char **argv)
{
    return check_main("extract", cases, CHECK_COUNT_OF(cases), argc, argv);
}
