/* grow.c - checked array growth (see grow.h). */
#include "core/grow.h"

#include <stdint.h>
#include <stdlib.h>

#include "sdf/sdf.h"

int sdf__grow(void **array, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t n = *cap ? *cap : 16;
    while (n < need)
        n = n > SIZE_MAX / 2 ? need : n * 2;
    if (n > SIZE_MAX / elem)
        return SDF_ENOMEM;
    void *p = realloc(*array, n * elem);
    if (!p)
        return SDF_ENOMEM;
    *array = p;
    *cap = n;
    return 0;
}
