/* filterparams.c - filter parameters from JSON or URL arguments (see filterparams.h). */
#include "filterparams.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

enum kind { NUMBER, COUNT, FLAG, KERNEL, SEED };

static const struct field {
    const char *name;
    enum kind kind;
} fields[] = {
    {"kernel", KERNEL}, {"cap", NUMBER},   {"a", NUMBER},       {"b", NUMBER},
    {"samples", COUNT}, {"grid", FLAG},    {"unsigned", FLAG},  {"allow_wide_bump", FLAG},
    {"seed", SEED},
};
#define FIELDS (sizeof fields / sizeof fields[0])

#define MAX_SEED 9007199254740992.0 /* 2^53: every integer up to it is exact in JSON */

static int bad(char *err, size_t cap, const char *fmt, const char *name)
{
    snprintf(err, cap, fmt, name);
    return SDF_EINVAL;
}

/* Store one value. `number` for NUMBER/COUNT/SEED/FLAG, `text` for KERNEL. */
static int store(sdf_filter_options *f, const struct field *fd, double number, const char *text,
                 char *err, size_t cap)
{
    switch (fd->kind) {
    case KERNEL:
        if (!strcmp(text, "gaussian"))
            f->kernel = SDF_KERNEL_GAUSSIAN;
        else if (!strcmp(text, "bump"))
            f->kernel = SDF_KERNEL_BUMP;
        else
            return bad(err, cap, "filter kernel must be \"gaussian\" or \"bump\", not \"%.40s\"",
                       text);
        return 0;
    case NUMBER:
        if (!isfinite(number))
            return bad(err, cap, "filter %s must be a finite number", fd->name);
        if (!strcmp(fd->name, "cap"))
            f->cap = number;
        else if (!strcmp(fd->name, "a"))
            f->a = number;
        else
            f->b = number;
        return 0;
    case COUNT:
        if (number != floor(number) || number < 1 || number > SDF_FILTER_MAX_SAMPLES)
            return bad(err, cap, "filter samples must be an integer 1..4096", NULL);
        f->samples = (int)number;
        return 0;
    case SEED:
        if (number != floor(number) || number < 0 || number > MAX_SEED)
            return bad(err, cap, "filter seed must be an integer 0..2^53", NULL);
        f->seed = (uint64_t)number;
        return 0;
    case FLAG:
        if (fd->name[0] == 'g')
            f->grid = number != 0;
        else if (fd->name[0] == 'u')
            f->unsigned_integrand = number != 0;
        else
            f->allow_wide_bump = number != 0;
        return 0;
    }
    return SDF_EINVAL;
}

static const struct field *find(const char *name)
{
    for (size_t i = 0; i < FIELDS; i++)
        if (!strcmp(fields[i].name, name))
            return &fields[i];
    return NULL;
}

int sdfd_filter_from_json(const char *text, size_t len, sdf_filter_options *out, char *err,
                          size_t cap)
{
    *out = (sdf_filter_options){0};
    cJSON *root = cJSON_ParseWithLength(text, len);
    if (!cJSON_IsObject(root)) {
        cJSON_Delete(root);
        return bad(err, cap, "\"filter\" must be a JSON object", NULL);
    }
    int rc = 0;
    for (cJSON *item = root->child; item && !rc; item = item->next) {
        const struct field *fd = item->string ? find(item->string) : NULL;
        if (!fd) {
            rc = bad(err, cap, "unknown filter parameter \"%.40s\" (kernel, cap, a, b, samples, "
                     "grid, unsigned, allow_wide_bump, seed)", item->string ? item->string : "");
        } else if (fd->kind == KERNEL) {
            rc = cJSON_IsString(item) ? store(out, fd, 0, item->valuestring, err, cap)
                                      : bad(err, cap, "filter %s must be a string", fd->name);
        } else if (fd->kind == FLAG) {
            rc = cJSON_IsBool(item) ? store(out, fd, cJSON_IsTrue(item), NULL, err, cap)
                                    : bad(err, cap, "filter %s must be true or false", fd->name);
        } else {
            rc = cJSON_IsNumber(item) ? store(out, fd, item->valuedouble, NULL, err, cap)
                                      : bad(err, cap, "filter %s must be a number", fd->name);
        }
    }
    cJSON_Delete(root);
    return rc;
}

int sdfd_filter_from_strings(const char *(*lookup)(void *ctx, const char *name), void *ctx,
                             sdf_filter_options *out, char *err, size_t cap)
{
    *out = (sdf_filter_options){0};
    for (size_t i = 0; i < FIELDS; i++) {
        const struct field *fd = &fields[i];
        const char *v = lookup(ctx, fd->name);
        if (!v)
            continue;
        int rc;
        if (fd->kind == KERNEL) {
            rc = store(out, fd, 0, v, err, cap);
        } else if (fd->kind == FLAG) {
            int on = !strcmp(v, "1") || !strcmp(v, "true"), off = !strcmp(v, "0") || !strcmp(v, "false");
            rc = on || off ? store(out, fd, on, NULL, err, cap)
                           : bad(err, cap, "filter %s must be true, false, 1 or 0", fd->name);
        } else {
            char *end;
            errno = 0;
            double number = strtod(v, &end);
            rc = *v && !*end && !errno ? store(out, fd, number, NULL, err, cap)
                                      : bad(err, cap, "filter %s must be a number", fd->name);
        }
        if (rc)
            return rc;
    }
    return 0;
}
