/* bigmem.c - scratch arrays of megabytes on huge pages (see bigmem.h). */
#include "core/bigmem.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

#define HUGE_PAGE ((size_t)2 << 20)

static size_t whole_huge_pages(size_t bytes)
{
    return (bytes + HUGE_PAGE - 1) / HUGE_PAGE * HUGE_PAGE;
}

void *sdf__big_alloc(size_t bytes)
{
    if (bytes < HUGE_PAGE)
        return malloc(bytes ? bytes : 1);
    if (bytes > SIZE_MAX / 2) /* past what sdf__big_size can describe; no machine has it */
        return NULL;
    size_t rounded = whole_huge_pages(bytes);
    void *p = aligned_alloc(HUGE_PAGE, rounded); /* C11: a multiple of the alignment */
#ifdef MADV_HUGEPAGE
    if (p)
        (void)madvise(p, rounded, MADV_HUGEPAGE); /* advice only: refused, the pages are small */
#endif
    return p;
}

size_t sdf__big_size(size_t bytes)
{
    if (bytes < HUGE_PAGE || bytes > SIZE_MAX / 2)
        return bytes;
    return whole_huge_pages(bytes) + HUGE_PAGE;
}

void sdf__big_free(void *p) { free(p); }
