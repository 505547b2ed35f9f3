/* opsparams.h - the field operations' JSON (docs/api.md, "Field operations"), for the body of
 * POST /v1/volumes/{name}/ops and the same keys in a bake's body:
 *   {"ops": [{"round": 0.05}, {"offset": -0.1}, ...], "solver": "sweep" | "sussman",
 *    "iterations": n, "band": b, "strict": true | false}
 * plus, in an ops body, "volume": the output's name. Each op is an object of exactly one key,
 * an operation's name (sdf_field_op_from_name), whose value is its r. Only syntax, types
 * and the documented ranges are checked here; the ops' values are the library's to judge
 * (sdf_volume_apply_ops), when the job runs. */
#ifndef SDFD_OPSPARAMS_H
#define SDFD_OPSPARAMS_H

#include <cjson/cJSON.h>
#include <stddef.h>

#include "state/registry.h"
#include "state/volumes.h"

/* What sdfd_ops_key returns for a key that is not a field-operation key. */
#define SDFD_OPS_NOT_MINE 1

/* The defaults: no ops, the SWEEP solver, derived iterations, the library's band. */
void sdfd_ops_defaults(sdfd_ops_request *out);

/* One member of a body's object: 0 when it was one of "ops", "solver", "iterations", "band",
 * "strict" and is valid (*seen gets its bit: SDFD_OPS_KEY_OPS for "ops", SDFD_OPS_KEY_OTHER
 * for the rest), SDF_EINVAL with a message when it is not valid, SDFD_OPS_NOT_MINE when it
 * is another key. */
#define SDFD_OPS_KEY_OPS 1
#define SDFD_OPS_KEY_OTHER 2
int sdfd_ops_key(const cJSON *item, sdfd_ops_request *out, unsigned *seen, char *err,
                 size_t cap);

/* An ops route's body: 0, SDFD_ESYNTAX (not JSON) or SDF_EINVAL with a message. `volume` is
 * "" when not given. */
int sdfd_ops_from_json(const char *text, size_t len, sdfd_ops_request *out,
                       char volume[SDFD_MAX_NAME + 1], char *err, size_t cap);

#endif
