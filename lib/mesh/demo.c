/* demo.c - the built-in demo mesh, so sdfd runs with no files at all: a tube of radius
 * 0.35 swept along the (2,3) torus knot (a trefoil)
 *     c(t) = ((2 + cos 3t) cos 2t, (2 + cos 3t) sin 2t, sin 3t),  t in [0, 2 pi),
 * with a circular cross-section in the curve's normal plane. Both directions are periodic,
 * so the surface is a closed, manifold torus; the knot's strands stay more than 0.8 apart,
 * so the tube never touches itself. The frame is the Frenet frame (the trefoil's curvature
 * never vanishes), which closes up exactly at t = 2 pi. */
#include <math.h>
#include <stdlib.h>

#include "sdf/sdf.h"

#define RINGS 512  /* along the knot */
#define SIDES 12   /* around the tube */
#define TUBE_RADIUS 0.35

static void knot(double t, double out[3])
{
    double r = 2 + cos(3 * t);
    out[0] = r * cos(2 * t);
    out[1] = r * sin(2 * t);
    out[2] = sin(3 * t);
}

static void normalize(double v[3])
{
    double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= len;
}

/* Frenet frame from central differences of the curve (exact enough for a mesh). */
static void frame(double t, double tangent[3], double normal[3], double binormal[3])
{
    const double h = 1e-4;
    double a[3], b[3], c[3];
    knot(t - h, a);
    knot(t, b);
    knot(t + h, c);
    for (int i = 0; i < 3; i++) {
        tangent[i] = c[i] - a[i];
        normal[i] = c[i] - 2 * b[i] + a[i];
    }
    normalize(tangent);
    double along = normal[0] * tangent[0] + normal[1] * tangent[1] + normal[2] * tangent[2];
    for (int i = 0; i < 3; i++)
        normal[i] -= along * tangent[i];
    normalize(normal);
    binormal[0] = tangent[1] * normal[2] - tangent[2] * normal[1];
    binormal[1] = tangent[2] * normal[0] - tangent[0] * normal[2];
    binormal[2] = tangent[0] * normal[1] - tangent[1] * normal[0];
}

int sdf_mesh_create_demo(sdf_mesh **out)
{
    float *v = malloc(3 * RINGS * SIDES * sizeof *v);
    uint32_t *tri = malloc(6 * RINGS * SIDES * sizeof *tri);
    if (!v || !tri) {
        free(v);
        free(tri);
        return SDF_ENOMEM;
    }
    for (int i = 0; i < RINGS; i++) {
        double t = 2 * M_PI * i / RINGS, c[3], T[3], N[3], B[3];
        knot(t, c);
        frame(t, T, N, B);
        for (int j = 0; j < SIDES; j++) {
            double phi = 2 * M_PI * j / SIDES;
            for (int k = 0; k < 3; k++)
                v[3 * (i * SIDES + j) + k] =
                    (float)(c[k] + TUBE_RADIUS * (cos(phi) * N[k] + sin(phi) * B[k]));
        }
    }
    /* Quads (i, j) -> (i+1, j+1), split in two; wound so normals point out of the tube
     * (the cross-section runs N -> B, counter-clockwise about T). */
    uint32_t *t = tri;
    for (int i = 0; i < RINGS; i++) {
        for (int j = 0; j < SIDES; j++) {
            uint32_t a = (uint32_t)(i * SIDES + j);
            uint32_t b = (uint32_t)(((i + 1) % RINGS) * SIDES + j);
            uint32_t c = (uint32_t)(((i + 1) % RINGS) * SIDES + (j + 1) % SIDES);
            uint32_t d = (uint32_t)(i * SIDES + (j + 1) % SIDES);
            *t++ = a, *t++ = d, *t++ = c;
            *t++ = a, *t++ = c, *t++ = b;
        }
    }
    int rc = sdf_mesh_create(v, RINGS * SIDES, tri, 2 * RINGS * SIDES, NULL, out, NULL);
    free(v);
    free(tri);
    return rc;
}
