/* diag.h - internal helpers to fill an sdf_diag (see sdf.h). */
#ifndef SDF_CORE_DIAG_H
#define SDF_CORE_DIAG_H

#include "sdf/sdf.h"

/* Fill `diag` (may be NULL) with a printf-style message and location; returns `code` so a
 * caller can write `return sdf__diag_set(...)`. `line` 0 / `offset` -1 mean "not known". */
int sdf__diag_set(sdf_diag *diag, int code, long line, long long offset, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));

/* Reset `diag` (may be NULL) to "success". */
void sdf__diag_clear(sdf_diag *diag);

#endif
