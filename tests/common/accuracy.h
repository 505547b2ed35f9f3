/* accuracy.h - the TDF paper's accuracy experiment (sec. 5.2), shared by the volume tests and
 * the bench tool that prints the tables of docs/volumes.md: the mesh scaled into a cube
 * [-half, half]^3 (the paper's [-1, 1]^3: half = 1), volumes over that cube at several
 * resolutions, resampled at the nodes of a fine reference grid over it and compared with the
 * exact signed distances (and gradients) there. */
#ifndef SDF_TESTS_ACCURACY_H
#define SDF_TESTS_ACCURACY_H

#include <stddef.h>

#include "sdf/sdf.h"

/* A copy of `mesh` scaled uniformly and centred so its box fits [-half, half]^3 (its longest
 * side spans it). NULL on failure. normalized_mesh: half = 1. */
sdf_mesh *scaled_mesh(const sdf_mesh *mesh, double half);
sdf_mesh *normalized_mesh(const sdf_mesh *mesh);

/* The reference: reference^3 nodes over [-half, half]^3 and the exact answers there. */
typedef struct accuracy_grid {
    size_t count;
    double half;
    float *points, *distance, *gradient; /* gradient: only if asked for */
} accuracy_grid;

int accuracy_grid_make(const sdf_mesh *scaled, size_t reference, double half, int threads,
                       int with_gradient, accuracy_grid *out);
void accuracy_grid_free(accuracy_grid *grid);

typedef struct accuracy_error {
    double mean, max; /* absolute error of the value */
    double angle;     /* mean angle in degrees between the reconstructed and the exact gradient
                         (NAN without the grid's gradients) */
} accuracy_error;

/* `volume` reconstructed by `filter` at the grid's nodes. 0 or an SDF_E* code. */
int accuracy_measure(const sdf_volume *volume, sdf_volume_filter filter,
                     const accuracy_grid *grid, accuracy_error *out);

/* Volumes over the grid's cube, `dims` nodes per axis, baked by `opts` (its bounds and dims
 * are set here). */
int accuracy_bake(const sdf_mesh *scaled, const accuracy_grid *grid, size_t dims,
                  sdf_bake_options opts, sdf_volume **out);

/* The paper's table: nearest-neighbour resampling. */
typedef struct accuracy_row {
    size_t dim;
    double zero, first, packed; /* mean absolute errors */
    double first_gradient;      /* first order normalised by SDF_NORMALIZE_GRADIENT (if asked) */
    double zero_seconds, first_seconds;
} accuracy_row;

/* Fill rows[i] for resolutions dims[i] (count rows); `threads` as in sdf_query_options;
 * first_gradient only when `with_gradient` (NAN otherwise). Returns 0 or an SDF_E* code. */
int accuracy_table(const sdf_mesh *scaled, const accuracy_grid *grid, const size_t *dims,
                   int count, int threads, int with_gradient, accuracy_row *rows);

/* Every reconstruction: zero order nearest and trilinear, first order (the default bake,
 * SDF_NORMALIZE_PLANE) nearest, trilinear and hermite, and hermite of the first order packed
 * into 32 bits a node, as many bytes as zero order. */
enum { FILTER_ZERO_NEAREST, FILTER_ZERO_TRILINEAR, FILTER_FIRST_NEAREST, FILTER_FIRST_TRILINEAR,
       FILTER_FIRST_HERMITE, FILTER_PACKED_HERMITE, FILTER_COLUMNS };
typedef struct filter_row {
    size_t dim;
    accuracy_error e[FILTER_COLUMNS];
} filter_row;

int filter_table(const sdf_mesh *scaled, const accuracy_grid *grid, const size_t *dims,
                 int count, int threads, filter_row *rows);

#endif
