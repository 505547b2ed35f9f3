/* workload.h - query point sets for tests and the benchmark, made from a seed:
 *   box  - uniform in the mesh's bounding box grown by 20 % about its centre
 *   band - area-weighted surface samples pushed off by N(0, (1 % of the diagonal)^2) per axis
 *   grid - a regular k^3 grid over the grown box, x fastest (k = round(n^(1/3)), lowered
 *          until k^3 <= n; so n = 1,000,000 gives peer_bench.py's 100^3 grid)
 *   far  - uniform in a box 10x the mesh's, outside the grown box
 * These follow tests/bench/peer_bench.py's definitions (not its random stream: to
 * compare on identical points, have peer_bench.py write them with --points-out). */
#ifndef SDF_TESTS_WORKLOAD_H
#define SDF_TESTS_WORKLOAD_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

typedef struct sdf_rng {
    uint64_t state;
} sdf_rng;

uint64_t sdf_rng_next(sdf_rng *r);
double sdf_rng_uniform(sdf_rng *r);  /* [0, 1) */
double sdf_rng_normal(sdf_rng *r);   /* N(0, 1) */

/* Fill `points` (3n floats) with workload `kind` ("box", "band", "grid", "far"); for
 * "grid" *n is lowered to k^3. Returns 0 or SDF_EINVAL for an unknown kind. */
int sdf_workload(const sdf_mesh *mesh, const char *kind, size_t *n, uint64_t seed, float *points);

#endif
