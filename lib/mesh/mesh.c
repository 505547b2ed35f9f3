/* mesh.c - the sdf_mesh handle: building the index from a triangle soup, sharing it
 * (retain/release) and reporting on it.
 *
 * The build is a fixed graph of named steps: weld; then, side by side, build our own tree
 * (with Embree's builder, on the caller's thread) and analyse the edges; orient (flip a
 * closed inside-out mesh, which needs both done: the tree reads the corners the flip swaps);
 * then, side by side, the pseudonormals and the search for self-intersections (they decide
 * what `auto` signs with); last the winding-number moments where `auto` needs them. Each pair
 * runs on its own thread and the caller's because neither step is parallel throughout (a
 * sequential part of one fills the core the other leaves idle). Every step is always done, so
 * any sign method can be asked for on any mesh and the mesh is immutable (hence lock-free)
 * once built. Two caches are the exceptions, made on first use and not counted in the
 * report's index bytes: Embree's own scene, which only the raycast sign and
 * SDF_TRAVERSAL_SINGLE use (bvh/embree.h), and, on meshes that `auto` signs by pseudonormals,
 * the winding-number moments (22 bytes per triangle). */
#include "mesh/mesh.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "bvh/embree.h"
#include "core/diag.h"
#include "mesh/intersect.h"
#include "mesh/topology.h"
#include "sign/pseudonormal.h"
#include "sign/winding.h"

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void mesh_free(sdf_mesh *m)
{
    sdf__winding_destroy(atomic_load(&m->winding));
    pthread_mutex_destroy(&m->lazy);
    sdf__pseudonormals_destroy(m->normals);
    sdf__tree_free(&m->tree);
    sdf__bvh_destroy(m->bvh);
    free(m->edge_of);
    free(m->triangles);
    free(m->positions);
    free(m);
}

/* What the steps hand on to later ones, beside the mesh itself. */
typedef struct build {
    sdf_mesh *m;
    sdf__edge_faces faces; /* from the edge analysis, for the pseudonormals */
} build;

static int step_weld(sdf_mesh *m, float *soup, size_t soup_vertices)
{
    m->report.input_vertices = soup_vertices;
    return sdf__weld(soup, soup_vertices, m->triangles, m->report.triangles, &m->positions,
                     &m->report.vertices);
}

static int step_analyse(build *b, sdf_diag *diag)
{
    sdf_mesh *m = b->m;
    int rc = sdf__analyse(m->positions, m->triangles, m->report.triangles, &m->edge_of,
                          &m->edge_count, &b->faces, &m->report);
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "out of memory for %zu triangles",
                             m->report.triangles);
    return 0;
}

static int step_trees(build *b, sdf_diag *diag)
{
    sdf_mesh *m = b->m;
    sdf_mesh_report *r = &m->report;
    int rc = sdf__bvh_create(m->positions, r->vertices, m->triangles, r->triangles, &m->bvh, diag);
    if (rc)
        return rc;
    rc = sdf__tree_build(m->bvh, m->positions, m->triangles, r->triangles, 8,
                         &m->tree);
    if (!rc)
        rc = sdf__bvh_check(m->bvh, diag);
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "building the BVH failed: %s", sdf_strerror(rc));
    return 0;
}

static void step_orient(sdf_mesh *m)
{
    sdf_mesh_report *r = &m->report;
    if (r->closed && r->volume < 0) {
        sdf__flip(m->triangles, m->edge_of, r->triangles);
        r->volume = -r->volume;
        r->flipped = 1;
    }
    /* "On the surface": within a few float ulps of the mesh's largest coordinate. */
    float extent = 0;
    for (int i = 0; i < 3; i++) {
        extent = fabsf(r->bbox_min[i]) > extent ? fabsf(r->bbox_min[i]) : extent;
        extent = fabsf(r->bbox_max[i]) > extent ? fabsf(r->bbox_max[i]) : extent;
    }
    m->surface_epsilon = 4 * FLT_EPSILON * (extent > 0 ? extent : 1);
}

static int step_pseudonormals(build *b, sdf_diag *diag)
{
    sdf_mesh *m = b->m;
    int rc = sdf__pseudonormals_create(m->positions, m->report.vertices, m->triangles,
                                       m->report.triangles, b->faces.start, b->faces.face,
                                       m->edge_count, &m->normals);
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "out of memory for the sign data");
    return 0;
}

/* A step on a thread of its own while the caller's thread does another. */
typedef struct side_step {
    int (*run)(build *b, sdf_diag *diag);
    build *b;
    sdf_diag diag;
    int rc, started;
    pthread_t thread;
} side_step;

static void *side_main(void *arg)
{
    side_step *s = arg;
    s->rc = s->run(s->b, &s->diag);
    return NULL;
}

static void side_start(side_step *s, int (*run)(build *, sdf_diag *), build *b)
{
    *s = (side_step){.run = run, .b = b};
    s->started = pthread_create(&s->thread, NULL, side_main, s) == 0;
}

/* Waits for the step (or, when no thread could start, runs it here); returns its code,
 * with its message in *diag unless `first_rc` (the caller's own step's) already failed. */
static int side_finish(side_step *s, int first_rc, sdf_diag *diag)
{
    if (s->started)
        pthread_join(s->thread, NULL);
    else
        s->rc = s->run(s->b, &s->diag);
    if (first_rc)
        return first_rc;
    if (s->rc && diag)
        *diag = s->diag;
    return s->rc;
}

