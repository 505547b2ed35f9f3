/* workers.h - threads for work that leaves its front end's thread (uploads, volume loads,
 * slices, volume queries): each task gets a thread at once, as a thread of its own would,
 * but a thread that finishes waits for the next task instead of exiting, up to `max_idle`
 * of them. Reusing threads matters beyond the cost of starting one: Embree keeps an
 * allocator for every thread that has ever built a mesh index until the process exits
 * (sdf.h), so a new thread per upload grows sdfd by that much each time.
 *
 * Thread-safe: any thread may call sdfd_workers_run. sdfd_workers_destroy waits for every
 * task to end, so it comes after the front ends have answered everything. */
#ifndef SDFD_WORKERS_H
#define SDFD_WORKERS_H

#include <stddef.h>

typedef struct sdfd_workers sdfd_workers;

/* sdfd keeps this many idle threads: more requests than that at once start threads that end
 * with them. */
#define SDFD_IDLE_WORKERS 8

/* 0 and *out, or -1 (out of memory or resources). */
int sdfd_workers_create(size_t max_idle, sdfd_workers **out);

/* Run fn(arg) on an idle thread, or on a new one when none is idle. 0, or -1 when no thread
 * could be started (fn is then not called). */
int sdfd_workers_run(sdfd_workers *w, void (*fn)(void *arg), void *arg);

/* Threads now waiting for a task, and threads started since creation. */
void sdfd_workers_counts(sdfd_workers *w, size_t *idle, size_t *started);

/* Waits for the running tasks to end, then ends every thread. NULL is ignored. */
void sdfd_workers_destroy(sdfd_workers *w);

#endif
