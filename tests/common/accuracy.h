/* accuracy.h - the TDF paper's accuracy experiment (sec. 5.2), shared by the volume test
 * and the bench tool that prints the table for docs/volumes.md:
 * the mesh normalised to [-1, 1]^3, zero- and first-order volumes over [-1, 1]^3 at several
 * resolutions, each resampled by nearest neighbour (the nearest node's value, or its plane
 * evaluated, for first order) at the nodes of a fine reference grid, and the mean absolute
 * error against the exact signed distances there. */
#ifndef SDF_TESTS_ACCURACY_H
#define SDF_TESTS_ACCURACY_H

#include <stddef.h>

#include "sdf/sdf.h"

/* A copy of `mesh` scaled uniformly and centred so its box fits [-1, 1]^3 (its longest side
 * spans it). NULL on failure. */
sdf_mesh *normalized_mesh(const sdf_mesh *mesh);

typedef struct accuracy_row {
    size_t dim;
    double zero, first, packed; /* mean absolute errors */
    double first_gradient;      /* first order normalised by SDF_NORMALIZE_GRADIENT (if asked) */
    double zero_seconds, first_seconds;
} accuracy_row;

/* Fill rows[i] for resolutions dims[i] (count rows) against a reference grid of `reference`
 * nodes per axis; `threads` as in sdf_query_options; first_gradient only when
 * `with_gradient` (NAN otherwise). Returns 0 or an SDF_E* code. */
int accuracy_table(const sdf_mesh *normalized, const size_t *dims, int count, size_t reference,
                   int threads, int with_gradient, accuracy_row *rows);

#endif
