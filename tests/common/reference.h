/* reference.h - slow, obvious reference answers the fast paths are tested against:
 * distances by looping over every triangle in double precision (with a point-triangle
 * distance written independently of the library's: project onto the plane, else the best
 * of the three edges), and generalized winding numbers by summing every triangle's solid
 * angle. O(triangles) per point, by design. */
#ifndef SDF_TESTS_REFERENCE_H
#define SDF_TESTS_REFERENCE_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

typedef struct ref_hit {
    double dist;
    double point[3];
    size_t triangle;
} ref_hit;

/* Closest point on triangle (a, b, c) to p; returns the distance. */
double ref_point_triangle(const double p[3], const double a[3], const double b[3],
                          const double c[3], double closest[3]);

/* Closest point over all triangles of the mesh. */
void ref_closest(const sdf_mesh *mesh, const float p[3], ref_hit *hit);

/* Generalized winding number: sum of solid angles / 4 pi over all triangles. */
double ref_winding(const sdf_mesh *mesh, const float p[3]);

#endif
