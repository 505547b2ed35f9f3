/* mesh.h - the inside of an sdf_mesh, shared by the modules that build and query it.
 * Everything here is immutable once sdf__mesh_build returns, so queries need no locks. */
#ifndef SDF_MESH_MESH_H
#define SDF_MESH_MESH_H

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
    struct sdf__bvh *bvh;  /* Embree's scene: closest points and rays */
    sdf__tree tree;        /* our own BVH: packets, winding numbers, self-intersection */
    struct sdf__pseudonormals *normals;
    struct sdf__winding *winding;
};

/* Take ownership of a triangle soup (positions with 3 floats per vertex, 0-based triangle
 * indices already checked < vertex_count) and build the full mesh: weld, analyse, orient,
 * BVHs and sign data. Frees `positions` and `triangles` in all cases. */
int sdf__mesh_build(float *positions, size_t vertex_count, uint32_t *triangles,
                    size_t triangle_count, sdf_format format, sdf_mesh **out, sdf_diag *diag);

#endif
