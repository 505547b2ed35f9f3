/* opsparams.c - the field operations' JSON (see opsparams.h), read with cJSON as the bake's
 * body is (bakeparams.c), of which it parses the "ops" keys too. */
#include "ops/opsparams.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/errors.h"
#include "ops/filterparams.h" /* sdfd_json_body_object */

#define OP_NAMES "redistance, offset, round, fillet, smooth"

static int fail(char *err, size_t cap, const char *fmt, const char *key)
{
    snprintf(err, cap, fmt, key);
    return SDF_EINVAL;
}

void sdfd_ops_defaults(sdfd_ops_request *out)
{
    memset(out, 0, sizeof *out);
    out->options.solver = SDF_FIELD_SWEEP; /* docs/volumes.md: as exact, and faster */
}

/* ops[i]: {"name": r}. */
static int one_op(const cJSON *item, size_t i, sdf_field_op *op, char *err, size_t cap)
{
    const cJSON *key = cJSON_IsObject(item) ? item->child : NULL;
    if (!key || key->next) {
        snprintf(err, cap, "ops[%zu] must be an object of exactly one key, an operation's name "
                 "(" OP_NAMES ") with its r as the value, e.g. {\"round\": 0.05}", i);
        return SDF_EINVAL;
    }
    if (sdf_field_op_from_name(key->string, &op->kind) ||
        strcmp(key->string, sdf_field_op_name(op->kind))) { /* the names as documented */
        snprintf(err, cap, "ops[%zu]: unknown operation '%.60s' (" OP_NAMES ")", i, key->string);
        return SDF_EINVAL;
    }
    if (!cJSON_IsNumber(key) || !isfinite(key->valuedouble) || fabs(key->valuedouble) > FLT_MAX) {
        snprintf(err, cap, "ops[%zu].%s must be a number (its r, a length)", i, key->string);
        return SDF_EINVAL;
    }
    op->r = (float)key->valuedouble;
    return 0;
}

static int ops_list(const cJSON *item, sdfd_ops_request *out, char *err, size_t cap)
{
    int n = cJSON_IsArray(item) ? cJSON_GetArraySize(item) : -1;
    if (n < 1 || n > SDF_FIELD_MAX_OPS) {
        snprintf(err, cap, "'ops' must be an array of 1..%d operations, e.g. "
                 "[{\"round\": 0.05}]", SDF_FIELD_MAX_OPS);
        return SDF_EINVAL;
    }
    size_t i = 0;
    for (const cJSON *op = item->child; op; op = op->next, i++)
        if (one_op(op, i, &out->ops[i], err, cap))
            return SDF_EINVAL;
    out->count = i;
    return 0;
}

int sdfd_ops_key(const cJSON *item, sdfd_ops_request *out, unsigned *seen, char *err,
                 size_t cap)
{
    const char *key = item->string;
    sdf_field_options *o = &out->options;
    if (!strcmp(key, "ops")) {
        *seen |= SDFD_OPS_KEY_OPS;
        return ops_list(item, out, err, cap);
    }
    if (strcmp(key, "solver") && strcmp(key, "iterations") && strcmp(key, "band") &&
        strcmp(key, "strict"))
        return SDFD_OPS_NOT_MINE;
    *seen |= SDFD_OPS_KEY_OTHER;
    if (!strcmp(key, "solver")) {
        if (!cJSON_IsString(item) || sdf_field_solver_from_name(item->valuestring, &o->solver) ||
            strcmp(item->valuestring, sdf_field_solver_name(o->solver)))
            return fail(err, cap, "'%s' must be \"sweep\", \"sussman\" or \"exact\"", key);
        return 0;
    }
    if (!strcmp(key, "strict")) {
        if (!cJSON_IsBool(item))
            return fail(err, cap, "'%s' must be true or false", key);
        o->strict = cJSON_IsTrue(item);
        return 0;
    }
    double v = cJSON_IsNumber(item) ? item->valuedouble : NAN;
    if (!strcmp(key, "iterations")) {
        if (!(v >= 0 && v <= 1e6) || v != floor(v))
            return fail(err, cap, "'%s' must be a whole number 0..1000000 (0: derived)", key);
        o->iterations = (int)v;
        return 0;
    }
    if (!(v >= 0 && isfinite(v)))
        return fail(err, cap, "'%s' must be a length >= 0 (0: the library's default)", key);
    o->band = v;
    return 0;
}

static int one_key(const cJSON *item, sdfd_ops_request *out, char volume[SDFD_MAX_NAME + 1],
                   unsigned *seen, char *err, size_t cap)
{
    const char *key = item->string;
    if (!strcmp(key, "volume")) {
        if (!cJSON_IsString(item) ||
            !sdfd_valid_name(item->valuestring, strlen(item->valuestring)))
            return fail(err, cap, "'%s' must be 1-255 characters of A-Z a-z 0-9 . _ - "
                                  "not starting with '.'", key);
        snprintf(volume, SDFD_MAX_NAME + 1, "%s", item->valuestring);
        return 0;
    }
    int rc = sdfd_ops_key(item, out, seen, err, cap);
    if (rc == SDFD_OPS_NOT_MINE)
        return fail(err, cap, "unknown key '%.60s' (ops, volume, solver, iterations, band, "
                              "strict)", key);
    return rc;
}

int sdfd_ops_from_json(const char *text, size_t len, sdfd_ops_request *out,
                       char volume[SDFD_MAX_NAME + 1], char *err, size_t cap)
{
    sdfd_ops_defaults(out);
    volume[0] = '\0';
    cJSON *root;
    int rc = sdfd_json_body_object(text, len, &root, err, cap);
    if (rc)
        return rc;
    unsigned seen = 0;
    for (const cJSON *item = root->child; !rc && item; item = item->next)
        rc = one_key(item, out, volume, &seen, err, cap);
    if (!rc && !(seen & SDFD_OPS_KEY_OPS))
        rc = fail(err, cap, "'%s' is required: an array of operations, e.g. "
                            "[{\"round\": 0.05}]", "ops");
    cJSON_Delete(root);
    return rc;
}
