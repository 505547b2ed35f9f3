/* polygon.c - the corner list the parsers gather a polygon in (see parsers.h). */
#include <stdlib.h>

#include "mesh/parsers.h"

int sdf__polygon_push(sdf__polygon *poly, uint32_t index)
{
    if (poly->count == poly->cap) {
        size_t cap = poly->cap ? 2 * poly->cap : 16;
        uint32_t *idx = realloc(poly->idx, cap * sizeof *idx);
        if (!idx)
            return SDF_ENOMEM;
        poly->idx = idx;
        poly->cap = cap;
    }
    poly->idx[poly->count++] = index;
    return 0;
}

void sdf__polygon_free(sdf__polygon *poly)
{
    free(poly->idx);
    *poly = (sdf__polygon){0};
}
