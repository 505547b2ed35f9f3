/* mesh.h - the inside of an sdf_mesh, shared by the modules that build and query it.
 * Everything here is immutable once sdf__mesh_build returns, so queries need no locks,
 * except two caches made on first use under the mesh's mutex and never changed after:
 * Embree's scene (bvh/embree.h) and, on meshes that `auto` signs by pseudonormals, the
 * winding-number moments (sdf__mesh_need_winding). */
#ifndef SDF_MESH_MESH_H
#define SDF_MESH_MESH_H

#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "bvh/tree.h"
#include "sdf/sdf.h"

struct sdf__bvh;
struct sdf__pseudonormals;
struct sdf__winding;

struct sdf_mesh {
    atomic_int refs;
    float *positions;     /* 3 per welded vertex, plus padding for Embree */
    uint32_t *triangles;  /* 3 per triangle, outward-oriented when closed */
    uint32_t *edge_of;    /* 3 per triangle: edge ids (see topology.h) */
    size_t edge_count;
    sdf_mesh_report report;
    float surface_epsilon; /* float resolution at the mesh's scale: "on the surface" */
    struct sdf__bvh *bvh;  /* Embree's device, and its scene for rays and single queries */
    sdf__tree tree;        /* our own BVH: packets, winding numbers, self-intersection */
    struct sdf__pseudonormals *normals;
    _Atomic(struct sdf__winding *) winding; /* sdf__mesh_winding: NULL until needed */
    pthread_mutex_t lazy;  /* held while the winding moments are made */
    int lazy_rc;           /* their first build's error, kept: it is not retried */
};

/* Take ownership of a triangle soup (positions with 3 floats per vertex, 0-based triangle
 * indices already checked < vertex_count) and build the full mesh: weld, analyse, orient,
 * BVHs and sign data (on a second thread beside the caller's for part of it). Frees
 * `positions` and `triangles` in all cases. */
int sdf__mesh_build(float *positions, size_t vertex_count, uint32_t *triangles,
                    size_t triangle_count, sdf_format format, sdf_mesh **out, sdf_diag *diag);

/* Make the winding-number moments if no call has yet (thread-safe: concurrent callers wait
 * for the one build). Every query that signs by winding numbers calls it first. Meshes that
 * `auto` signs by winding numbers have them from the build. 0 or SDF_ENOMEM. */
int sdf__mesh_need_winding(const sdf_mesh *mesh);

/* An upper bound of the bytes the first query signed by `sign` adds to the mesh (what is
 * made on first use and not made yet): the winding-number moments, or Embree's scene. */
size_t sdf__mesh_first_use_bound(const sdf_mesh *mesh, sdf_sign_method sign);

/* The moments, after sdf__mesh_need_winding succeeded. */
static inline const struct sdf__winding *sdf__mesh_winding(const sdf_mesh *mesh)
{
    return atomic_load_explicit(&((sdf_mesh *)mesh)->winding, memory_order_acquire);
}

#endif