/* Pseudonormals are only a valid sign on closed meshes that do not cross themselves. */
static int step_choose_sign(sdf_mesh *m, sdf_diag *diag)
{
    sdf_mesh_report *r = &m->report;
    if (r->closed) {
        int found = sdf__self_intersects(&m->tree, m->positions, m->triangles);
        if (found < 0)
            return sdf__diag_set(diag, found, 0, -1, "out of memory searching self-intersections");
        r->self_intersecting = found;
    }
    r->auto_sign = r->closed && !r->self_intersecting ? SDF_SIGN_PSEUDONORMAL : SDF_SIGN_WINDING;
    return 0;
}

static int step_sign_data(sdf_mesh *m, sdf_diag *diag)
{
    sdf_mesh_report *r = &m->report;
    int rc = 0;
    if (r->auto_sign == SDF_SIGN_WINDING) /* what the default sign needs, now */
        rc = sdf__mesh_need_winding(m);
    if (rc)
        return sdf__diag_set(diag, rc, 0, -1, "out of memory for the sign data");
    r->index_bytes = sdf__bvh_memory(m->bvh) + m->normals->bytes +
                     sdf__winding_bytes(sdf__mesh_winding(m)) +
                     3 * r->triangles * sizeof(uint32_t) +
                     m->tree.node_count * (sizeof(sdf__tree_node) + sizeof(sdf__tree_disc)) +
                     m->tree.prim_count * sizeof(uint32_t) +
                     m->tree.wide.count * sizeof(sdf__wide_node);
    return 0;
}

/* Embree's scene holds ~67 bytes a triangle once built (docs/performance.md); its builder's
 * peak is Embree's own and not counted by us, so three times that is allowed for. */
#define EMBREE_SCENE_BYTES_PER_TRIANGLE 200

size_t sdf__mesh_first_use_bound(const sdf_mesh *m, sdf_sign_method sign)
{
    if (sign == SDF_SIGN_AUTO)
        sign = m->report.auto_sign;
    if (sign == SDF_SIGN_WINDING && !sdf__mesh_winding(m))
        return sdf__winding_build_bytes(m->tree.node_count);
    if (sign == SDF_SIGN_RAYCAST && !sdf__bvh_is_ready(m->bvh))
        return EMBREE_SCENE_BYTES_PER_TRIANGLE * m->report.triangles;
    return 0;
}

int sdf__mesh_need_winding(const sdf_mesh *cm)
{
    sdf_mesh *m = (sdf_mesh *)cm; /* the moments are a cache: making them is not a change */
    if (sdf__mesh_winding(m))
        return 0;
    pthread_mutex_lock(&m->lazy);
    if (!atomic_load_explicit(&m->winding, memory_order_relaxed) && !m->lazy_rc) {
        sdf__winding *w = NULL;
        m->lazy_rc = sdf__winding_create(&m->tree, m->positions, m->triangles, &w);
        if (!m->lazy_rc)
            atomic_store_explicit(&m->winding, w, memory_order_release);
    }
    int rc = m->lazy_rc;
    pthread_mutex_unlock(&m->lazy);
    return rc;
}

int sdf__mesh_build(float *positions, size_t vertex_count, uint32_t *triangles,
                    size_t triangle_count, sdf_format format, sdf_mesh **out, sdf_diag *diag)
{
    double start = now_seconds();
    *out = NULL;
    sdf_mesh *m = calloc(1, sizeof *m);
    if (!m) {
        free(positions);
        free(triangles);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory");
    }
    atomic_init(&m->refs, 1);
    if (pthread_mutex_init(&m->lazy, NULL)) {
        free(m);
        free(positions);
        free(triangles);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of resources for a mutex");
    }
    m->triangles = triangles;
    m->report.triangles = triangle_count;
    m->report.format = format;
    build b = {.m = m};
    int rc = step_weld(m, positions, vertex_count);
    free(positions);
    if (rc == SDF_ENOMEM)
        sdf__diag_set(diag, rc, 0, -1, "out of memory for %zu triangles", triangle_count);
    side_step side;
    if (!rc) {
        /* The trees on the caller's thread: Embree keeps a per-thread allocator (sdf.h) for
         * every thread that ever builds, so a fresh side thread each time would grow it. */
        side_start(&side, step_analyse, &b);
        rc = side_finish(&side, step_trees(&b, diag), diag);
    }
    if (!rc) {
        step_orient(m);
        side_start(&side, step_pseudonormals, &b);
        rc = side_finish(&side, step_choose_sign(m, diag), diag);
    }
    sdf__edge_faces_free(&b.faces);
    if (!rc)
        rc = step_sign_data(m, diag);
    if (rc) {
        mesh_free(m);
        return rc;
    }
    m->report.build_seconds = now_seconds() - start;
    *out = m;
    return 0;
}

sdf_mesh *sdf_mesh_retain(sdf_mesh *mesh)
{
    if (mesh)
        atomic_fetch_add(&mesh->refs, 1);
    return mesh;
}

void sdf_mesh_release(sdf_mesh *mesh)
{
    if (mesh && atomic_fetch_sub(&mesh->refs, 1) == 1)
        mesh_free(mesh);
}

void sdf_mesh_get_report(const sdf_mesh *mesh, sdf_mesh_report *out) { *out = mesh->report; }

const float *sdf_mesh_vertices(const sdf_mesh *mesh) { return mesh->positions; }

const uint32_t *sdf_mesh_triangles(const sdf_mesh *mesh) { return mesh->triangles; }
