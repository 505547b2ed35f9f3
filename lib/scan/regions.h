/* regions.h - where each feature of a closed mesh is the closest: the convex regions that
 * closest-feature scan conversion rasterises (scan/scan.c, scan/raster.c).
 *
 * A point's closest surface point lies inside a face, on an edge or at a vertex, and then
 * the point lies in that feature's region: the prism over the face, the wedge between the
 * normal planes of an edge's two faces, the cone of directions at a vertex that make obtuse
 * angles with all its edges. Each region is built twice over: as half-spaces n . p <= c
 * (what decides whether a node is in it) and as corners and edges of a bounding polyhedron
 * (what a scan crosses to find the rows to visit). Regions are capped at a reach: how far
 * from the surface a node can lie, and, with an upper-bound field of |f|, where the feature
 * is shown to have lost every farther point. */
#ifndef SDF_SCAN_REGIONS_H
#define SDF_SCAN_REGIONS_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

#define SDF__REGION_PLANES 64 /* a vertex with more edges keeps 62 planes: a larger region */
#define SDF__REGION_CORNERS 65
#define SDF__REGION_EDGES 128

static inline double sdf__min2(double a, double b) { return a < b ? a : b; }
static inline double sdf__max2(double a, double b) { return a > b ? a : b; }
static inline double sdf__dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void sdf__cross3(double out[3], const double a[3], const double b[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

enum { SDF__REGION_FACE, SDF__REGION_EDGE, SDF__REGION_VERTEX };

typedef struct sdf__region {
    int kind;
    double origin[3], dir[3]; /* face: a corner and the unit normal; edge: an end and the
                                 unit direction; vertex: its position */
    double sign_dir[3];       /* the feature's pseudonormal (Baerentzen & Aanaes): a point
                                 the feature is closest to is inside where
                                 (p - origin) . sign_dir < 0 */
    int planes;
    double plane[SDF__REGION_PLANES][4]; /* n . p <= c as (n, c), slack included */
    int corners;
    double corner[SDF__REGION_CORNERS][3];
    int edges;
    uint8_t edge[SDF__REGION_EDGES][2];
} sdf__region;

/* A mesh's features: faces 0..faces-1, then edges (the mesh's edge ids), then vertices. */
typedef struct sdf__features {
    const uint32_t *triangles;
    double *pos;                         /* vertex positions in double, 3 per vertex */
    size_t faces, edges, vertices, count;
    uint32_t *edge_end;                  /* 2 per edge */
    uint32_t *edge_first, *edge_tri;     /* triangles of each edge (CSR, ascending) */
    uint32_t *vert_first, *vert_nbr;     /* neighbour vertices of each vertex (CSR) */
    uint32_t *vertex_tri;                /* each vertex's lowest-numbered triangle (UINT32_MAX:
                                            none) */
    const float *edge_normal;            /* the mesh's edge and vertex pseudonormals, 3 each */
    const float *vertex_normal;
    /* Set by the caller before building regions: */
    double reach_front, reach_back;      /* farthest a node lies outside / inside */
    double slack;                        /* rounding slack of every half-space, world units */
    double row_pad;                      /* the scan's padding of row ranges, world units */
    const float *bound;                  /* optional: |f| on a coarse lattice, x fastest */
    const float *bound_point;            /* its nodes' closest surface points, xyz */
    double bound_point_error;            /* how far those floats can lie from the surface */
    size_t bound_dims[3];
    const double *bound_coord[3];        /* its node coordinates per axis */
    double bound_inv_step[3];            /* 1 / the spacing of its nodes */
    double march;                        /* step along a region's axis when truncating */
} sdf__features;

/* Positions in double and the adjacency of a closed mesh's features, on up to `threads`
 * (sdf_query_options' meaning). 0 or SDF_ENOMEM. */
int sdf__features_init(sdf__features *f, const sdf_mesh *mesh, int threads);
void sdf__features_free(sdf__features *f);

/* How far from the surface any node of the lattice coord[a][0..dims[a]) can lie, and what
 * truncates regions: exact distances and closest points on every step-th node
 * (sdf__query_points with `threads`), a node being within half the largest coarse cell's
 * diagonal of one of them. On a closed mesh signed by pseudonormals the two sides are bounded
 * apart (a point whose closest point is on a face's front lies outside). Sets reach_front,
 * reach_back, bound*, march; *bound (the distances, then the points: one block) and
 * bound_coord[] are the caller's to free (also on failure). Needs `slack` set. 0,
 * SDF_ENOMEM or a query's code. */
int sdf__features_bound(sdf__features *f, const sdf_mesh *mesh, const double *const coord[3],
                        const size_t dims[3], size_t step, int threads, float **bound,
                        double *bound_coord[3]);

/* Nodes of sdf__features_bound's coarse lattice along an axis of `dim` nodes: every step-th,
 * and the last. */
static inline size_t sdf__features_bound_nodes(size_t dim, size_t step)
{
    return (dim - 1 + step - 1) / step + 1;
}

/* The region of `feature`; 0 when it has none worth scanning (a face or edge without
 * extent, a vertex whose cone is only itself). */
int sdf__region_build(const sdf__features *f, size_t feature, sdf__region *r);

/* Prefetches what building the feature's region reads first (stage 0: its own entries in
 * the adjacency) or next (stage 1: what those entries point to, once they have arrived). */
void sdf__feature_prefetch(const sdf__features *f, size_t feature, int stage);

/* The feature's lowest-numbered triangle (the face itself for a face). */
uint32_t sdf__feature_triangle(const sdf__features *f, size_t feature);

#endif
