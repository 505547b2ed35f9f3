/* test_topology.c - the mesh report: closedness, manifoldness, orientation, flipping of
 * inside-out meshes, degenerate triangles, volume, self-intersection, welding; and the
 * handle's reference counting and argument checks. Meshes are small hand-made ones whose
 * answers are known exactly, and fandisk.off with one vertex moved, whose self-intersection
 * is decided by brute force over every pair of triangles (the tree search must agree). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/workload.h"
#include "mesh/intersect.h"
#include "mesh/mesh.h"

static const float cube_v[8 * 3] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,
                                    0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
/* Outward-oriented (counter-clockwise seen from outside). */
static const uint32_t cube_t[12 * 3] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                        1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};

static sdf_mesh *make(const float *v, size_t nv, const uint32_t *t, size_t nt, sdf_mesh_report *r)
{
    sdf_mesh *m = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_create(v, nv, t, nt, NULL, &m, &diag);
    CHECK(rc == 0, "create: %s", diag.message);
    if (m)
        sdf_mesh_get_report(m, r);
    return m;
}

static float distance_at(sdf_mesh *m, float x, float y, float z)
{
    float p[3] = {x, y, z}, d = NAN;
    sdf_query_result res = {.distance = &d};
    CHECK(sdf_query(m, p, 1, NULL, &res) == 0, "query");
    return d;
}

static void test_cube(void)
{
    sdf_mesh_report r;
    sdf_mesh *m = make(cube_v, 8, cube_t, 12, &r);
    CHECK(r.closed && r.edge_manifold && !r.flipped && !r.self_intersecting, "cube: closed %d",
          r.closed);
    CHECK(fabs(r.volume - 1) < 1e-12 && r.degenerate_triangles == 0, "cube volume %g", r.volume);
    CHECK(r.auto_sign == SDF_SIGN_PSEUDONORMAL, "cube auto sign");
    CHECK(fabs(r.diagonal - sqrt(3)) < 1e-12, "diagonal %g", r.diagonal);
    CHECK(distance_at(m, 0.5f, 0.5f, 0.5f) == -0.5f, "centre");
    CHECK(distance_at(m, 0.5f, 0.5f, 3.0f) == 2.0f, "above");
    CHECK(distance_at(m, 2, 2, 2) == (float)sqrt(3), "corner");
    /* Every sign method agrees at the centre and outside. */
    for (int s = SDF_SIGN_AUTO; s <= SDF_SIGN_RAYCAST; s++) {
        float p[6] = {0.25f, 0.5f, 0.75f, 1.5f, 0.5f, 0.5f}, d[2];
        sdf_query_options o = {.sign = (sdf_sign_method)s};
        sdf_query_result res = {.distance = d};
        CHECK(sdf_query(m, p, 2, &o, &res) == 0 && d[0] == -0.25f && d[1] == 0.5f,
              "%s: %g %g", sdf_sign_name((sdf_sign_method)s), d[0], d[1]);
    }
    sdf_mesh_release(m);
}

static void test_inside_out(void)
{
    uint32_t t[12 * 3];
    for (int i = 0; i < 12; i++) {
        t[3 * i] = cube_t[3 * i];
        t[3 * i + 1] = cube_t[3 * i + 2];
        t[3 * i + 2] = cube_t[3 * i + 1];
    }
    sdf_mesh_report r;
    sdf_mesh *m = make(cube_v, 8, t, 12, &r);
    CHECK(r.closed && r.flipped && fabs(r.volume - 1) < 1e-12, "inside-out cube: flipped %d vol %g",
          r.flipped, r.volume);
    CHECK(distance_at(m, 0.5f, 0.5f, 0.5f) == -0.5f, "inside-out cube centre still inside");
    sdf_mesh_release(m);
}

