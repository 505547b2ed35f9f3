/* pseudonormal.h - angle-weighted pseudonormals (Baerentzen & Aanaes 2005, cited in sec. 3
 * of the convolution paper): for a closed, manifold, non-self-intersecting mesh, p is
 * outside exactly when (p - c) . N > 0, where c is the closest point and N the pseudonormal
 * of the feature c lies on:
 *   face:   the face normal;
 *   edge:   the sum of the two adjacent face normals (each weighted by pi);
 *   vertex: sum over incident faces of (angle at the vertex) * (face normal).
 * Zero-area triangles have no normal and contribute nothing. Edge and vertex normals are
 * stored; face normals are not (12 bytes per triangle): the caller passes the one its
 * closest-point search computed. */
#ifndef SDF_SIGN_PSEUDONORMAL_H
#define SDF_SIGN_PSEUDONORMAL_H

#include <stddef.h>
#include <stdint.h>

typedef struct sdf__pseudonormals {
    float *edge;   /* 3 per edge, unit (or zero) */
    float *vertex; /* 3 per vertex, unit (or zero) */
    size_t bytes;
} sdf__pseudonormals;

/* From the mesh and which triangles use each edge: edge e's are edge_face[edge_start[e]]
 * up to edge_face[edge_start[e + 1]] (the arrays of mesh/topology.h's sdf__edge_faces, which
 * the mesh build hands on; sign/ sits below mesh/). Returns 0 or SDF_ENOMEM. */
int sdf__pseudonormals_create(const float *positions, size_t vertex_count,
                              const uint32_t *triangles, size_t triangle_count,
                              const size_t *edge_start, const uint32_t *edge_face,
                              size_t edge_count,
                              sdf__pseudonormals **out);
void sdf__pseudonormals_destroy(sdf__pseudonormals *pn);

/* The unit pseudonormal of `feature` (enum sdf__feature) of triangle `tri`, whose face
 * normal (any length; the closest-point search has it at hand) is `face`. Falls back to the
 * face normal, then to a corner's normal, when a feature has none (degenerate
 * neighbourhoods); all zero only if the whole neighbourhood is degenerate. */
void sdf__pseudonormal(const sdf__pseudonormals *pn, const uint32_t *triangles,
                       const uint32_t *edge_of, uint32_t tri, int feature, const double face[3],
                       float n[3]);

#endif
