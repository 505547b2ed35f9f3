/* polygon.c - the corner list the parsers gather a polygon in (see parsers.h). */
#include <stdlib.h>

#include "core/grow.h"
#include "mesh/parsers.h"

int sdf__polygon_push(sdf__polygon *poly, uint32_t index)
{
    if (sdf__grow((void **)&poly->idx, &poly->cap, poly->count + 1, sizeof *poly->idx))
        return SDF_ENOMEM;
    poly->idx[poly->count++] = index;
    return 0;
}

void sdf__polygon_free(sdf__polygon *poly)
{
    free(poly->idx);
    *poly = (sdf__polygon){0};
}
