/* filter.h - the sample sets of the convolution-filtered field (sdf_query_filtered in
 * sdf.h; the paper is ../shared/papers/convolution-filtering-sdf.md, sec. 4-5).
 *
 * A sample set is drawn once per request from its seed: displacements s_i with weights w_i
 * summing to 1 (1/n for samples drawn from the kernel's density, eq. 10; w(s_i) normalised
 * for the regular 3^3 grid, eq. 9). Kept apart from the evaluation so tests can look at the
 * samples themselves. */
#ifndef SDF_QUERY_FILTER_H
#define SDF_QUERY_FILTER_H

#include "geom/triangle.h" /* sdf__hit */
#include "sdf/sdf.h"

typedef struct sdf__samples {
    int n;
    double (*offset)[3]; /* s_i, in mesh units (already scaled by the kernel's width) */
    double *weight;      /* w_i, summing to 1 */
} sdf__samples;

/* Draw the sample set of fully resolved options (no zero defaults left). Returns 0 or
 * SDF_ENOMEM. */
int sdf__samples_draw(const sdf_filter_options *f, sdf__samples *out);
void sdf__samples_free(sdf__samples *s);

/* Resolve the zero defaults of `in` for `mesh` and validate every parameter. Returns 0, or
 * SDF_EINVAL with a message saying which value is wrong and what is allowed. */
int sdf__filter_resolve(const sdf_mesh *mesh, const sdf_filter_options *in,
                        sdf_filter_options *out, sdf_diag *diag);

/* Answer `count` packed points in the given order, SDF__PACKET consecutive points to a
 * packet, each search starting from bound[i] (an upper bound of point i's distance; the
 * points of one packet should lie close together). sign_hint (may be NULL) gives signs known
 * in advance (+1, -1; 0 = compute it), which are used instead of the sign method; run_start
 * (may be NULL) marks with 1 the first point of each run of nearby points, and no packet
 * spans two runs. Otherwise the same answers as sdf_query. Defined in query.c. */
int sdf__query_seeded(const sdf_mesh *mesh, const float *points, const double *bound,
                      const int8_t *sign_hint, const uint8_t *run_start, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out);

/* Is the batch (xyz floats `stride` bytes apart, 0 = packed) a full lattice: point
 * (k ny + j) nx + i at (x_i, y_j, z_k), each axis at least 2 long? Then 1, its dims and its
 * axes (malloc'ed, the caller frees them); else 0 and NULLs. Defined in query.c. */
int sdf__find_lattice(const float *points, size_t stride, size_t count, size_t dims[3],
                      float *axis[3]);

/* An upper bound of the bytes sdf_query, sdf__query_points or sdf__query_seeded allocate
 * for a batch of `count` points on `threads` threads, the lattice path's scan aside (a batch
 * it takes is a lattice of at least two whole z-slices). Defined in query.c. */
size_t sdf__query_scratch_bound(size_t count, int threads);

/* An upper bound of the bytes sdf_query_filtered allocates for `count` points with fully
 * resolved options `f` (gradient: whether it is asked for), its inner queries' included.
 * Defined in filter.c. */
size_t sdf__filter_scratch_bound(const sdf_filter_options *f, size_t count, int gradient,
                                 int threads);

/* sdf_query on options whose workspace the caller has claimed (core/workspace.h):
 * sdf_query_filtered's queries at its points. Defined in query.c. */
int sdf__query(const sdf_mesh *mesh, const float *points, size_t count,
               const sdf_query_options *opts, sdf_query_result *out);

/* sdf_query without its lattice path (volume/scan.c queries its coarse lattice with it):
 * packets or single queries only. Defined in query.c. */
int sdf__query_points(const sdf_mesh *mesh, const float *points, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out);

/* The outputs `r` asks for, from point `first` on. */
static inline sdf_query_result sdf__result_at(const sdf_query_result *r, size_t first)
{
    sdf_query_result part = {
        .distance = r->distance ? r->distance + first : NULL,
        .gradient = r->gradient ? r->gradient + 3 * first : NULL,
        .closest = r->closest ? r->closest + 3 * first : NULL,
        .triangle = r->triangle ? r->triangle + first : NULL,
        .barycentric = r->barycentric ? r->barycentric + 3 * first : NULL,
    };
    return part;
}

/* Answer `count` packed points whose closest points are already known (hits[i]; a hit with
 * dist2 == INFINITY is searched again): signs and outputs exactly as sdf_query gives them for
 * the same closest points. Runs on the calling thread. Defined in query.c. */
int sdf__query_finish(const sdf_mesh *mesh, const float *points, const sdf__hit *hits,
                      size_t count, const sdf_query_options *opts, sdf_query_result *out);

#endif
