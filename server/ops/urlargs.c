/* urlargs.c - the check of a request's URL arguments against its operation's (urlargs.h).
 *
 * What each operation takes is its line of optable.c. A refused name gets the nearest name
 * the operation takes when it is a likely misspelling (an edit or two away), because
 * "unknown argument 'sample'" alone sends the client to the docs for what "did you mean
 * 'samples'?" says at once. */
#include "ops/urlargs.h"

#include <stdio.h>
#include <string.h>

#include "ops/filterparams.h"

/* Names closer than this many edits (and than half the given name's length) are suggested. */
#define SUGGEST_EDITS 2
#define SUGGEST_LEN 64 /* longer names are not compared */

void sdfd_url_args_add(sdfd_url_args *args, const char *name, const char *value)
{
    if (args->n < SDFD_URL_MAX_ARGS)
        args->arg[args->n++] = (sdfd_url_arg){name, value};
    args->given++;
}

const char *sdfd_url_value(const sdfd_url_args *args, const char *name)
{
    for (size_t i = 0; i < args->n; i++)
        if (!strcmp(args->arg[i].name, name))
            return args->arg[i].value;
    return NULL;
}

const char *sdfd_url_lookup(void *ctx, const char *name)
{
    return sdfd_url_value(ctx, name);
}

const char *sdfd_url_first_filter_arg(const sdfd_url_args *args)
{
    for (size_t i = 0; i < args->n; i++)
        if (sdfd_filter_is_url_name(args->arg[i].name))
            return args->arg[i].name;
    return NULL;
}

static size_t least(size_t x, size_t y)
{
    return x < y ? x : y;
}

/* Edits (insert, delete, replace, swap two neighbours) from a to b; both < SUGGEST_LEN. */
static size_t edits(const char *a, const char *b)
{
    size_t n = strlen(a), m = strlen(b);
    unsigned char d[SUGGEST_LEN + 1][SUGGEST_LEN + 1]; /* at most 2 * SUGGEST_LEN */
    for (size_t i = 0; i <= n; i++)
        for (size_t j = 0; j <= m; j++) {
            size_t e = i + j; /* one side empty */
            if (i && j)
                e = least((size_t)d[i - 1][j - 1] + (a[i - 1] != b[j - 1]),
                          least((size_t)d[i - 1][j], (size_t)d[i][j - 1]) + 1);
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
                e = least(e, (size_t)d[i - 2][j - 2] + 1);
            d[i][j] = (unsigned char)e;
        }
    return d[n][m];
}

/* The name t takes that `given` is likely a misspelling of, or NULL. */
static const char *nearest(const sdfd_op *t, const char *given)
{
    size_t len = strlen(given), best_edits = SUGGEST_EDITS + 1;
    const char *best = NULL;
    for (size_t i = 0; len < SUGGEST_LEN && sdfd_op_arg(t, i); i++) {
        const char *name = sdfd_op_arg(t, i);
        size_t n = strlen(name), apart = n > len ? n - len : len - n; /* edits >= apart */
        size_t e = n < SUGGEST_LEN && apart < best_edits ? edits(given, name) : best_edits;
        if (e < best_edits && 2 * e <= len)
            best = name, best_edits = e;
    }
    return best;
}

/* Whether any route takes `name`: then it is misplaced here, not misspelt. */
static int known_anywhere(const char *name)
{
    for (size_t i = 0; i < SDFD_OP_COUNT; i++)
        if (sdfd_op_takes(sdfd_op_get((sdfd_op_id)i), name))
            return 1;
    return 0;
}

/* "unknown argument 'sample' (did you mean 'samples'?)", or what the route takes. */
static int unknown(const sdfd_op *t, const char *name, char *err, size_t cap)
{
    int elsewhere = known_anywhere(name);
    const char *near = elsewhere ? NULL : nearest(t, name);
    size_t at = (size_t)snprintf(err, cap, elsewhere ? "argument '%.40s' is not this route's"
                                                     : "unknown argument '%.40s'", name);
    if (at < cap && near)
        snprintf(err + at, cap - at, " (did you mean '%s'?)", near);
    else if (at < cap && !sdfd_op_arg(t, 0))
        snprintf(err + at, cap - at, ": this route takes no URL arguments");
    for (size_t i = 0; !near && sdfd_op_arg(t, i) && at < cap; i++)
        at += (size_t)snprintf(err + at, cap - at, "%s %s", i ? "," : ": this route takes",
                               sdfd_op_arg(t, i));
    return SDF_EINVAL;
}

int sdfd_url_args_check(const sdfd_url_args *args, const sdfd_op *t, char *err, size_t cap,
                        const char **argument)
{
    *argument = "";
    if (args->given > SDFD_URL_MAX_ARGS) {
        snprintf(err, cap, "more than %d URL arguments", SDFD_URL_MAX_ARGS);
        return SDF_EINVAL;
    }
    for (size_t i = 0; i < args->n; i++) {
        const sdfd_url_arg *a = &args->arg[i];
        *argument = a->name;
        if (!sdfd_op_takes(t, a->name))
            return unknown(t, a->name, err, cap);
        for (size_t j = 0; j < i; j++)
            if (!strcmp(args->arg[j].name, a->name)) {
                snprintf(err, cap, "argument '%.40s' is given twice", a->name);
                return SDF_EINVAL;
            }
        if (!a->value || !a->value[0]) {
            snprintf(err, cap, "argument '%.40s' needs a value", a->name);
            return SDF_EINVAL;
        }
    }
    *argument = "";
    return 0;
}
