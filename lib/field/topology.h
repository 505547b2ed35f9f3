/* topology.h - how many connected parts a field's solid (phi < 0) and its outside have, to
 * tell when an offset crossed the medial axis (the rounding paper's validity caveat): a
 * valid rounding or filleting keeps both counts. */
#ifndef SDF_FIELD_TOPOLOGY_H
#define SDF_FIELD_TOPOLOGY_H

#include "field/grid.h"

typedef struct sdf__field_parts {
    size_t inside, outside; /* face-connected (6-neighbour) components */
} sdf__field_parts;

/* Count the parts of phi's sign pattern; labels is g->nodes uint32 of scratch (the grid
 * holds at most 2^30 nodes). */
void sdf__field_count_parts(const sdf__field_grid *g, const float *phi, uint32_t *labels,
                            sdf__field_parts *out);

#endif
