/* hermite.h - the tricubic Hermite reconstruction of first-order volumes (SDF_VOLUME_HERMITE,
 * the default for them; docs/volumes.md "Evaluation").
 *
 * Trilinear interpolation of the planes' coefficients is as accurate as trilinear
 * interpolation of plain node values (both err by h^2 f'' / 8, with opposite signs), so it
 * wastes the gradients a first-order node stores. Here every node contributes its value and
 * gradient from its plane, and its cross derivatives f_xy, f_xz, f_yz, f_xyz from central
 * differences of its neighbours' gradients: a C1 field that reproduces a cubic from its
 * exact tangent planes wherever those differences are central (one node in from the
 * volume's faces). Before that, a node's value is limited by its neighbours' closest
 * points: the distance to the surface is at most the distance to any surface point, and a
 * neighbour's plane names one, its foot x_m - P_m(x_m) n_m / |n_m|^2. Step 6 of the TDF paper's
 * Algorithm 1 (SDF_NORMALIZE_PLANE) inflates a node's value where its fitting grid straddles
 * the medial axis, by up to 1 / |fitted gradient|; the limit pulls such a value back to the
 * nearest neighbour's foot, and leaves every value a plane field or a clean fit gives alone.
 * Volumes baked with SDF_NORMALIZE_GRADIENT keep the fitted values and skip the limit.
 *
 * volume.c locates the point and gathers the decoded planes of the 4 x 4 x 4 nodes around
 * its cell; this module does the arithmetic, on doubles. */
#ifndef SDF_VOLUME_HERMITE_H
#define SDF_VOLUME_HERMITE_H

#include <stddef.h>

/* One axis of the lookup: the cell, the four rows of nodes the cell's corners and their
 * neighbours lie on, and the 1D basis at the point. */
typedef struct sdf__hermite_axis {
    size_t cell;     /* the cell's first node */
    size_t node[4];  /* rows cell - 1 .. cell + 2, clamped to the volume (repeated at its ends) */
    double pos[4];   /* the rows' coordinates */
    /* basis[c][0]: weight of corner c's (c = 0, 1: rows 1, 2) value; basis[c][1]: of its
     * derivative along the axis; dbasis: their derivatives by the coordinate. Inside the
     * volume the cubic Hermite basis of the cell; outside, the boundary node's value and
     * derivative continued linearly (1 and the offset from it). */
    double basis[2][2], dbasis[2][2];
} sdf__hermite_axis;

/* Locate coordinate p along an axis of `dim` (>= 2) nodes from `origin`, `spacing` apart. */
void sdf__hermite_locate(double p, double origin, double spacing, size_t dim,
                         sdf__hermite_axis *out);

/* The reconstruction and its exact gradient at the point the three axes were located for;
 * planes[(z * 4 + y) * 4 + x] is the plane (a, b, c, d) of node (ax[0].node[x],
 * ax[1].node[y], ax[2].node[z]). `limit`: limit the node values by the neighbours' feet (for
 * SDF_NORMALIZE_PLANE volumes; a value fitted without step 6's division is left alone, as
 * there a neighbour's normal blended across the medial axis puts its foot off the surface). */
void sdf__hermite_eval(const sdf__hermite_axis ax[3], const double planes[64][4], int limit,
                       double *value, double grad[3]);

#endif
