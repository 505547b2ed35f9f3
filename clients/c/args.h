/* args.h - sdfq's command-line options: each subcommand names the options it takes, the
 * parser fills their values and the positional arguments, and refuses anything else with a
 * one-line message (exit 1). Options may come before or after positionals; `--name=value`
 * and `--name value` are the same; `--` ends the options; `-` alone is a positional. An
 * option given twice keeps its last value, unless it is repeatable (bake --op), which keeps
 * each. */
#ifndef SDFQ_ARGS_H
#define SDFQ_ARGS_H

#include <stdint.h>

#define SDFQ_MAX_POS 66    /* sdfq ops: a volume and the API's 64 operations (and one more,
                              so that 65 operations reach the server's refusal) */
#define SDFQ_MAX_REPEAT 65 /* values of a repeatable option (bake --op), as many */

typedef struct sdfq_opt {
    const char *name;  /* without dashes: "mode"; "o" is written -o */
    int takes_value;   /* 0 a flag, 1 a value, 2 a value that may be given again */
    const char *value; /* out: the (last) value, or "1" for a flag given; NULL when absent */
    const char *values[SDFQ_MAX_REPEAT]; /* out, takes_value 2: each value in order */
    int count;
} sdfq_opt;

typedef struct sdfq_args {
    const char *cmd;
    sdfq_opt *opts;
    int nopts;
    const char *pos[SDFQ_MAX_POS];
    int npos;
} sdfq_args;

/* Parse argv[0..argc) for command `cmd` against opts (values reset first). 0, or 1 after
 * printing why on stderr. */
int sdfq_parse(sdfq_args *a, const char *cmd, sdfq_opt *opts, int nopts, int argc, char **argv);
/* The value of option `name` (NULL when not given). */
const char *sdfq_opt_value(const sdfq_args *a, const char *name);
/* Option `name` itself (its values and count when repeatable); NULL if the command has none. */
const sdfq_opt *sdfq_opt_find(const sdfq_args *a, const char *name);
/* Numbers from options: 0, or 1 after a message naming the option. `lo`..`hi` bounds. */
int sdfq_opt_long(const sdfq_args *a, const char *name, long lo, long hi, long *out);
int sdfq_opt_double(const sdfq_args *a, const char *name, double *out);
int sdfq_opt_u64(const sdfq_args *a, const char *name, uint64_t *out);

#endif
