/* topology.h - what a triangle list's connectivity says about it.
 *
 * Welding merges vertices with bit-identical coordinates (STL stores every triangle's
 * corners separately, so without it no edge would be shared). The edge analysis then finds
 * every undirected edge and how many triangles use it in which direction: that yields
 * closedness, edge-manifoldness and consistent orientation, and the per-triangle edge ids
 * the pseudonormal sign needs. Both use open-addressing hash tables, linear in size. */
#ifndef SDF_MESH_TOPOLOGY_H
#define SDF_MESH_TOPOLOGY_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* SDF__NO_EDGE */
#include "sdf/sdf.h"

/* Merge bit-identical vertices (+0 and -0 are equal). Rewrites `triangles` in place and
 * returns a new position array in *out (3 floats per vertex plus one float of padding, as
 * Embree reads 16 bytes per vertex). Returns 0 or SDF_ENOMEM. */
int sdf__weld(const float *positions, size_t vertex_count, uint32_t *triangles,
              size_t triangle_count, float **out, size_t *out_count);

/* The triangles using each edge, in triangle order: edge e's are face[start[e]] up to
 * face[start[e + 1]] (excluded). */
typedef struct sdf__edge_faces {
    size_t *start; /* edge_count + 1 */
    uint32_t *face;
} sdf__edge_faces;

void sdf__edge_faces_free(sdf__edge_faces *faces);

/* Find the edges; fills report fields closed, edge_manifold, boundary_edges,
 * nonmanifold_edges, misoriented_edges and degenerate_triangles, volume, bbox, diagonal.
 * *edge_of receives 3 edge ids per triangle (edge k runs from corner k to corner k+1;
 * SDF__NO_EDGE for a triangle with a repeated corner), and *faces (unless NULL) which
 * triangles use each edge. Returns 0 or SDF_ENOMEM. */
int sdf__analyse(const float *positions, const uint32_t *triangles, size_t triangle_count,
                 uint32_t **edge_of, size_t *edge_count, sdf__edge_faces *faces,
                 sdf_mesh_report *report);

/* Reverse every triangle's orientation, keeping edge_of consistent. */
void sdf__flip(uint32_t *triangles, uint32_t *edge_of, size_t triangle_count);

#endif