static void test_open_and_broken(void)
{
    sdf_mesh_report r;
    sdf_mesh *m = make(cube_v, 8, cube_t, 11, &r); /* one triangle missing */
    CHECK(!r.closed && r.edge_manifold && r.boundary_edges == 3 && r.auto_sign == SDF_SIGN_WINDING,
          "open cube: closed %d boundary %zu", r.closed, r.boundary_edges);
    CHECK(distance_at(m, 0.5f, 0.5f, 0.5f) < 0, "open cube centre is inside by winding number");
    sdf_mesh_release(m);

    uint32_t t[13 * 3];
    memcpy(t, cube_t, sizeof cube_t);
    uint32_t tmp = t[1]; /* misorient one triangle */
    t[1] = t[2], t[2] = tmp;
    m = make(cube_v, 8, t, 12, &r);
    CHECK(!r.closed && r.misoriented_edges == 3 && r.boundary_edges == 0, "misoriented: %zu",
          r.misoriented_edges);
    sdf_mesh_release(m);

    memcpy(t, cube_t, sizeof cube_t); /* a third triangle on edge 0-1 */
    float v[9 * 3];
    memcpy(v, cube_v, sizeof cube_v);
    v[24] = 0.5f, v[25] = -1, v[26] = -1;
    t[36] = 0, t[37] = 1, t[38] = 8;
    m = make(v, 9, t, 13, &r);
    CHECK(!r.closed && !r.edge_manifold && r.nonmanifold_edges == 1, "non-manifold: %zu",
          r.nonmanifold_edges);
    sdf_mesh_release(m);

    memcpy(t, cube_t, sizeof cube_t); /* a zero-area triangle and one with a repeated corner */
    uint32_t deg[6] = {0, 1, 1, 0, 1, 2};
    v[24] = 2, v[25] = 0, v[26] = 0; /* collinear with 0 and 1 */
    uint32_t t2[14 * 3];
    memcpy(t2, cube_t, sizeof cube_t);
    memcpy(t2 + 36, deg, sizeof deg);
    t2[41] = 8;
    m = make(v, 9, t2, 14, &r);
    CHECK(r.degenerate_triangles == 2, "degenerate: %zu", r.degenerate_triangles);
    CHECK(distance_at(m, 3, 0, 0) == 1.0f, "distance to a degenerate triangle's segment");
    sdf_mesh_release(m);
}

/* Two cubes, the second shifted by `shift`: each closed, together closed; crossing or not. */
static sdf_mesh *two_cubes(const float shift[3], sdf_mesh_report *r)
{
    float v[16 * 3];
    uint32_t t[24 * 3];
    memcpy(v, cube_v, sizeof cube_v);
    memcpy(t, cube_t, sizeof cube_t);
    for (int i = 0; i < 24; i++)
        v[24 + i] = cube_v[i] + shift[i % 3];
    for (int i = 0; i < 36; i++)
        t[36 + i] = cube_t[i] + 8;
    return make(v, 16, t, 24, r);
}

static void test_self_intersection(void)
{
    /* A generic overlap, and a symmetric one where every crossing lies on an edge. */
    const float shifts[3][3] = {{0.5f, 0.37f, 0.29f}, {0.5f, 0.5f, 0.5f}, {0.5f, 0, 0}};
    sdf_mesh_report r;
    for (int i = 0; i < 3; i++) {
        sdf_mesh *m = two_cubes(shifts[i], &r);
        CHECK(r.closed && r.self_intersecting && r.auto_sign == SDF_SIGN_WINDING,
              "overlapping cubes %d: closed %d self-intersecting %d", i, r.closed,
              r.self_intersecting);
        sdf_mesh_release(m);
    }
    /* Apart, they do not cross. */
    const float apart[3] = {2, 2, 2};
    sdf_mesh *m = two_cubes(apart, &r);
    CHECK(r.closed && !r.self_intersecting && r.auto_sign == SDF_SIGN_PSEUDONORMAL,
          "separate cubes: self-intersecting %d", r.self_intersecting);
    sdf_mesh_release(m);
}

/* Does segment pq cross triangle abc? The plane's crossing point, then its barycentric
 * coordinates: a different construction from the library's orientation tests, and exact
 * enough away from touching contacts, which randomly moved vertices do not make. */
