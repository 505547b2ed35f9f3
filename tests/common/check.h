/* check.h - the few assertion helpers the C tests share. A failed CHECK prints where and
 * why and counts; a test's main returns check_finish(), non-zero if anything failed. */
#ifndef SDF_TESTS_CHECK_H
#define SDF_TESTS_CHECK_H

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

/* Print a summary line and return the process exit code. */
int check_finish(const char *name);

/* Path of a file in tests/data (static buffer). */
const char *data_path(const char *file);

/* Load tests/data/`file`, failing a CHECK (and returning NULL) if it does not load. */
sdf_mesh *load_data_mesh(const char *file);

#endif
