/* parallel.h - a minimal parallel-for over an index range for batch calls.
 *
 * Threads are created per call: libsdf keeps no global pool (no global state), and a batch
 * large enough to be worth splitting amortises thread start-up many times over. Work is
 * handed out in chunks through an atomic counter, so a slow chunk never idles a core. */
#ifndef SDF_CORE_PARALLEL_H
#define SDF_CORE_PARALLEL_H

#include <stddef.h>

#define SDF__MAX_THREADS 256 /* workers of one call, at most */

/* Processes items [begin, end). `worker` is 0..threads-1 (for per-thread scratch). */
typedef void (*sdf__range_fn)(void *ctx, size_t begin, size_t end, int worker);

/* Number of online CPUs (at least 1). */
int sdf__cpu_count(void);

/* The thread count a batch of `count` items will use for `requested` (0 = all CPUs). */
int sdf__effective_threads(int requested, size_t count, size_t chunk);

/* Run fn over [0, count) in chunks of `chunk` items on `threads` threads (the caller's
 * thread is one of them). All work is always done: a thread that cannot start only costs
 * speed. Returns the number of threads that ran. */
int sdf__parallel_for(size_t count, size_t chunk, int threads, sdf__range_fn fn, void *ctx);

#endif
