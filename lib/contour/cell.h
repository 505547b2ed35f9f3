/* cell.h - the surface inside one cell of marching cubes, built from one rule on each face
 * instead of a case table, so that neighbouring cells always agree.
 *
 * A node is inside when its value (relative to the iso-value) is < 0. On each of the cell's
 * six faces the crossing points of its edges are joined by segments: two crossings give one
 * segment; four (an ambiguous face, its inside corners diagonal) are joined as the bilinear
 * interpolant's saddle says (the asymptotic decider: the inside corners are joined through
 * the face when the saddle value is < 0). The rule reads the face's four values alone, so
 * the two cells sharing a face draw the same segments on it; each crossing ends one segment
 * and starts another, so the segments chain into closed loops, and the loops, triangulated,
 * make a surface that is closed and edge-manifold wherever the grid goes on. Segments run
 * from the crossing where the face's boundary (counter-clockwise seen from outside the cell)
 * enters the inside to the one where it leaves, which orients every triangle with its normal
 * towards the outside (increasing values).
 *
 * Each loop is fanned from the vertex whose fan's smallest triangle is largest, unless every
 * fan would join two crossings of one face that no segment joins (only possible across an
 * ambiguous face, where the neighbouring cell might draw the same diagonal): then from a new
 * vertex at the loop's centroid.
 *
 * Corner c of the cell is (c & 1, c >> 1 & 1, c >> 2 & 1) in cell units; edge e joins two
 * corners along axis e / 4, at the corner whose other two coordinates are bits of e % 4
 * (x-edges: (y, z); y-edges: (x, z); z-edges: (x, y)). */
#ifndef SDF_CONTOUR_CELL_H
#define SDF_CONTOUR_CELL_H

#include <stdint.h>

#define SDF__CELL_MAX_TRIANGLES 12 /* per cell: 12 crossings at most, n triangles a loop */
#define SDF__CELL_CENTROID 12      /* the vertex index of a loop's centroid (see above) */
#define SDF__CELL_MAX_CENTROIDS 4  /* loops of one cell */

#define SDF__CELL_EDGE_MARGIN 1e-3 /* a crossing's least distance from a node, in cells */

/* Where along an edge from value a to value b (of different sides) the crossing is: linear
 * interpolation, kept SDF__CELL_EDGE_MARGIN from both ends so that no two crossings of a cell
 * meet. */
static inline double sdf__cell_crossing(float a, float b)
{
    double t = (double)a / ((double)a - b);
    return t < SDF__CELL_EDGE_MARGIN ? SDF__CELL_EDGE_MARGIN
         : t > 1 - SDF__CELL_EDGE_MARGIN ? 1 - SDF__CELL_EDGE_MARGIN : t;
}

/* The corner pair of edge e (0..11): its two corners, the lower first. */
void sdf__cell_edge_corners(int e, int *a, int *b);

typedef struct sdf__cell_out {
    /* Triangles as three vertex numbers: 0..11 the crossing on that edge, or
     * SDF__CELL_CENTROID + m the centroid of loop m (whose crossing edges are listed in
     * centroid_edges[m], centroid_count[m] of them). */
    uint8_t tri[SDF__CELL_MAX_TRIANGLES][3];
    int triangles;
    uint8_t centroid_edges[SDF__CELL_MAX_CENTROIDS][12];
    int centroid_count[SDF__CELL_MAX_CENTROIDS];
    int centroids;
} sdf__cell_out;

/* The loops of a cell (at most 4): loop_of[e] the loop through edge e's crossing, -1 where
 * the edge does not cross; loops[m] the crossing edges of loop m in order (count[m] of them,
 * 3..12), the order a polygon of the surface takes them, counter-clockwise seen from outside.
 * Returns the number of loops. */
int sdf__cell_loops(const float value[8], int8_t loop_of[12], uint8_t loops[4][12],
                    int count[4]);

/* Dual contouring's polygons of a cell: its loops, each split by a chord between two of its
 * crossings wherever it holds two segments of one face (an ambiguous face whose two segments
 * are in one loop, on this side and so on the other), until none does, so that two polygons
 * of neighbouring cells share at most one segment and the dual surface stays edge-manifold. */
#define SDF__CELL_MAX_POLYS 12
#define SDF__CELL_MAX_POLY_SIZE 12
typedef struct sdf__cell_polys {
    int count;
    uint8_t vert[SDF__CELL_MAX_POLYS][SDF__CELL_MAX_POLY_SIZE]; /* crossing edges in order */
    int size[SDF__CELL_MAX_POLYS];
    int8_t out[12], in[12];  /* the polygon holding the face segment leaving / reaching edge
                                e's crossing; -1 where the edge does not cross */
    int8_t out_face[12];     /* the face (0..5: -x, +x, -y, +y, -z, +z) of the segment leaving
                                it; the one reaching it lies on the crossing's other face */
} sdf__cell_polys;

/* The polygons of a cell; returns their count. */
int sdf__cell_polygons(const float value[8], sdf__cell_polys *p);

/* The triangles of a cell: value[c] at corner c (relative to the iso-value), and the
 * crossing's position in cell units on each edge whose two corners differ in side (the
 * other entries unread); `scale` the cell's size along x, y and z (for choosing fans by
 * area). Returns the number of triangles. */
int sdf__cell_triangulate(const float value[8], const double crossing[12][3],
                          const double scale[3], sdf__cell_out *out);

#endif
