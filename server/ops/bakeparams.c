/* bakeparams.c - the bake request body (see bakeparams.h), parsed with cJSON: it is small
 * and has nested objects, so a tree is the clear way to read it. */
#include "core/errors.h"
#include "ops/bakeparams.h"
#include "ops/opsparams.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

static int fail(char *err, size_t cap, const char *fmt, const char *key)
{
    snprintf(err, cap, fmt, key);
    return SDF_EINVAL;
}

static int number(const cJSON *item, const char *key, double *out, char *err, size_t cap)
{
    if (!cJSON_IsNumber(item) || !isfinite(item->valuedouble))
        return fail(err, cap, "'%s' must be a number", key);
    *out = item->valuedouble;
    return 0;
}

/* A whole number within [lo, hi], a window that only keeps it a long: the library states
 * each value's real limits. */
static int integer(const cJSON *item, const char *key, double lo, double hi, long *out, char *err,
                   size_t cap)
{
    double v;
    if (number(item, key, &v, err, cap) || v != floor(v))
        return fail(err, cap, "'%s' must be a whole number", key);
    if (v < lo || v > hi) {
        snprintf(err, cap, "'%s' is %g, out of range (%g..%g)", key, v, lo, hi);
        return SDF_EINVAL;
    }
    *out = (long)v;
    return 0;
}

static int triple(const cJSON *item, const char *key, double out[3], char *err, size_t cap)
{
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) != 3)
        return fail(err, cap, "'%s' must be an array of 3 numbers", key);
    for (int a = 0; a < 3; a++)
        if (number(cJSON_GetArrayItem(item, a), key, &out[a], err, cap))
            return SDF_EINVAL;
    return 0;
}

static int name(const cJSON *item, const char *key, char *out, size_t out_cap, char *err,
                size_t cap)
{
    if (!cJSON_IsString(item) || strlen(item->valuestring) >= out_cap)
        return fail(err, cap, "'%s' must be a string", key);
    snprintf(out, out_cap, "%s", item->valuestring);
    return 0;
}

static int bounds(const cJSON *item, sdf_bake_options *o, char *err, size_t cap)
{
    const cJSON *lo = cJSON_GetObjectItemCaseSensitive(item, "min");
    const cJSON *hi = cJSON_GetObjectItemCaseSensitive(item, "max");
    if (!cJSON_IsObject(item) || !lo || !hi || cJSON_GetArraySize(item) != 2)
        return fail(err, cap, "'%s' must be {\"min\": [x, y, z], \"max\": [x, y, z]}", "bounds");
    if (triple(lo, "bounds.min", o->lo, err, cap) || triple(hi, "bounds.max", o->hi, err, cap))
        return SDF_EINVAL;
    /* All zero would read as "no bounds" to the library (sdf_bake_options). */
    for (int a = 0; a < 3; a++)
        if (!(o->lo[a] < o->hi[a]))
            return fail(err, cap, "'%s' must have min < max on every axis", "bounds");
    return 0;
}

static int resolution(const cJSON *item, sdf_bake_options *o, char *err, size_t cap)
{
    long n;
    if (cJSON_IsNumber(item)) {
        if (integer(item, "resolution", 2, SDF_VOLUME_MAX_DIM, &n, err, cap))
            return SDF_EINVAL;
        o->dims[0] = o->dims[1] = o->dims[2] = (size_t)n;
        return 0;
    }
    if (!cJSON_IsArray(item) || cJSON_GetArraySize(item) != 3)
        return fail(err, cap, "'%s' must be a whole number or an array of 3", "resolution");
    for (int a = 0; a < 3; a++) {
        if (integer(cJSON_GetArrayItem(item, a), "resolution", 2, SDF_VOLUME_MAX_DIM, &n, err,
                    cap))
            return SDF_EINVAL;
        o->dims[a] = (size_t)n;
    }
    return 0;
}

/* A member naming an item: a string that is a valid name. */
static int item_name(const cJSON *item, const char *key, char *dst, size_t size, char *err,
                     size_t cap)
{
    if (name(item, key, dst, size, err, cap))
        return SDF_EINVAL;
    if (!sdfd_valid_name(dst, strlen(dst)))
        return fail(err, cap, "'%s' must be 1-255 characters of A-Z a-z 0-9 . _ - "
                              "not starting with '.'", key);
    return 0;
}

