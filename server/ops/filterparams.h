/* filterparams.h - the filtered modes' parameters as HTTP clients write them: a "filter"
 * object in a JSON body, or the same names as URL arguments for octet-stream and npy bodies
 * (docs/api.md):
 *   kernel gaussian|bump, cap, a, b, medial (numbers > 0), samples, min_samples (1..4096),
 *   grid, unsigned,
 *   allow_wide_bump (true|false, or 1|0 in a URL), seed (integer 0..2^53), and a smoothing
 *   volume: JSON "smooth": {"sphere": [x,y,z,r]} | {"box": [x0,y0,z0,x1,y1,z1]} |
 *   {"mesh": "name"}, with optional "depth" and "scale"; URL smooth_sphere=x,y,z,r |
 *   smooth_box=x0,y0,z0,x1,y1,z1 | smooth_mesh=name, smooth_depth, smooth_scale.
 * A mesh volume comes back as its name in `volume_mesh` (the caller looks it up and puts a
 * reference in out->smooth.mesh); "" when there is none.
 * Only the syntax is checked here (types, integers, unknown names, keys given twice, and
 * numbers > 0, as the library reads 0 as "the default"); the values are the library's to
 * judge (sdfd_filter_validate), so both front ends give the same messages. */
#ifndef SDFD_FILTERPARAMS_H
#define SDFD_FILTERPARAMS_H

#include <stddef.h>

#include <cjson/cJSON.h>

#include "sdf/sdf.h"

/* The first key an object (a cJSON node) holds twice, or NULL: JSON leaves repeated keys
 * undefined, so the parsers of filter and bake objects refuse them. */
const char *sdfd_json_repeated_key(const cJSON *object);

/* Parse a request body that must be one JSON object without repeated keys (bake and
 * field-operation bodies). 0 with *root (the caller frees it with cJSON_Delete), or
 * SDFD_ESYNTAX (not JSON) / SDF_EINVAL (not an object, a key twice) with a message in err
 * and *root NULL. */
int sdfd_json_body_object(const char *text, size_t len, cJSON **root, char *err, size_t cap);

/* From the text of a JSON object (parsed with cJSON). 0, or SDF_EINVAL with a message. */
#define SDFD_VOLUME_NAME_MAX 255

int sdfd_filter_from_json(const char *text, size_t len, sdf_filter_options *out,
                          char volume_mesh[SDFD_VOLUME_NAME_MAX + 1], char *err, size_t cap);

/* From named string values, e.g. URL arguments: lookup(ctx, name) returns the value or NULL.
 * Only the names listed above are looked up: refusing others, and names given twice, is the
 * caller's (sdfd_url_args_check, urlargs.h). 0, or SDF_EINVAL with a message. */
int sdfd_filter_from_strings(const char *(*lookup)(void *ctx, const char *name), void *ctx,
                             sdf_filter_options *out, char volume_mesh[SDFD_VOLUME_NAME_MAX + 1],
                             char *err, size_t cap);

/* The URL argument names sdfd_filter_from_strings reads: the i-th from 0, then NULL. */
const char *sdfd_filter_url_name(size_t i);
/* Whether `name` is one of them. */
int sdfd_filter_is_url_name(const char *name);

#endif
