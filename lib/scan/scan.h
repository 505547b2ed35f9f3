/* scan.h - signed distances at every node of a volume's lattice (zero order) or at every
 * node's fine grid (first order) by closest-feature scan conversion (after Mauch's CSC), for
 * bakes of the raw field.
 *
 * Querying node after node makes each far node rule out every triangle within its distance
 * (docs/performance.md): the cost grows with the distance. Turned around, the work is small: a
 * point's closest surface point lies inside a face, on an edge or at a vertex, and then the
 * point lies in that feature's region (scan/regions.h). Each region is a convex polyhedron;
 * scan-converting all of them over the lattice hands every node the few features whose region
 * holds it (the regions are truncated, so only a few), and the nearest of those is the closest.
 * The regions are necessary conditions taken with a rounding slack, so a node can only get
 * extra candidates, never miss its closest feature. Zero order: the winner's distance is then
 * the exact double test of geom/triangle.c, and sign and float output are sdf_query's own
 * (sdf__query_finish), so a node gets the same float as sdf_query at the same point; a node
 * whose winner was an extra candidate (its exact distance exceeds the region's estimate) is
 * asked again through sdf_query's search. When distances alone are asked for, a node well
 * inside its winner's region and off the surface needs neither: its estimate is exact, its side
 * of the winner's pseudonormal is the sign, and its float is taken when every value within the
 * rounding of both computations rounds to the same float (the same bits, without the exact
 * test).
 *
 * scan/ sits above the point engine (points/), which queries its coarse lattice and finishes
 * its winners, and below its two users: sdf_query's lattice path (query/query.c) and
 * sdf_volume_bake (volume/bake.c). */
#ifndef SDF_SCAN_SCAN_H
#define SDF_SCAN_SCAN_H

#include <stddef.h>

#include "sdf/sdf.h"

typedef struct sdf__scan sdf__scan;

/* Is the scan the faster way to bake this mesh with this sign? Closed meshes (their regions
 * reach only as far as the box; an open mesh's boundary edges and vertices own half-spaces
 * beyond its rims) signed by pseudonormals or unsigned: a winding-number or ray sign costs
 * as much per node either way, and sdf_query's Morton-ordered packets share more of it. */
int sdf__scan_supported(const sdf_mesh *mesh, sdf_sign_method sign);

/* Does one z-slice of nx * ny nodes keep its scratch (16 bytes per node, or first order, with
 * fine_half = H > 0, 4 per fine sample; per worker of `threads`) under 256 MiB? Scans run in
 * whole slices: a bake or query whose slice does not fit takes the search path instead. */
int sdf__scan_fits(size_t nx, size_t ny, int fine_half, int threads);

/* An upper bound of the bytes a scan of `info`'s lattice allocates over its life (the
 * mesh's adjacency, the coarse lattice, each call's per-node arrays), on `threads`. */
size_t sdf__scan_scratch_bound(const sdf_mesh *mesh, const sdf_volume_info *info, int threads);

/* Prepare the scan of `info`'s lattice (dims, origin, spacing): the mesh's adjacency and how
 * far from the surface any node lies (from a coarse lattice of exact queries). `opts` gives
 * the sign and threads. Returns 0 or SDF_ENOMEM. */
int sdf__scan_create(const sdf_mesh *mesh, const sdf_volume_info *info,
                     const sdf_query_options *opts, sdf__scan **out);

/* How many z-slices one sdf__scan_slices call should take (its scratch is 16 bytes per node
 * and worker, kept under 64 MiB). */
size_t sdf__scan_slices_per_call(const sdf__scan *scan);

/* A scan of the lattice whose node (i, j, k) is (axis[0][i], axis[1][j], axis[2][k]), each
 * axis increasing with at least 2 nodes, every node within 1 % of a cell of even spacing (a
 * batch of query points laid out as a lattice, x fastest). SDF_EINVAL if it is not such a
 * lattice; else as sdf__scan_create. */
int sdf__scan_create_lattice(const sdf_mesh *mesh, const size_t dims[3],
                             const float *const axis[3], const sdf_query_options *opts,
                             sdf__scan **out);

/* Zero order: sdf_query's outputs (those `out` asks for) at the nodes of slices k0 <= k < k1,
 * node (i, j, k) at index (k - k0) N M + j N + i of each array (N, M = dims[0], dims[1]).
 * Returns 0 or SDF_ENOMEM. */
int sdf__scan_slices(sdf__scan *scan, size_t k0, size_t k1, const sdf_query_result *out);

/* Receives the signed distances at the fine samples of nodes [first, first + count) of the
 * volume (count * (2 half + 1)^3 floats, node-major), on worker `worker`; may write them.
 * A non-zero return fails the call with that code. */
typedef int (*sdf__sample_fn)(void *user, size_t first, size_t count, float *f, int worker);

/* First order (Algorithm 1's fine grids): the signed distances at the (2 half + 1)^3 samples
 * around every node of slices k0 <= k < k1, at offsets (i, j, k) * fine_spacing * spacing,
 * i, j, k in -half..half, x fastest, handed to `consume` in runs of nodes from worker
 * threads. A sample sits at the float node plus the offset, in double (a query would round it
 * to float first); its value is the exact distance there to the winning feature, rounded to
 * float and signed by the feature's pseudonormal: a fit needs no more, and no triangle test
 * runs per sample. A sample no region held (none should be) is NAN. 0, SDF_ENOMEM or the
 * consumer's code. */
int sdf__scan_samples(sdf__scan *scan, size_t k0, size_t k1, int half, double fine_spacing,
                      sdf__sample_fn consume, void *user);

/* Slices per sdf__scan_samples call (its scratch: 4 bytes per sample and worker, kept
 * under 128 MiB). */
size_t sdf__scan_sample_slices_per_call(const sdf__scan *scan, int half);

void sdf__scan_destroy(sdf__scan *scan);

#endif
