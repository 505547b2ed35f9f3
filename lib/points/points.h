/* points.h - the point engine (points/points.c): a checked batch answered point by point,
 * by packets of Morton-ordered points, clusters of seeded points or single traversals, each
 * closest point then signed and written out the same way. It sits below both users of it:
 * the scan (scan/, which queries its coarse lattice here and finishes its winners with
 * sdf__query_finish) and sdf_query's entry (query/query.c), which picks between the scan and
 * this engine. */
#ifndef SDF_POINTS_POINTS_H
#define SDF_POINTS_POINTS_H

#include <stddef.h>
#include <stdint.h>

#include "geom/triangle.h" /* sdf__hit */
#include "sdf/sdf.h"

/* Check a batch as sdf_query does before it writes anything: the arguments (SDF_EINVAL,
 * also for a NULL `out`), every point finite and within SDF_MAX_COORDINATE (SDF_ENONFINITE,
 * the first bad one's index in out->bad_index), and the caches the sign needs made on first
 * use (Embree's scene, the winding-number moments). 0 when it may be answered. */
int sdf__query_check(const sdf_mesh *mesh, const float *points, size_t count,
                     const sdf_query_options *opts, sdf_query_result *out);

/* Answer a batch sdf__query_check passed: packets or single queries. */
int sdf__query_checked_points(const sdf_mesh *mesh, const float *points, size_t count,
                              const sdf_query_options *opts, sdf_query_result *out);

/* Both: sdf_query without its lattice path (the scan queries its coarse lattice with it). */
int sdf__query_points(const sdf_mesh *mesh, const float *points, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out);

/* Answer `count` packed points in the given order, SDF__PACKET consecutive points to a
 * packet, each search starting from bound[i] (an upper bound of point i's distance; the
 * points of one packet should lie close together). sign_hint (may be NULL) gives signs known
 * in advance (+1, -1; 0 = compute it), which are used instead of the sign method; run_start
 * (may be NULL) marks with 1 the first point of each run of nearby points, and no packet
 * spans two runs. Otherwise the same answers as sdf_query. */
int sdf__query_seeded(const sdf_mesh *mesh, const float *points, const double *bound,
                      const int8_t *sign_hint, const uint8_t *run_start, size_t count,
                      const sdf_query_options *opts, sdf_query_result *out);

/* Answer `count` packed points whose closest points are already known (hits[i]; a hit with
 * dist2 == INFINITY is searched again): signs and outputs exactly as sdf_query gives them for
 * the same closest points. Runs on the calling thread. */
int sdf__query_finish(const sdf_mesh *mesh, const float *points, const sdf__hit *hits,
                      size_t count, const sdf_query_options *opts, sdf_query_result *out);

/* An upper bound of the bytes sdf_query, sdf__query_points or sdf__query_seeded allocate
 * for a batch of `count` points on `threads` threads, the lattice path's scan aside (a batch
 * it takes is a lattice of at least two whole z-slices). */
size_t sdf__query_scratch_bound(size_t count, int threads);

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

#endif