static int one_key(const cJSON *item, sdfd_bake_request *out, sdfd_bake_names *names,
                   int *field, unsigned *ops_seen, char *err, size_t cap)
{
    sdf_bake_options *o = &out->options;
    const char *key = item->string;
    long n;
    if (!strcmp(key, "volume"))
        return item_name(item, key, names->volume, sizeof names->volume, err, cap);
    if (!strcmp(key, "mesh"))
        return item_name(item, key, out->surface, sizeof out->surface, err, cap);
    if (!strcmp(key, "bounds"))
        return bounds(item, o, err, cap);
    if (!strcmp(key, "margin")) {
        int rc = number(item, key, &o->margin, err, cap);
        out->mesh_box = !rc && o->margin == 0;
        return rc;
    }
    if (!strcmp(key, "resolution"))
        return resolution(item, o, err, cap);
    if (!strcmp(key, "order")) {
        if (integer(item, key, -1e9, 1e9, &n, err, cap))
            return SDF_EINVAL;
        o->order = (int)n;
        return 0;
    }
    if (!strcmp(key, "H")) {
        if (integer(item, key, -1e9, 1e9, &n, err, cap))
            return SDF_EINVAL;
        o->fine_half = (int)n;
        return n == 0 ? fail(err, cap, "'%s' must be at least 1", key) : 0;
    }
    if (!strcmp(key, "delta")) {
        int rc = number(item, key, &o->fine_spacing, err, cap);
        return !rc && o->fine_spacing == 0 ? fail(err, cap, "'%s' must be > 0", key) : rc;
    }
    char text[32];
    if (!strcmp(key, "field")) {
        if (name(item, key, text, sizeof text, err, cap))
            return SDF_EINVAL;
        if (strcasecmp(text, "raw") && strcasecmp(text, "filtered"))
            return fail(err, cap, "'%s' must be \"raw\" or \"filtered\"", key);
        *field = !strcasecmp(text, "filtered");
        return 0;
    }
    if (!strcmp(key, "encoding")) {
        if (name(item, key, text, sizeof text, err, cap) ||
            sdf_encoding_from_name(text, &o->encoding))
            return fail(err, cap, "'%s' must be \"float32\" or \"packed32\"", key);
        return 0;
    }
    if (!strcmp(key, "normalize")) {
        if (name(item, key, text, sizeof text, err, cap) ||
            sdf_normalize_from_name(text, &o->normalize))
            return fail(err, cap, "'%s' must be \"plane\" or \"gradient\"", key);
        return 0;
    }
    if (!strcmp(key, "sign")) {
        if (name(item, key, text, sizeof text, err, cap) ||
            sdf_sign_from_name(text, &o->query.sign))
            return fail(err, cap, "'%s' must be auto, pseudonormal, winding, raycast or none", key);
        return 0;
    }
    if (!strcmp(key, "filter")) {
        if (!cJSON_IsObject(item))
            return fail(err, cap, "'%s' must be an object", key);
        char *inner = cJSON_PrintUnformatted(item);
        if (!inner)
            return fail(err, cap, "out of memory reading '%s'", key);
        int rc = sdfd_filter_from_json(inner, strlen(inner), &out->filter, names->smoothing_mesh,
                                       err, cap);
        cJSON_free(inner);
        out->filtered = 1;
        if (!rc && out->filter.sample_gradient) /* a bake keeps values only */
            return fail(err, cap, "'%s' is for queries' gradients; a bake takes no gradient",
                        "sample_gradient");
        return rc;
    }
    int rc = sdfd_ops_key(item, &out->ops, ops_seen, err, cap);
    if (rc != SDFD_OPS_NOT_MINE)
        return rc;
    snprintf(err, cap, "unknown key '%s' (volume, mesh, bounds, margin, resolution, order, H, delta, "
                       "normalize, field, filter, encoding, sign, ops, solver, iterations, band, "
                       "strict)", key);
    return SDF_EINVAL;
}

int sdfd_bake_from_json(const char *text, size_t len, sdfd_bake_request *out,
                        sdfd_bake_names *names, char *err, size_t cap)
{
    memset(out, 0, sizeof *out);
    memset(names, 0, sizeof *names);
    sdfd_ops_defaults(&out->ops);
    cJSON *root;
    int rc = sdfd_json_body_object(text, len, &root, err, cap);
    if (rc)
        return rc;
    int field = -1;
    unsigned ops_seen = 0;
    for (const cJSON *item = root->child; !rc && item; item = item->next)
        rc = one_key(item, out, names, &field, &ops_seen, err, cap);
    if (!rc && ops_seen == SDFD_OPS_KEY_OTHER) /* a solver for no ops: a mistake */
        rc = fail(err, cap, "'solver', 'iterations', 'band' and 'strict' apply to '%s'; give "
                            "the operations too", "ops");
    if (!rc && field == 0 && out->filtered)
        rc = fail(err, cap, "a '%s' object needs \"field\": \"filtered\" (or no field)", "filter");
    if (!rc && field == 1)
        out->filtered = 1; /* the filter's defaults */
    if (out->options.lo[0] < out->options.hi[0])
        out->mesh_box = 0; /* bounds given: the margin does not apply */
    cJSON_Delete(root);
    return rc;
}