static int ref_segment_crosses(const double p[3], const double q[3], const double *a,
                               const double *b, const double *c)
{
    double u[3], v[3], n[3], d[3], ap[3];
    for (int i = 0; i < 3; i++)
        u[i] = b[i] - a[i], v[i] = c[i] - a[i], d[i] = q[i] - p[i], ap[i] = a[i] - p[i];
    n[0] = u[1] * v[2] - u[2] * v[1], n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    double along = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    if (along == 0)
        return 0; /* parallel to the plane */
    double t = (n[0] * ap[0] + n[1] * ap[1] + n[2] * ap[2]) / along;
    if (t < 0 || t > 1)
        return 0;
    double w[3];
    for (int i = 0; i < 3; i++)
        w[i] = p[i] + t * d[i] - a[i];
    double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    double uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    double wu = w[0] * u[0] + w[1] * u[1] + w[2] * u[2];
    double wv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
    double den = uu * vv - uv * uv, s = (vv * wu - uv * wv) / den, r = (uu * wv - uv * wu) / den;
    return s >= 0 && r >= 0 && s + r <= 1;
}

/* Do triangles i and j (sharing no vertex) of the array mesh cross? Some edge of one
 * crosses the other. */
static int ref_triangles_cross(const float *pos, const uint32_t *tri, size_t i, size_t j)
{
    double c[2][3][3];
    const size_t t[2] = {i, j};
    for (int s = 0; s < 2; s++)
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                c[s][k][a] = pos[3 * (size_t)tri[3 * t[s] + k] + a];
    for (int s = 0; s < 2; s++)
        for (int k = 0; k < 3; k++)
            if (ref_segment_crosses(c[s][k], c[s][(k + 1) % 3], c[1 - s][0], c[1 - s][1],
                                    c[1 - s][2]))
                return 1;
    return 0;
}

/* Each triangle's box: lo xyz, hi xyz. */
static float *triangle_boxes(const float *pos, const uint32_t *tri, size_t nt)
{
    float *box = malloc(6 * nt * sizeof *box);
    for (size_t t = 0; box && t < nt; t++)
        for (int a = 0; a < 3; a++) {
            box[6 * t + a] = INFINITY, box[6 * t + 3 + a] = -INFINITY;
            for (int k = 0; k < 3; k++) {
                float x = pos[3 * (size_t)tri[3 * t + k] + a];
                box[6 * t + a] = fminf(box[6 * t + a], x);
                box[6 * t + 3 + a] = fmaxf(box[6 * t + 3 + a], x);
            }
        }
    return box;
}

static int boxes_apart(const float *box, size_t i, size_t j)
{
    const float *a = box + 6 * i, *b = box + 6 * j;
    return a[3] < b[0] || b[3] < a[0] || a[4] < b[1] || b[4] < a[1] || a[5] < b[2] ||
           b[5] < a[2];
}

static int share_vertex(const uint32_t *tri, size_t i, size_t j)
{
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            if (tri[3 * i + a] == tri[3 * j + b])
                return 1;
    return 0;
}

/* Brute force: does any triangle in `touched` (or, with touched NULL, any at all) cross
 * another triangle it shares no vertex with? */
static int ref_self_intersects(const float *pos, const uint32_t *tri, size_t nt,
                               const uint8_t *touched)
{
    float *box = triangle_boxes(pos, tri, nt);
    int found = 0;
    for (size_t i = 0; box && i < nt && !found; i++) {
        if (touched && !touched[i])
            continue;
        for (size_t j = touched ? 0 : i + 1; j < nt && !found; j++)
            found = j != i && (!touched || !touched[j] || j > i) && !boxes_apart(box, i, j) &&
                    !share_vertex(tri, i, j) && ref_triangles_cross(pos, tri, i, j);
    }
    CHECK(box != NULL, "out of memory");
    free(box);
    return found;
}

/* fandisk.off does not cross itself; moving one vertex by a random step (1e-2.5 to 1e-0.5 of
 * the diagonal) sometimes makes its triangles cross others. Each variant's report must say
 * what brute force over its triangles' pairs says, and both answers must turn up. */
