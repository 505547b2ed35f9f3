/* test_workers.c - server/state/workers.c, the threads uploads, slices and volume queries run on:
 *  - tasks run one after another reuse one thread (a thread per task is what it replaces:
 *    Embree keeps memory for every thread that has built an index);
 *  - tasks that block until all of them run at once each get a thread at once: none waits
 *    behind a busy one (the 40 meet at a barrier that needs all 40);
 *  - after such a burst at most SDFD_IDLE_WORKERS threads stay idle;
 *  - many threads submitting at once: every task runs exactly once;
 *  - destroy waits for a task still running. */
#include <pthread.h>
#include <stdatomic.h>
#include <unistd.h>

#include "../common/check.h"
#include "state/workers.h"

static atomic_int ran;

static void count(void *arg)
{
    (void)arg;
    atomic_fetch_add(&ran, 1);
}

/* Run n tasks one at a time (each waits for the last to end), then wait until its thread
 * is idle again, so the next one could reuse it. */
static void one_at_a_time(sdfd_workers *w, int n)
{
    for (int i = 0; i < n; i++) {
        int before = atomic_load(&ran);
        CHECK(sdfd_workers_run(w, count, NULL) == 0, "run %d", i);
        size_t idle = 0, started;
        while (atomic_load(&ran) == before || idle == 0) {
            usleep(100);
            sdfd_workers_counts(w, &idle, &started);
        }
    }
}

#define BURST 40
static pthread_barrier_t meet;

static void wait_for_all(void *arg)
{
    (void)arg;
    pthread_barrier_wait(&meet); /* returns only once all BURST tasks run at once */
    atomic_fetch_add(&ran, 1);
}

static void *submit(void *arg)
{
    sdfd_workers *w = arg;
    for (int i = 0; i < 500; i++)
        CHECK(sdfd_workers_run(w, count, NULL) == 0, "concurrent run %d", i);
    return NULL;
}

static void slow(void *arg)
{
    usleep(200000);
    atomic_store((atomic_int *)arg, 1);
}

static void test_one_at_a_time(void)
{
    sdfd_workers *w;
    CHECK(sdfd_workers_create(SDFD_IDLE_WORKERS, &w) == 0, "create");
    size_t idle, started;
    one_at_a_time(w, 200);
    sdfd_workers_counts(w, &idle, &started);
    CHECK(started == 1 && idle == 1, "200 tasks in turn: %zu threads started, %zu idle",
          started, idle);
    sdfd_workers_destroy(w);
}

static void test_burst(void)
{
    sdfd_workers *w;
    CHECK(sdfd_workers_create(SDFD_IDLE_WORKERS, &w) == 0, "create");
    size_t idle = 0, started = 0;
    atomic_store(&ran, 0);
    pthread_barrier_init(&meet, NULL, BURST);
    for (int i = 0; i < BURST; i++)
        CHECK(sdfd_workers_run(w, wait_for_all, NULL) == 0, "burst %d", i);
    for (int t = 0; t < 10000 && atomic_load(&ran) < BURST; t++)
        usleep(1000);
    CHECK(atomic_load(&ran) == BURST, "%d of %d blocking tasks ended", atomic_load(&ran), BURST);
    for (int t = 0; t < 1000; t++) { /* the burst's threads settle: idle, or gone */
        sdfd_workers_counts(w, &idle, &started);
        if (idle == SDFD_IDLE_WORKERS)
            break;
        usleep(1000);
    }
    CHECK(idle == SDFD_IDLE_WORKERS, "after the burst %zu idle (keeps %d)", idle,
          SDFD_IDLE_WORKERS);
    CHECK(started == BURST, "%zu started for a burst of %d", started, BURST);
    sdfd_workers_destroy(w);
    pthread_barrier_destroy(&meet);
}

static void test_concurrent_submitters(void)
{
    sdfd_workers *w;
    CHECK(sdfd_workers_create(SDFD_IDLE_WORKERS, &w) == 0, "create");
    atomic_store(&ran, 0);
    pthread_t submitters[4];
    for (int i = 0; i < 4; i++)
        pthread_create(&submitters[i], NULL, submit, w);
    for (int i = 0; i < 4; i++)
        pthread_join(submitters[i], NULL);
    for (int t = 0; t < 10000 && atomic_load(&ran) < 2000; t++)
        usleep(1000);
    CHECK(atomic_load(&ran) == 2000, "%d of 2000 concurrent tasks ran", atomic_load(&ran));
    sdfd_workers_destroy(w);
}

static void test_destroy_waits(void)
{
    sdfd_workers *w;
    CHECK(sdfd_workers_create(SDFD_IDLE_WORKERS, &w) == 0, "create");
    atomic_int done = 0;
    CHECK(sdfd_workers_run(w, slow, &done) == 0, "slow task");
    sdfd_workers_destroy(w);
    CHECK(atomic_load(&done) == 1, "destroy returned before the running task ended");
}

static const check_case cases[] = {
    {"one_at_a_time", test_one_at_a_time},
    {"burst", test_burst},
    {"concurrent_submitters", test_concurrent_submitters},
    {"destroy_waits", test_destroy_waits},
};

int main(int argc, char **argv)
{
    return check_main("server_workers", cases, CHECK_COUNT_OF(cases), argc, argv);
}
