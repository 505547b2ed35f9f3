/* cluster.h - closest triangles of a cluster of nearby points from one candidate list.
 *
 * The filtered field asks for the distances of many samples around each query point p
 * (convolution paper, eq. 10), each bounded by |f(p)| + |x - p| since f is 1-Lipschitz.
 * Traversing the tree once per packet of samples (sec. 3, "packet sampling") still walks
 * ~40 nodes per packet. Instead, one walk gathers every triangle that can be closest to any
 * point of the cluster: a point x with bound B is closest to a triangle within B of x, so
 * within B + |x - c| of the cluster's centre c. The candidates are sorted by their distance
 * D from c, and each group of eight points tests them in that order with the float lane
 * test (lanes.h) until D - |x - c| (a lower bound of x's distance to the rest) exceeds
 * every point's best so far.
 *
 * The float test picks each point's winner; its closest point comes from the exact double
 * test (triangle.h) on that one triangle. So a distance is exact for the triangle named,
 * and that triangle is closest up to float rounding of the distances compared (~1e-6 of the
 * triangle's size): where two triangles tie that closely, the one named may differ from
 * sdf_query's. A caller may take the float distance instead, and skip the exact test where
 * it needs no closest point (the filtered field's samples whose sign is known), except very
 * near the surface, where float rounding is large next to the distance. */
#ifndef SDF_POINTS_CLUSTER_H
#define SDF_POINTS_CLUSTER_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* sdf__hit */
#include "bvh/tree.h"

#define SDF__CLUSTER_MAX 64 /* points of one cluster, at most */

/* What a point's hit holds. */
enum sdf__cluster_want {
    SDF__CLUSTER_EXACT,       /* the exact test's closest point and distance */
    SDF__CLUSTER_FLOAT,       /* the float distance (squared) and the triangle; nothing else */
    SDF__CLUSTER_FLOAT_POINT, /* the float distance, and the exact test's closest point */
    /* (both exact within 256e-6 x extent of the surface: cluster.c, FLOAT_DISTANCE_MIN) */
};

/* Scratch for clusters with up to `capacity` candidate triangles (one per thread). */
typedef struct sdf__cluster sdf__cluster;

/* Returns NULL when out of memory. */
sdf__cluster *sdf__cluster_create(int capacity);
/* The bytes sdf__cluster_create(capacity) allocates. */
size_t sdf__cluster_bytes(int capacity);
void sdf__cluster_destroy(sdf__cluster *cluster);

/* Closest points of `n` (1..SDF__CLUSTER_MAX) points (xyz floats `stride` bytes apart)
 * whose distances are at most bound[i], over the mesh's `tree`; `extent` is the mesh's
 * bounding-box diagonal (the scale of float rounding). Returns 0 with hits[i] filled
 * (dist2 == INFINITY: no candidate held point i after rounding; ask again), or -1 when more
 * triangles than the capacity could be closest: the caller then answers the points another
 * way. want[i] (NULL: all SDF__CLUSTER_EXACT) says what hits[i] must hold. */
int sdf__cluster_closest(sdf__cluster *cluster, const sdf__tree *tree, const float *positions,
                         const uint32_t *triangles, float extent, const char *points,
                         size_t stride, const double *bound, const uint8_t *want, int n,
                         sdf__hit *hits);

#endif