static void test_self_intersection_brute_force(void)
{
    sdf_mesh *base = load_data_mesh("fandisk.off");
    if (!base)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(base, &r);
    size_t nv = r.vertices, nt = r.triangles;
    float *pos = malloc(3 * nv * sizeof *pos);
    uint32_t *tri = malloc(3 * nt * sizeof *tri);
    uint8_t *touched = malloc(nt);
    memcpy(tri, base->triangles, 3 * nt * sizeof *tri);
    CHECK(!r.self_intersecting && !ref_self_intersects(base->positions, tri, nt, NULL),
          "fandisk should not cross itself (report %d)", r.self_intersecting);
    sdf_rng rng = {2024};
    int agreed[2] = {0, 0};
    for (int trial = 0; trial < 40; trial++) {
        memcpy(pos, base->positions, 3 * nv * sizeof *pos);
        uint32_t v = (uint32_t)(sdf_rng_next(&rng) % nv);
        double step = r.diagonal * pow(10, -2.5 + 2 * sdf_rng_uniform(&rng));
        double dir[3], len = 0;
        for (int a = 0; a < 3; a++)
            dir[a] = sdf_rng_normal(&rng), len += dir[a] * dir[a];
        for (int a = 0; a < 3; a++)
            pos[3 * v + a] += (float)(step * dir[a] / sqrt(len));
        for (size_t t = 0; t < nt; t++)
            touched[t] = tri[3 * t] == v || tri[3 * t + 1] == v || tri[3 * t + 2] == v;
        int expected = ref_self_intersects(pos, tri, nt, touched);
        sdf_mesh *m = make(pos, nv, tri, nt, &r);
        if (!m)
            break;
        CHECK(r.closed && r.self_intersecting == expected,
              "fandisk, vertex %u moved %g: self-intersecting %d, brute force %d", v, step,
              r.self_intersecting, expected);
        agreed[expected] += r.self_intersecting == expected;
        sdf_mesh_release(m);
    }
    CHECK(agreed[0] > 0 && agreed[1] > 0, "moved vertices: %d crossing and %d clean agreed",
          agreed[1], agreed[0]);
    printf("self-intersection vs brute force: %d crossing, %d clean variants agreed\n", agreed[1],
           agreed[0]);
    free(pos), free(tri), free(touched);
    sdf_mesh_release(base);
}

/* Soups of small random triangles, sharing no vertex, in a unit cube: a few pairs cross in
 * about half of them. The tree search (called directly: a soup is open, and the report
 * only searches closed meshes) must agree with brute force in every soup, wherever in the
 * tree's leaves the crossing pair lies. */
static void test_self_intersection_soups(void)
{
    enum { SOUPS = 400, TRIANGLES = 240 };
    const double LONG = 0.04, SMALL = 0.005; /* sliver length and corner spread */
    sdf_rng rng = {77};
    float pos[9 * TRIANGLES];
    uint32_t tri[3 * TRIANGLES];
    for (uint32_t i = 0; i < 3 * TRIANGLES; i++)
        tri[i] = i;
    int agreed[2] = {0, 0};
    for (int soup = 0; soup < SOUPS; soup++) {
        for (int t = 0; t < TRIANGLES; t++) {
            /* Half of them long slivers, which cross triangles in other leaves. */
            double c[3], along[3], len = t % 2 ? LONG : 0;
            for (int a = 0; a < 3; a++)
                c[a] = sdf_rng_uniform(&rng), along[a] = len * sdf_rng_normal(&rng);
            for (int k = 0; k < 3; k++)
                for (int a = 0; a < 3; a++)
                    pos[9 * t + 3 * k + a] =
                        (float)(c[a] + (k - 1) * along[a] + SMALL * sdf_rng_normal(&rng));
        }
        int expected = ref_self_intersects(pos, tri, TRIANGLES, NULL);
        sdf_mesh_report r;
        sdf_mesh *m = make(pos, 3 * TRIANGLES, tri, TRIANGLES, &r);
        if (!m)
            break;
        int found = sdf__self_intersects(&m->tree, m->positions, m->triangles);
        CHECK(found == expected, "soup %d: the tree search says %d, brute force %d", soup, found,
              expected);
        agreed[expected] += found == expected;
        sdf_mesh_release(m);
    }
    CHECK(agreed[0] > SOUPS / 10 && agreed[1] > SOUPS / 10,
          "soups: %d crossing and %d clean agreed", agreed[1], agreed[0]);
    printf("self-intersection of soups vs brute force: %d crossing, %d clean agreed\n", agreed[1],
           agreed[0]);
}

