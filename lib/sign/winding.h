/* winding.h - fast generalized winding numbers.
 *
 * The generalized winding number (Jacobson et al. 2013) of a point q is the sum of the
 * solid angles the triangles subtend at q, over 4 pi: 1 inside a closed outward-oriented
 * mesh, 0 outside, and a smooth fractional value near holes, which is what makes signs on
 * open and defective meshes usable ("inside" = w > 1/2).
 *
 * Evaluated hierarchically after Barill et al. 2018 ("Fast winding numbers for soups and
 * clouds"): over the mesh's BVH (tree.h), a node whose expansion centre p~ is farther than
 * beta * r from q (r bounds the node's extent around p~) contributes its multipole expansion
 * instead of its triangles, so a query costs O(log n) instead of O(n). We keep the first two
 * terms of the expansion of (x - q)/|x - q|^3 about p~ (see far_field in winding.c). */
#ifndef SDF_SIGN_WINDING_H
#define SDF_SIGN_WINDING_H

#include <stddef.h>
#include <stdint.h>

#include "bvh/tree.h"

typedef struct sdf__winding sdf__winding;

/* The most bytes sdf__winding_create allocates for a tree of node_count nodes (the kept
 * moments and the build's double-precision ones). */
size_t sdf__winding_build_bytes(size_t node_count);

/* Compute the moments of every node of `tree`. The tree, `positions` and `triangles` must
 * outlive the result. Returns 0 or SDF_ENOMEM. */
int sdf__winding_create(const sdf__tree *tree, const float *positions, const uint32_t *triangles,
                        sdf__winding **out);
void sdf__winding_destroy(sdf__winding *w);
size_t sdf__winding_bytes(const sdf__winding *w); /* 0 for NULL (none made yet) */

/* The winding number at q. Thread-safe. */
double sdf__winding_number(const sdf__winding *w, const double q[3]);

/* The winding numbers of n <= SDF__WINDING_LANES points (coordinates SoA; all lanes are read,
 * so pad past n with copies) in one traversal: the same values as sdf__winding_number. */
#define SDF__WINDING_LANES 32
void sdf__winding_packet(const sdf__winding *w, const double *qx, const double *qy,
                         const double *qz, int n, double *winding);

/* The exact solid angle of triangle (a, b, c) seen from q, in steradians, positive when q
 * sees the triangle's back (van Oosterom & Strackee 1983). */
double sdf__solid_angle(const double q[3], const double a[3], const double b[3],
                        const double c[3]);

#endif
