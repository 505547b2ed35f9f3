/* grow.h - the one growth policy for libsdf's dynamic arrays (parser buffers, polygon
 * corners, traversal stacks): double, starting at 16, with overflow checks. */
#ifndef SDF_CORE_GROW_H
#define SDF_CORE_GROW_H

#include <stddef.h>

/* Make room for `need` elements of `elem` bytes in *array (capacity *cap, in elements).
 * Returns 0, or SDF_ENOMEM leaving *array and *cap unchanged. */
int sdf__grow(void **array, size_t *cap, size_t need, size_t elem);

#endif
