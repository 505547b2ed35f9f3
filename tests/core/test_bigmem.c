/* test_bigmem.c - sdf__big_alloc gives writable arrays of the size asked, 2 MiB-aligned from
 * 2 MiB up (so the whole array can be huge pages), and never holds more than sdf__big_size
 * says: the scratch bounds (sdf_volume_bake_scratch and the query bounds) rely on that. */
#define _GNU_SOURCE
#include <malloc.h>
#include <stdint.h>
#include <string.h>

#include "../common/check.h"
#include "core/bigmem.h"

static void test_sizes(void)
{
    const size_t mib = (size_t)1 << 20;
    const size_t sizes[] = {1, 4096, 2 * mib - 1, 2 * mib, 2 * mib + 1, 5 * mib + 123, 64 * mib};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        size_t n = sizes[i];
        unsigned char *p = sdf__big_alloc(n);
        CHECK(p != NULL, "%zu bytes: no memory", n);
        if (!p)
            continue;
        memset(p, 0xab, n); /* every byte writable (the sanitizer builds check the ends) */
        CHECK(p[0] == 0xab && p[n - 1] == 0xab, "%zu bytes: not kept", n);
        CHECK(sdf__big_size(n) >= n, "%zu bytes: size %zu", n, sdf__big_size(n));
        if (n >= 2 * mib) {
            CHECK((uintptr_t)p % (2 * mib) == 0, "%zu bytes at %p: not 2 MiB-aligned", n,
                  (void *)p);
            CHECK(malloc_usable_size(p) <= sdf__big_size(n), "%zu bytes: holds %zu > %zu", n,
                  malloc_usable_size(p), sdf__big_size(n));
        }
        sdf__big_free(p);
    }
    CHECK(sdf__big_alloc(SIZE_MAX) == NULL, "SIZE_MAX bytes were given");
    CHECK(sdf__big_alloc(SIZE_MAX - mib) == NULL, "SIZE_MAX - 1 MiB bytes were given");
    sdf__big_free(NULL);
}

static const check_case cases[] = {
    {"sizes", test_sizes},
};

int main(int argc, char **argv)
{
    return check_main("bigmem", cases, CHECK_COUNT_OF(cases), argc, argv);
}
