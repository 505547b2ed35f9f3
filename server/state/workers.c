/* workers.c - the thread cache of workers.h. A task waits in the queue only when an idle
 * thread is free to take it (queued < idle), so it never waits behind a busy one: otherwise
 * run starts a new thread with the task. Threads are detached; the pool counts them, and
 * destroy waits until the last has let go of the lock. */
#include "state/workers.h"

#include <pthread.h>
#include <stdlib.h>

typedef struct task {
    struct task *next;
    struct sdfd_workers *pool;
    void (*fn)(void *arg);
    void *arg;
} task;

struct sdfd_workers {
    pthread_mutex_t lock;
    pthread_cond_t wake; /* a task queued, or stopping */
    pthread_cond_t gone; /* a thread ended */
    task *head, *tail;
    size_t queued, idle, live, started, max_idle;
    int stopping;
};

int sdfd_workers_create(size_t max_idle, sdfd_workers **out)
{
    sdfd_workers *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    w->max_idle = max_idle;
    pthread_mutex_init(&w->lock, NULL);
    pthread_cond_init(&w->wake, NULL);
    pthread_cond_init(&w->gone, NULL);
    *out = w;
    return 0;
}

/* Under the lock: the oldest queued task, or NULL. */
static task *pop(sdfd_workers *w)
{
    task *t = w->head;
    if (t) {
        w->head = t->next;
        if (!w->head)
            w->tail = NULL;
        w->queued--;
    }
    return t;
}

static void *worker_main(void *arg)
{
    task *t = arg;
    sdfd_workers *w = t->pool;
    for (;;) {
        t->fn(t->arg);
        free(t);
        pthread_mutex_lock(&w->lock);
        if (!w->head && !w->stopping && w->idle < w->max_idle) {
            w->idle++;
            while (!w->head && !w->stopping)
                pthread_cond_wait(&w->wake, &w->lock);
            w->idle--;
        }
        if (!(t = pop(w)))
            break; /* with the lock held */
        pthread_mutex_unlock(&w->lock);
    }
    w->live--;
    pthread_cond_broadcast(&w->gone);
    pthread_mutex_unlock(&w->lock);
    return NULL;
}

int sdfd_workers_run(sdfd_workers *w, void (*fn)(void *arg), void *arg)
{
    task *t = malloc(sizeof *t);
    if (!t)
        return -1;
    *t = (task){.pool = w, .fn = fn, .arg = arg};
    pthread_mutex_lock(&w->lock);
    if (w->idle > w->queued) {
        if (w->tail)
            w->tail->next = t;
        else
            w->head = t;
        w->tail = t;
        w->queued++;
        pthread_cond_signal(&w->wake);
        pthread_mutex_unlock(&w->lock);
        return 0;
    }
    w->live++, w->started++;
    pthread_mutex_unlock(&w->lock);
    pthread_t thread;
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    int failed = pthread_create(&thread, &attr, worker_main, t);
    pthread_attr_destroy(&attr);
    if (failed) {
        pthread_mutex_lock(&w->lock);
        w->live--, w->started--;
        pthread_cond_broadcast(&w->gone);
        pthread_mutex_unlock(&w->lock);
        free(t);
        return -1;
    }
    return 0;
}

void sdfd_workers_counts(sdfd_workers *w, size_t *idle, size_t *started)
{
    pthread_mutex_lock(&w->lock);
    *idle = w->idle;
    *started = w->started;
    pthread_mutex_unlock(&w->lock);
}

void sdfd_workers_destroy(sdfd_workers *w)
{
    if (!w)
        return;
    pthread_mutex_lock(&w->lock);
    w->stopping = 1;
    pthread_cond_broadcast(&w->wake);
    while (w->live > 0)
        pthread_cond_wait(&w->gone, &w->lock);
    pthread_mutex_unlock(&w->lock);
    pthread_cond_destroy(&w->wake);
    pthread_cond_destroy(&w->gone);
    pthread_mutex_destroy(&w->lock);
    free(w);
}
