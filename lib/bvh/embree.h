/* embree.h - the Embree 3 side of a mesh: one device and one committed triangle scene per
 * mesh (no global state), used for exact closest-point queries (rtcPointQuery with our own
 * double-precision triangle test) and for ray-crossing counts (raycast sign).
 * Embree errors are caught by the device's error callback and turned into SDF_EBVH. */
#ifndef SDF_BVH_EMBREE_H
#define SDF_BVH_EMBREE_H

#include <stddef.h>
#include <stdint.h>

#include <embree3/rtcore.h>

#include "sdf/sdf.h"

typedef struct sdf__bvh sdf__bvh;

/* The closest point found for one query. */
typedef struct sdf__hit {
    double point[3];
    double bary[3];
    double dist2;
    double face_normal[3]; /* (b - a) x (c - a) of the triangle, not normalized */
    uint32_t triangle;
    int feature; /* enum sdf__feature */
} sdf__hit;

/* Build the scene over `positions` (padded, see topology.h) and `triangles`; both must
 * outlive the bvh. */
int sdf__bvh_create(const float *positions, size_t vertex_count, const uint32_t *triangles,
                    size_t triangle_count, sdf__bvh **out, sdf_diag *diag);
void sdf__bvh_destroy(sdf__bvh *bvh);

/* The device, for building further trees (see tree.h). */
RTCDevice sdf__bvh_device(const sdf__bvh *bvh);
/* Bytes Embree holds for this mesh (device memory monitor). */
size_t sdf__bvh_memory(const sdf__bvh *bvh);
/* Did Embree report an error since creation? Returns SDF_EBVH with its message. */
int sdf__bvh_check(const sdf__bvh *bvh, sdf_diag *diag);

/* Exact closest point on the mesh to p. Thread-safe. */
void sdf__bvh_closest(const sdf__bvh *bvh, const float p[3], sdf__hit *hit);

/* Number of distinct triangles the ray origin + t * dir (t > 0) crosses. Thread-safe. */
unsigned sdf__bvh_crossings(const sdf__bvh *bvh, const float origin[3], const float dir[3]);

#endif
