/* bakeparams.h - a bake request's JSON body, as clients write it (docs/api.md):
 *   {"volume": "name", "mesh": "name", "bounds": {"min": [x, y, z], "max": [x, y, z]}, "margin": m,
 *    "resolution": n | [n, m, k], "order": 0 | 1, "H": h, "delta": d,
 *    "normalize": "plane" | "gradient",
 *    "field": "raw" | "filtered", "filter": {...}, "encoding": "float32" | "packed32",
 *    "sign": "auto" | ...,
 *    "ops": [...], "solver": ..., "iterations": n, "band": b, "strict": bool (opsparams.h)}
 * Every key is optional; an unknown key is an error (a typo must not bake the wrong volume).
 * Only syntax and types are checked here; values are judged by sdf_volume_plan, so the
 * messages are the library's. */
#ifndef SDFD_BAKEPARAMS_H
#define SDFD_BAKEPARAMS_H

#include <stddef.h>

#include "ops/filterparams.h"
#include "state/registry.h"
#include "state/volumes.h"

typedef struct sdfd_bake_names {
    char volume[SDFD_MAX_NAME + 1];                 /* "" = not given */
    char smoothing_mesh[SDFD_VOLUME_NAME_MAX + 1];  /* filter's "smooth": {"mesh": ...} */
} sdfd_bake_names;

/* Parse `len` bytes of JSON. 0, or SDFD_ESYNTAX (not JSON) / SDF_EINVAL with a message. */
int sdfd_bake_from_json(const char *text, size_t len, sdfd_bake_request *out,
                        sdfd_bake_names *names, char *err, size_t cap);

#endif
