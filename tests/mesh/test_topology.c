/* test_topology.c - the mesh report: closedness, manifoldness, orientation, flipping of
 * inside-out meshes, degenerate triangles, volume, self-intersection, welding; and the
 * handle's reference counting and argument checks. Meshes are small hand-made ones whose
 * answers are known exactly. */
#include <math.h>
#include <string.h>

#include "../common/check.h"

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

int main(void)
{
    test_cube();
    test_inside_out();
    test_open_and_broken();
    test_self_intersection();
    test_demo_and_handles();
    return check_finish("test_topology");
}