static void test_demo_and_handles(void)
{
    sdf_mesh *m;
    CHECK(sdf_mesh_create_demo(&m) == 0, "demo");
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    CHECK(r.closed && r.edge_manifold && !r.flipped && !r.self_intersecting &&
              r.degenerate_triangles == 0 && r.triangles == 12288,
          "demo: closed %d manifold %d flipped %d self-x %d", r.closed, r.edge_manifold, r.flipped,
          r.self_intersecting);
    /* A tube along the trefoil ((2 + cos 3t) cos 2t, (2 + cos 3t) sin 2t, sin 3t) with a
     * 12-gon cross-section of circumradius 0.35 (area 3 r^2): volume ~ 3 r^2 L. */
    double length = 0;
    for (int i = 0; i < 100000; i++) {
        double t0 = 2 * M_PI * i / 100000, t1 = 2 * M_PI * (i + 1) / 100000, dx[3];
        dx[0] = (2 + cos(3 * t1)) * cos(2 * t1) - (2 + cos(3 * t0)) * cos(2 * t0);
        dx[1] = (2 + cos(3 * t1)) * sin(2 * t1) - (2 + cos(3 * t0)) * sin(2 * t0);
        dx[2] = sin(3 * t1) - sin(3 * t0);
        length += sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2]);
    }
    double expected = 3 * 0.35 * 0.35 * length;
    CHECK(fabs(r.volume - expected) < 0.02 * expected, "demo volume %g, expected ~%g", r.volume,
          expected);
    CHECK(r.index_bytes > 0 && r.build_seconds > 0, "demo report");
    CHECK(sdf_mesh_retain(m) == m, "retain");
    sdf_mesh_release(m);
    CHECK(distance_at(m, 3, 0, 0) < 0, "demo still alive after one release; (3,0,0) is on the knot");
    sdf_mesh_release(m);
    sdf_mesh_release(NULL);

    sdf_mesh *out = (sdf_mesh *)1;
    uint32_t bad[3] = {0, 1, 9};
    sdf_diag diag;
    CHECK(sdf_mesh_create(cube_v, 8, bad, 1, NULL, &out, &diag) == SDF_EINDEX && out == NULL,
          "out-of-range index accepted");
    CHECK(sdf_mesh_create(cube_v, 8, cube_t, 0, NULL, &out, &diag) == SDF_EEMPTY, "no triangles");
    float nan_v[8 * 3];
    memcpy(nan_v, cube_v, sizeof nan_v);
    nan_v[5] = NAN;
    CHECK(sdf_mesh_create(nan_v, 8, cube_t, 12, NULL, &out, &diag) == SDF_ENONFINITE,
          "NaN vertex accepted");
    CHECK(sdf_mesh_create(NULL, 8, cube_t, 12, NULL, &out, &diag) == SDF_EINVAL, "NULL vertices");
    CHECK(sdf_mesh_load_memory(NULL, 5, NULL, &out, &diag) == SDF_EINVAL, "NULL data");
}

static const check_case cases[] = {
    {"cube", test_cube},
    {"inside_out", test_inside_out},
    {"open_and_broken", test_open_and_broken},
    {"self_intersection", test_self_intersection},
    {"self_intersection_brute_force", test_self_intersection_brute_force},
    {"self_intersection_soups", test_self_intersection_soups},
    {"demo_and_handles", test_demo_and_handles},
};

int main(int argc, char **argv)
{
    return check_main("topology", cases, CHECK_COUNT_OF(cases), argc, argv);
}
