/* exact.h - the EXACT re-distancing solver: the field's zero set extracted (marching cubes,
 * lib/contour, from the field's own linear crossings) and each node of the band given its
 * exact distance to that surface by libsdf's query engine, so that the result's error is the
 * surface's reconstruction error (a fraction of a cell; sharp edges chamfered), not an upwind
 * scheme's, whatever the distance. */
#ifndef SDF_FIELD_EXACT_H
#define SDF_FIELD_EXACT_H

#include <stdint.h>

#include "field/grid.h"
#include "sdf/sdf.h"

/* The zero set of f (g->nodes values, negative inside) as a mesh in the grid's frame (node
 * (i, j, k) at (i h0, j h1, k h2)). 0; SDF_EINVAL when f has no zero crossing; SDF_ENOMEM. */
int sdf__exact_surface(const sdf__field_grid *g, const float *f, sdf_mesh **out);

/* Into phi: each node marked SDF__NODE_ACTIVE in state its unsigned distance to the surface,
 * the others `cap` (the caller signs and clamps). 0 or SDF_ENOMEM. */
int sdf__exact_solve(const sdf__field_grid *g, const sdf_mesh *surface, const uint8_t *state,
                     float cap, float *phi);

#endif
