/* bigmem.h - scratch arrays of megabytes, backed by huge pages where the kernel offers them.
 *
 * Batch calls allocate their scratch (a query's visit-order copies and Morton keys, a
 * filtered block's samples, a bake's per-worker bests) and free it before they return. Arrays
 * that large come fresh from the kernel each call and are first touched page by page: on the
 * virtualised machines this project runs on, a 4 KiB page fault costs microseconds, and a
 * bake's per-worker bests took their faults on their first writes. 2 MiB pages take 512
 * times fewer faults. Linux usually offers transparent huge pages only where a range is
 * advised (THP "madvise" mode), so these allocations are aligned to 2 MiB and advised;
 * elsewhere the advice is a no-op. */
#ifndef SDF_CORE_BIGMEM_H
#define SDF_CORE_BIGMEM_H

#include <stddef.h>

/* Like malloc(bytes) (NULL when out of memory); from 2 MiB up, on huge pages where the
 * kernel has them. Free with sdf__big_free. */
void *sdf__big_alloc(size_t bytes);

/* At most the bytes sdf__big_alloc(bytes) holds, as malloc_usable_size counts them: from
 * 2 MiB up, rounded up to whole huge pages plus the alignment's slack (scratch bounds add
 * this, not `bytes`, for each such array). */
size_t sdf__big_size(size_t bytes);

/* Frees what sdf__big_alloc returned; NULL is a no-op. */
void sdf__big_free(void *p);

#endif
