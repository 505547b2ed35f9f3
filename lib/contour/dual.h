/* dual.h - dual contouring of a volume, with the nodes' gradients (a first-order volume's
 * planes) as Hermite data, so that sharp edges and corners come back instead of being
 * chamfered (sdf.h, SDF_EXTRACT_DUAL).
 *
 * One vertex per loop of each cell that marching cubes (cell.h) polygonizes, where the
 * quadratic error of the loop's crossings (each a point and the normal the two nodes' planes
 * give there) is least, found by a truncated eigen-decomposition about the crossings' mean and
 * clamped to its cell; one quad per crossing edge, joining the vertices of the loops through
 * it in its four cells, split into the two triangles of larger smallest area. The result is
 * the dual of marching cubes' surface: closed and edge-manifold where that surface is, with
 * a vertex per sheet where plain dual contouring would merge several into one.
 * Same threads and numbering rules as extract.c. A zero-order volume's gradients are central
 * differences of its values (signs.h). */
#ifndef SDF_CONTOUR_DUAL_H
#define SDF_CONTOUR_DUAL_H

#include "contour/signs.h"
#include "sdf/sdf.h"

/* The surface of s's grid (filled: sdf__signs_fill) into *out. 0, SDF_ELIMIT, SDF_ENOMEM. */
int sdf__dual_extract(const sdf__signs *s, int threads, sdf_surface *out);

#endif
