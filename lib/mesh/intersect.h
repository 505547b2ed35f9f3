/* intersect.h - does a mesh intersect itself?
 *
 * The pseudonormal sign is only valid on closed meshes that do not self-intersect
 * (Baerentzen & Aanaes 2005); real "closed" files such as cow.off do, and pseudonormals then
 * get whole regions wrong. So `auto` needs this answer at load time. A dual traversal of
 * the BVH visits pairs of overlapping nodes; in overlapping leaves, two triangles that share
 * no vertex intersect exactly when an edge of one meets the other (orientation tests in
 * double precision; touching counts). Coplanar overlaps and pairs sharing a vertex are not
 * reported. The
 * search stops at the first intersection found. */
#ifndef SDF_MESH_INTERSECT_H
#define SDF_MESH_INTERSECT_H

#include <stdint.h>

#include "bvh/tree.h"

/* 1 if two vertex-disjoint triangles intersect, 0 if none do, SDF_ENOMEM on failure. */
int sdf__self_intersects(const sdf__tree *tree, const float *positions, const uint32_t *triangles);

#endif
