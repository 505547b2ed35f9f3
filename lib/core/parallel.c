/* parallel.c - chunked parallel-for on pthreads (see parallel.h for why). */
#include "core/parallel.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>


typedef struct job {
    atomic_size_t next;
    size_t count, chunk;
    sdf__range_fn fn;
    void *ctx;
} job;

typedef struct worker_arg {
    job *job;
    int index;
} worker_arg;

int sdf__cpu_count(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (n > SDF__MAX_THREADS ? SDF__MAX_THREADS : (int)n);
}

int sdf__effective_threads(int requested, size_t count, size_t chunk)
{
    int threads = requested > 0 ? requested : sdf__cpu_count();
    if (threads > SDF__MAX_THREADS)
        threads = SDF__MAX_THREADS;
    size_t chunks = chunk ? (count + chunk - 1) / chunk : 1;
    if ((size_t)threads > chunks)
        threads = chunks ? (int)chunks : 1;
    return threads;
}

static void run_chunks(job *j, int index)
{
    for (;;) {
        size_t begin = atomic_fetch_add(&j->next, j->chunk);
        if (begin >= j->count)
            return;
        size_t end = begin + j->chunk < j->count ? begin + j->chunk : j->count;
        j->fn(j->ctx, begin, end, index);
    }
}

static void *worker_main(void *p)
{
    worker_arg *a = p;
    run_chunks(a->job, a->index);
    return NULL;
}

int sdf__parallel_for(size_t count, size_t chunk, int threads, sdf__range_fn fn, void *ctx)
{
    if (chunk == 0)
        chunk = 1;
    threads = sdf__effective_threads(threads, count, chunk);
    job j = {.count = count, .chunk = chunk, .fn = fn, .ctx = ctx};
    atomic_init(&j.next, 0);
    if (threads <= 1) {
        run_chunks(&j, 0);
        return 1;
    }
    pthread_t tid[SDF__MAX_THREADS];
    worker_arg args[SDF__MAX_THREADS];
    int started = 0;
    for (int i = 1; i < threads; i++) {
        args[i] = (worker_arg){&j, i};
        if (pthread_create(&tid[i], NULL, worker_main, &args[i]) != 0)
            break;
        started++;
    }
    run_chunks(&j, 0);
    for (int i = 1; i <= started; i++)
        pthread_join(tid[i], NULL);
    return started + 1;
}
