/* triangle.h - exact closest point on one triangle, in double precision, with the feature
 * (face interior, one of the 3 edges, one of the 3 corners) it lies on. The feature picks
 * the pseudonormal for the sign (Baerentzen & Aanaes 2005), so it must be exact: the
 * Voronoi-region tests of Ericson (Real-Time Collision Detection, sec. 5.1.5) give it
 * directly. Zero-area triangles are handled as their three segments. The test and its hit
 * sit below every folder that searches for closest points (bvh/, query/, volume/) or signs
 * (sign/), which all share them. */
#ifndef SDF_GEOM_TRIANGLE_H
#define SDF_GEOM_TRIANGLE_H

#include <stdint.h>

/* Features of triangle (v0, v1, v2). Edge k runs from corner k to corner (k+1) % 3. */
enum sdf__feature {
    SDF__FACE = 0,
    SDF__EDGE0 = 1, SDF__EDGE1 = 2, SDF__EDGE2 = 3,
    SDF__VERT0 = 4, SDF__VERT1 = 5, SDF__VERT2 = 6,
};

/* A mesh numbers its edges, 3 ids per triangle in the order above (mesh/topology.h); a
 * triangle with a repeated corner has none and takes this id for all three. */
#define SDF__NO_EDGE UINT32_MAX

/* The closest point found for one query: what every search (bvh/, points/, scan/) hands on
 * to the sign and the outputs. */
typedef struct sdf__hit {
    double point[3];
    double bary[3];
    double dist2;
    double face_normal[3]; /* (b - a) x (c - a) of the triangle, not normalized */
    uint32_t triangle;
    int feature; /* enum sdf__feature */
} sdf__hit;

/* Closest point to p on triangle (a, b, c): writes it to `closest`, the weights of a, b, c
 * to `bary` (summing to 1), and returns the squared distance; *feature receives an
 * sdf__feature. */
double sdf__closest_on_triangle(const double p[3], const double a[3], const double b[3],
                                const double c[3], double closest[3], double bary[3],
                                int *feature);

/* The exact test of triangle `tri` of a mesh (float `positions`, corner indices
 * `triangles`) from p: *hit takes its closest point when nearer than hit->dist2, or as near
 * with a lower triangle id (the searches' rule for ties). */
void sdf__triangle_offer(const float *positions, const uint32_t *triangles, uint32_t tri,
                         const double p[3], sdf__hit *hit);

/* (b - a) x (c - a): the face normal times twice the area. */
static inline void sdf__triangle_normal(const double a[3], const double b[3], const double c[3],
                                        double n[3])
{
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

#endif
