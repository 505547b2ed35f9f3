/* embree.h - the Embree 3 side of a mesh: one device per mesh (no global state), which
 * builds our own tree (bvh/tree.h), and a triangle scene for the two things only Embree's
 * traversal does here: the one-rtcPointQuery-per-point path (SDF_TRAVERSAL_SINGLE, with our own
 * double-precision triangle test) and ray-crossing counts (raycast sign). Neither is the
 * default, so the scene is committed on first use (sdf__bvh_ready): it would otherwise add a
 * large share of every mesh's build time and index memory. Embree errors are caught by the
 * device's error callback and turned into SDF_EBVH. Embree's own headers are included by bvh/'s
 * .c files alone, so nothing above bvh/ depends on them. */
#ifndef SDF_BVH_EMBREE_H
#define SDF_BVH_EMBREE_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* sdf__hit */
#include "sdf/sdf.h"

typedef struct sdf__bvh sdf__bvh;

/* The device, for a scene over `positions` (padded, see topology.h) and `triangles`; both
 * must outlive the bvh. */
int sdf__bvh_create(const float *positions, size_t vertex_count, const uint32_t *triangles,
                    size_t triangle_count, sdf__bvh **out, sdf_diag *diag);
void sdf__bvh_destroy(sdf__bvh *bvh);

/* The device (Embree's RTCDevice, named by its struct so that this header needs none of
 * Embree's: they stay inside bvh/), for building further trees (tree.c). */
struct RTCDeviceTy *sdf__bvh_device(const sdf__bvh *bvh);
/* Bytes Embree holds for this mesh (device memory monitor). */
size_t sdf__bvh_memory(const sdf__bvh *bvh);
/* Did Embree report an error since creation? Returns SDF_EBVH with its message. */
int sdf__bvh_check(const sdf__bvh *bvh, sdf_diag *diag);

/* Commit the scene if no call has yet (thread-safe; concurrent callers wait for the one
 * build). 0, or SDF_EBVH if Embree failed (then every later call fails too). */
int sdf__bvh_ready(const sdf__bvh *bvh);
/* Has a call committed the scene? */
int sdf__bvh_is_ready(const sdf__bvh *bvh);

/* Exact closest point on the mesh to p, by the scene (sdf__bvh_ready first). Thread-safe. */
void sdf__bvh_closest(const sdf__bvh *bvh, const float p[3], sdf__hit *hit);

/* Number of distinct triangles the ray origin + t * dir (t > 0) crosses, by the scene
 * (sdf__bvh_ready first). Thread-safe. */
unsigned sdf__bvh_crossings(const sdf__bvh *bvh, const float origin[3], const float dir[3]);

#endif
