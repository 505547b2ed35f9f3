/* check.h - the few assertion helpers the C tests share, and their main. A failed CHECK
 * prints where and why and counts. A test program is a table of named cases, each a function
 * that runs CHECKs; its main returns check_main(), which runs every case or the ones named on
 * the command line, so that one failing case can be run again alone (under gdb, rr, or a
 * sanitizer build) without the minutes the others take. */
#ifndef SDF_TESTS_CHECK_H
#define SDF_TESTS_CHECK_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "sdf/sdf.h"

/* Atomic: tests call CHECK from several threads at once (test_distance's concurrent
 * callers), which ThreadSanitizer rightly reported as a race on plain ints. */
extern _Atomic int check_failures;
extern _Atomic int check_count;

#define CHECK(cond, ...)                                                                   \
    do {                                                                                   \
        check_count++;                                                                     \
        if (!(cond)) {                                                                     \
            check_failures++;                                                              \
            fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond);       \
            fprintf(stderr, __VA_ARGS__);                                                  \
            fputc('\n', stderr);                                                           \
        }                                                                                  \
    } while (0)

/* One case of a test program: its name (what `test_X NAME` runs) and its function. */
typedef struct check_case {
    const char *name;
    void (*run)(void);
} check_case;

#define CHECK_COUNT_OF(cases) (sizeof(cases) / sizeof((cases)[0]))

/* A test program's main. No argument: every case in the table's order. Names: those cases, in
 * the order given. `--list`: the names, one a line, and exit 0. An unknown name prints the
 * names and fails. Each case prints its count of checks; the last line is
 * "`program`: N checks, N failed". Returns the exit code: non-zero if a CHECK failed or if a
 * case ran no CHECK at all (a test that checks nothing proves nothing). */
int check_main(const char *program, const check_case *cases, size_t n, int argc, char **argv);

/* Path of a file in tests/data (static buffer). */
const char *data_path(const char *file);

/* Load tests/data/`file`, failing a CHECK (and returning NULL) if it does not load. */
sdf_mesh *load_data_mesh(const char *file);

#endif
