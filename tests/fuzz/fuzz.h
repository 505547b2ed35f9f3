/* fuzz.h - what the libFuzzer harnesses of tests/fuzz/ share.
 *
 * Each harness is one .c file defining LLVMFuzzerTestOneInput for one input surface. Built
 * with -Dfuzz=true (clang) it is a libFuzzer target; in every build it is also compiled into
 * the replay test (replay.c), renamed by -DLLVMFuzzerTestOneInput=fuzz_<harness>, which feeds
 * it the corpus and the regression inputs. A harness returns 0 and aborts only on a broken
 * promise of the code it drives (a result that contradicts the documented contract), so the
 * sanitizers and these checks are what find bugs. */
#ifndef SDF_TESTS_FUZZ_H
#define SDF_TESTS_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sdf/sdf.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* A malloc'd copy of the input with a NUL after it (the parsers of sdfd want one), or NULL. */
static inline char *fuzz_text(const uint8_t *data, size_t size)
{
    char *t = malloc(size + 1);
    if (t) {
        if (size)
            memcpy(t, data, size);
        t[size] = 0;
    }
    return t;
}

/* Abort with a message: a harness's own check failed. */
#define FUZZ_CHECK(cond)                                                                     \
    do {                                                                                     \
        if (!(cond)) {                                                                       \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);         \
            abort();                                                                         \
        }                                                                                    \
    } while (0)

/* Read every byte of [p, p + n) so the address sanitizer sees a read past a buffer. */
static inline unsigned fuzz_touch(const void *p, size_t n)
{
    const volatile unsigned char *b = p;
    unsigned sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += b[i];
    return sum;
}

/* Read n floats as floats, as sdfd reads points: the sanitizers see an overrun and a
 * misaligned pointer (plain loads: the undefined-behaviour sanitizer does not check the
 * alignment of volatile ones). */
static inline void fuzz_touch_floats(const float *p, size_t n)
{
    float sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += p[i];
    __asm__ volatile("" : : "g"(sum)); /* the sum is used: the loads cannot go */
}

/* The built-in demo mesh, made on first use and kept (still reachable at exit): the harnesses
 * of option parsers hand what they parsed to the library's own checks on it, as sdfd does
 * with a loaded mesh. NULL if it cannot be made. */
static inline sdf_mesh *fuzz_demo_mesh(void)
{
    static sdf_mesh *demo;
    if (!demo && sdf_mesh_create_demo(&demo))
        demo = NULL;
    return demo;
}

#endif
