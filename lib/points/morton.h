/* morton.h - the visit order of a batch: points sorted along a Morton (Z-order) curve.
 *
 * Packets, clusters and the scan's features are cut from runs of this order, so nearby
 * items are visited together. The sort is a least-significant-digit radix sort (no
 * comparisons), split over the batch's threads for large batches: on one thread it kept a
 * core idle for a noticeable part of a large query. */
#ifndef SDF_POINTS_MORTON_H
#define SDF_POINTS_MORTON_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

/* Visit order of `count` points (xyz floats `stride` bytes apart, finite): 30-bit Morton
 * codes over the points' bounding box (10 bits per axis), ties by index, so the order is
 * the same for any thread count. `order` receives point indices. `threads` as in
 * sdf_query_options (0 = all CPUs); the keys live in `ws` (a claimed workspace,
 * core/workspace.h) when given. Returns 0 or SDF_ENOMEM (also for more than UINT32_MAX
 * points). */
int sdf__morton_order(const char *points, size_t stride, size_t count, int threads,
                      sdf_workspace *ws, uint32_t *order);

/* The bytes sdf__morton_order allocates for `count` points on `threads` (its keys and
 * histograms), for the callers' scratch bounds. */
size_t sdf__morton_scratch_bound(size_t count, int threads);

/* The 30-bit code of point p over the box [lo, lo + 1023 / scale] (scale 0 on a flat axis):
 * axis k's 10 bits at every third bit from bit k. Exposed for the tests' slow reference. */
uint32_t sdf__morton_code(const float p[3], const float lo[3], const float scale[3]);

#endif
