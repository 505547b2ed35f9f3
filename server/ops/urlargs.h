/* urlargs.h - a request's URL arguments, and the check they pass against what its operation
 * takes (optable.h) before it acts (docs/api.md, "URL arguments").
 *
 * A server that looks up only the names it knows answers `?smoothness=3`, `?sample=8` or
 * `?samples=8&samples=9` as if they were not there, and the client never learns that its
 * parameter was not applied. So every operation lists its names (optable.c), and an
 * argument the operation does not take (with the nearest name it does take, when one is close),
 * one given twice, or one without a value is refused with SDF_EINVAL before the route runs.
 * Whether a known argument applies to the request (the filter's only with a filtered mode)
 * is the route's own rule, checked where the mode is known.
 *
 * Independent of libmicrohttpd: the HTTP front end collects the arguments (repeats and all)
 * into an sdfd_url_args, and the fuzz harness builds one from a query string. */
#ifndef SDFD_URLARGS_H
#define SDFD_URLARGS_H

#include <stddef.h>

#include "ops/optable.h"

#define SDFD_URL_MAX_ARGS 64

/* One argument as given; value NULL for "?name" without '='. */
typedef struct sdfd_url_arg {
    const char *name, *value;
} sdfd_url_arg;

typedef struct sdfd_url_args {
    sdfd_url_arg arg[SDFD_URL_MAX_ARGS];
    size_t n;     /* kept in arg[] */
    size_t given; /* in the URL: more than n when over SDFD_URL_MAX_ARGS (then refused) */
} sdfd_url_args;

/* Append one argument (the strings are borrowed, not copied). */
void sdfd_url_args_add(sdfd_url_args *args, const char *name, const char *value);

/* The value of `name`, or NULL when it is not given (or given without a value). */
const char *sdfd_url_value(const sdfd_url_args *args, const char *name);

/* sdfd_url_value for sdfd_filter_from_strings's lookup (ctx: the sdfd_url_args). */
const char *sdfd_url_lookup(void *ctx, const char *name);

/* The first argument given that is one of the filter's (filterparams.h), or NULL. */
const char *sdfd_url_first_filter_arg(const sdfd_url_args *args);

/* Every argument one `op` takes, given once, with a non-empty value. 0, or SDF_EINVAL with a
 * message in err and the argument's name in *argument ("" when none is to blame). */
int sdfd_url_args_check(const sdfd_url_args *args, const sdfd_op *op, char *err, size_t cap,
                        const char **argument);

#endif
