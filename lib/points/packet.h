/* packet.h - coherent packet traversal for batched closest-point queries.
 *
 * Sec. 3 of the convolution paper ("packet sampling"): nearby queries go through the same
 * branches of the tree, so they are grouped and the tree is traversed once for all of them.
 * Three levers, in order of payoff (docs/design.md):
 *  1. bounds: no search starts at infinity. Points are visited in Morton order, and a
 *     point's search radius starts at min(d_prev + |p - p_prev|, |p - c_prev|), an upper
 *     bound of its distance by the triangle inequality (p_prev: the last point answered
 *     before its packet, d_prev its distance, c_prev its closest point, on the surface);
 *  2. packets: SDF__PACKET consecutive points traverse the mesh's BVH (bvh/tree.h) together;
 *     a node is skipped only when it is farther than every point's current bound;
 *  3. data layout: the packet's coordinates are SoA arrays, so the per-node box tests and
 *     a branchless float point-triangle distance run on eight lanes at once (GCC vector
 *     types, no intrinsics: points/lanes.h; AVX2 clones where the CPU has it, core/simd.h),
 *     and a triangle is tested only in the groups with a lane near its box.
 * The float distances only choose candidates: every triangle within a rounding margin of a
 * lane's best float distance gets the same exact double-precision test as the single-point
 * path (geom/triangle.c), so distances are identical to it; only exact ties may name a
 * different (equally close) triangle. */
#ifndef SDF_POINTS_PACKET_H
#define SDF_POINTS_PACKET_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* sdf__hit */
#include "bvh/tree.h"

#define SDF__PACKET 32

typedef struct sdf__packet {
    int n;                                     /* points 1..SDF__PACKET; lanes past n hold
                                                  copies of the last (padding, ignored) */
    float x[SDF__PACKET], y[SDF__PACKET], z[SDF__PACKET];
    double bound2[SDF__PACKET];                /* in: upper bounds of squared distances */
} sdf__packet;

/* Closest points of a packet's points over `tree`; `extent` is the mesh's bounding-box
 * diagonal (the scale of float rounding). Candidates are found with a float test on all
 * lanes at once and decided by the exact double test (geom/triangle.c). A point the packet
 * could not decide (a bound rounding made too small, or more near-equal candidates than it
 * holds) comes back with hit.dist2 == INFINITY and must be asked again (sdf__closest_exact). */
void sdf__closest_packet(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                         float extent, sdf__packet *pk, sdf__hit *hits);

/* The closest point to p over `tree` by one walk of it, a leaf's triangles tested together in
 * float (eight lanes, one triangle each; the same candidates rule and exact decision as
 * packets), starting from bound2 (an upper bound of the squared distance, or INFINITY). Gives
 * the same distance as sdf__closest_exact, or hit->dist2 == INFINITY when the point must be
 * asked again (as sdf__closest_packet). */
void sdf__closest_point(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        float extent, const float p[3], double bound2, sdf__hit *hit);

/* The closest point to p over `tree` by the exact double test alone (geom/triangle.c: every
 * triangle whose box is as near as the best so far), with the searches' tie rule: slow and
 * always decided. It answers the rare points the float searches hand back. */
void sdf__closest_exact(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        const float p[3], sdf__hit *hit);

#endif
