/* args.c - sdfq's option parser (args.h). Small on purpose: getopt_long would not know the
 * subcommands' own option sets, and each refusal here names the subcommand. */
#include "args.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static sdfq_opt *find(sdfq_args *a, const char *name, size_t len)
{
    for (int i = 0; i < a->nopts; i++)
        if (strlen(a->opts[i].name) == len && !strncmp(a->opts[i].name, name, len))
            return &a->opts[i];
    return NULL;
}

/* One option at argv[*i]; 0 or 1 after a message. */
static int take_option(sdfq_args *a, int argc, char **argv, int *i)
{
    const char *arg = argv[*i];
    const char *name = arg + (arg[1] == '-' ? 2 : 1);
    const char *eq = strchr(name, '=');
    size_t len = eq ? (size_t)(eq - name) : strlen(name);
    sdfq_opt *o = find(a, name, len);
    if (!o || (arg[1] != '-') != (strlen(o->name) == 1)) {
        fprintf(stderr, "sdfq %s: unknown option %.*s (see sdfq %s --help)\n", a->cmd,
                (int)(len + (size_t)(name - arg)), arg, a->cmd);
        return 1;
    }
    if (!o->takes_value) {
        if (eq) {
            fprintf(stderr, "sdfq %s: option %s takes no value\n", a->cmd, o->name);
            return 1;
        }
        o->value = "1";
        return 0;
    }
    if (eq) {
        o->value = eq + 1;
    } else if (*i + 1 < argc) {
        o->value = argv[++*i];
    } else {
        fprintf(stderr, "sdfq %s: option %s needs a value\n", a->cmd, arg);
        return 1;
    }
    if (o->takes_value == 2) {
        if (o->count == SDFQ_MAX_REPEAT) {
            fprintf(stderr, "sdfq %s: option %s given more than %d times\n", a->cmd, o->name,
                    SDFQ_MAX_REPEAT);
            return 1;
        }
        o->values[o->count++] = o->value;
    }
    return 0;
}

int sdfq_parse(sdfq_args *a, const char *cmd, sdfq_opt *opts, int nopts, int argc, char **argv)
{
    *a = (sdfq_args){.cmd = cmd, .opts = opts, .nopts = nopts};
    for (int i = 0; i < nopts; i++)
        opts[i].value = NULL, opts[i].count = 0;
    int options = 1;
    for (int i = 0; i < argc; i++) {
        const char *arg = argv[i];
        if (options && !strcmp(arg, "--")) {
            options = 0;
        } else if (options && arg[0] == '-' && arg[1]) {
            if (take_option(a, argc, argv, &i))
                return 1;
        } else if (a->npos < SDFQ_MAX_POS) {
            a->pos[a->npos++] = arg;
        } else {
            fprintf(stderr, "sdfq %s: too many arguments\n", cmd);
            return 1;
        }
    }
    return 0;
}

const sdfq_opt *sdfq_opt_find(const sdfq_args *a, const char *name)
{
    for (int i = 0; i < a->nopts; i++)
        if (!strcmp(a->opts[i].name, name))
            return &a->opts[i];
    return NULL;
}

const char *sdfq_opt_value(const sdfq_args *a, const char *name)
{
    for (int i = 0; i < a->nopts; i++)
        if (!strcmp(a->opts[i].name, name))
            return a->opts[i].value;
    return NULL;
}

int sdfq_opt_long(const sdfq_args *a, const char *name, long lo, long hi, long *out)
{
    const char *v = sdfq_opt_value(a, name);
    if (!v)
        return 0;
    char *end;
    errno = 0;
    long x = strtol(v, &end, 10);
    if (errno || end == v || *end || x < lo || x > hi) {
        fprintf(stderr, "sdfq %s: --%s must be an integer in %ld..%ld, not '%s'\n", a->cmd, name,
                lo, hi, v);
        return 1;
    }
    *out = x;
    return 0;
}

int sdfq_opt_double(const sdfq_args *a, const char *name, double *out)
{
    const char *v = sdfq_opt_value(a, name);
    if (!v)
        return 0;
    char *end;
    errno = 0;
    double x = strtod(v, &end);
    if (errno || end == v || *end || !isfinite(x)) {
        fprintf(stderr, "sdfq %s: --%s must be a finite number, not '%s'\n", a->cmd, name, v);
        return 1;
    }
    *out = x;
    return 0;
}

int sdfq_opt_u64(const sdfq_args *a, const char *name, uint64_t *out)
{
    const char *v = sdfq_opt_value(a, name);
    if (!v)
        return 0;
    char *end;
    errno = 0;
    unsigned long long x = strtoull(v, &end, 10);
    if (errno || end == v || *end || v[0] == '-') {
        fprintf(stderr, "sdfq %s: --%s must be an unsigned integer, not '%s'\n", a->cmd, name, v);
        return 1;
    }
    *out = x;
    return 0;
}
