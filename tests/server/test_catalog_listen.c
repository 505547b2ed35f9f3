/* test_catalog_listen.c - the listener and PostgreSQL going away (part of test_catalog):
 *  - every put and remove made through the catalog's pool reaches a listener on its own
 *    connection, once, in commit order, with its kind, name, version and kind of change;
 *    the delay from the call's return to the callback is printed (p50, p99, max): its p50
 *    must be under 10 ms and its p99 under 100 ms (in one of up to three runs);
 *  - PostgreSQL stopped (fast shutdown), then killed (SIGKILL) under a writer: every call
 *    answers SDFD_EUNAVAILABLE with a message, opening too; once it is back the same catalog
 *    works without reopening, every acknowledged write is there, and the listener has
 *    reconnected, called resync again and hears new changes;
 *  - stopping the listener while it waits to reconnect returns at once. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/check.h"
#include "catfixture.h"
#include "core/errors.h"
#include "state/catlisten.h"

enum { CHANGES = 300, MAX_EVENTS = 4096 };

typedef struct event {
    sdfd_item_kind kind;
    char name[32];
    uint64_t version;
    int deleted;
    double t;
} event;

static struct {
    pthread_mutex_t lock;
    event ev[MAX_EVENTS];
    size_t n;
    atomic_int resyncs;
} rec = {.lock = PTHREAD_MUTEX_INITIALIZER};

static sdfd_catlisten *listener;
static sdfd_catalog_metrics lm; /* the listener's */

static void on_change(void *arg, sdfd_item_kind kind, const char *name, uint64_t version,
                      int deleted)
{
    (void)arg;
    double t = now_seconds();
    pthread_mutex_lock(&rec.lock);
    if (rec.n < MAX_EVENTS) {
        event *e = &rec.ev[rec.n++];
        e->kind = kind, e->version = version, e->deleted = deleted, e->t = t;
        snprintf(e->name, sizeof e->name, "%s", name);
    }
    pthread_mutex_unlock(&rec.lock);
}

static void on_resync(void *arg)
{
    (void)arg;
    atomic_fetch_add(&rec.resyncs, 1);
}

static size_t events(void)
{
    pthread_mutex_lock(&rec.lock);
    size_t n = rec.n;
    pthread_mutex_unlock(&rec.lock);
    return n;
}

/* Poll cond(arg) every 5 ms for up to `seconds`: 1 when it held. */
static int wait_for(int (*cond)(long), long arg, double seconds)
{
    double end = now_seconds() + seconds;
    while (!cond(arg)) {
        if (now_seconds() > end)
            return 0;
        usleep(5000);
    }
    return 1;
}

static int resyncs_reach(long n) { return atomic_load(&rec.resyncs) >= n; }
static int events_reach(long n) { return (long)events() >= n; }
static int listening_is(long v) { return atomic_load(&lm.listening) == v; }

typedef struct expected {
    sdfd_item_kind kind;
    char name[32];
    uint64_t version;
    int deleted;
    double acked;
} expected;

/* The i-th change: puts and removes over 10 names of both kinds. */
static int make_change(sdfd_catalog *c, int i, int live[2][10], expected *e)
{
    char err[512] = "";
    int k = i % 2, j = (i / 2) % 10;
    e->kind = k ? SDFD_ITEM_VOLUME : SDFD_ITEM_MESH;
    snprintf(e->name, sizeof e->name, "ln%d", j);
    e->deleted = live[k][j] && i % 3 == 0;
    int rc = e->deleted ? sdfd_catalog_remove(c, e->kind, e->name, &e->version, err, sizeof err)
                        : sdfd_catalog_put(c, e->kind, e->name, e->name, 3, "obj", NULL,
                                           &e->version, NULL, err, sizeof err);
    e->acked = now_seconds();
    live[k][j] = !e->deleted;
    CHECK(rc == 0, "change %d: %s", i, err);
    return rc;
}

/* Each expected change arrived once, as made, in order; latencies[i] from its return. */
static void match(const expected *exp, size_t base, double *latencies)
{
    pthread_mutex_lock(&rec.lock);
    size_t got = rec.n - base;
    CHECK(got == CHANGES, "%zu notifications for %d changes", got, CHANGES);
    for (size_t i = 0; i < CHANGES && i < got; i++) {
        const event *e = &rec.ev[base + i];
        const expected *x = &exp[i];
        CHECK(e->version == x->version && e->kind == x->kind && e->deleted == x->deleted &&
              !strcmp(e->name, x->name), "notification %zu: %s %llu %d, made %s %llu %d", i,
              e->name, (unsigned long long)e->version, e->deleted, x->name,
              (unsigned long long)x->version, x->deleted);
        latencies[i] = e->t > x->acked ? e->t - x->acked : 0;
    }
    pthread_mutex_unlock(&rec.lock);
}

/* One run of CHANGES changes: all heard as made; returns the p99 delay in seconds. */
static double measure_run(sdfd_catalog *c, int run)
{
    expected *exp = calloc(CHANGES, sizeof *exp);
    double *lat = calloc(CHANGES, sizeof *lat);
    int live[2][10] = {{0}};
    unsigned long long before = atomic_load(&lm.notifications);
    size_t base = events();
    for (int i = 0; i < CHANGES; i++)
        make_change(c, i, live, &exp[i]);
    CHECK(wait_for(events_reach, (long)(base + CHANGES), 10), "all notifications within 10 s");
    usleep(100000); /* and no more than those */
    match(exp, base, lat);
    CHECK(atomic_load(&lm.notifications) - before == CHANGES, "metrics: %llu notifications",
          atomic_load(&lm.notifications) - before);
    double p50 = percentile(lat, CHANGES, 50), p99 = percentile(lat, CHANGES, 99);
    double max = percentile(lat, CHANGES, 100);
    printf("notification latency after the call returned, run %d, %d changes: p50 %.3f ms,"
           " p99 %.3f ms, max %.3f ms\n", run, CHANGES, p50 * 1e3, p99 * 1e3, max * 1e3);
    CHECK(p50 < 0.010, "p50 %.1f ms", p50 * 1e3);
    free(exp);
    free(lat);
    return p99;
}

/* The p99 bound is 100 ms. The machine is shared, and a run that met another process's
 * burst is run again (up to three runs, every one printed and checked but for that bound). */
void test_listener(sdfd_catalog *c)
{
    char err[512] = "";
    sdfd_catlisten_callbacks cb = {on_change, on_resync, NULL};
    CHECK(sdfd_catlisten_start(pg_uri("items"), &cb, &lm, &listener, err, sizeof err) == 0,
          "start: %s", err);
    CHECK(wait_for(resyncs_reach, 1, 10), "the first resync, once LISTEN is in place");
    double best = 1e9;
    for (int run = 1; run <= 3 && best >= 0.100; run++) {
        double p99 = measure_run(c, run);
        best = p99 < best ? p99 : best;
    }
    CHECK(best < 0.100, "p99 %.1f ms in the best of three runs", best * 1e3);
    sdfd_item_kind kind;
    char name[64];
    uint64_t v;
    int del;
    CHECK(sdfd_catlisten_parse("volume 12 del a.b-c_d", &kind, name, sizeof name, &v, &del) ==
          0 && kind == SDFD_ITEM_VOLUME && v == 12 && del && !strcmp(name, "a.b-c_d"), "parse");
    static const char *const bad[] = {"mesh 0 put a", "mesh 1 get a", "mesh -1 put a",
                                      "cube 1 put a", "mesh 1 put ../a", "mesh 1 put ",
                                      "mesh 99999999999999999999 put a"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        CHECK(sdfd_catlisten_parse(bad[i], &kind, name, sizeof name, &v, &del) == -1,
              "'%s' parsed", bad[i]);
}

/* ---- outages ---------------------------------------------------------------------------- */

/* Every kind of call answers SDFD_EUNAVAILABLE with a message while the server is down. */
static void check_unavailable(sdfd_catalog *c, const char *how)
{
    char err[512] = "";
    uint64_t v;
    sdfd_catalog_item item;
    sdfd_catalog_version *list = NULL;
    size_t n;
    int rc = sdfd_catalog_put(c, SDFD_ITEM_MESH, "down", "x", 1, "obj", NULL, &v, NULL, err,
                              sizeof err);
    CHECK(rc == SDFD_EUNAVAILABLE && strstr(err, "catalog unavailable"), "%s: put %d %s", how,
          rc, err);
    printf("%s: put says: %s\n", how, err);
    err[0] = '\0';
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "rt", &item, NULL, err, sizeof err) ==
          SDFD_EUNAVAILABLE && *err, "%s: read", how);
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_MESH, "rt", &v, err, sizeof err) ==
          SDFD_EUNAVAILABLE, "%s: remove", how);
    CHECK(sdfd_catalog_versions(c, SDFD_ITEM_MESH, &list, &n, err, sizeof err) ==
          SDFD_EUNAVAILABLE && !list, "%s: versions", how);
    CHECK(sdfd_catalog_sweep(c, 0, NULL, err, sizeof err) == SDFD_EUNAVAILABLE, "%s: sweep", how);
    sdfd_catalog *other = NULL;
    CHECK(sdfd_catalog_open(pg_uri("items"), NULL, &other, err, sizeof err) ==
          SDFD_EUNAVAILABLE && !other && strstr(err, "catalog unavailable"), "%s: open: %s",
          how, err);
    CHECK(wait_for(listening_is, 0, 10), "%s: the listener saw its connection go", how);
}

/* Back: the first call works, and the listener resyncs and hears a new change. */
static void check_recovered(sdfd_catalog *c, const char *how, int resyncs_before)
{
    char err[512] = "";
    uint64_t v;
    sdfd_catalog_item item;
    size_t base = events();
    int rc = sdfd_catalog_put(c, SDFD_ITEM_MESH, "back", how, strlen(how), "obj", NULL, &v, NULL,
                              err, sizeof err);
    CHECK(rc == 0, "%s: the first put after the restart: %d %s", how, rc, err);
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "back", &item, NULL, err, sizeof err) == 0 &&
          item.version == v, "%s: read: %s", how, err);
    free(item.info);
    CHECK(wait_for(resyncs_reach, resyncs_before + 1, 15), "%s: the listener resynced", how);
    CHECK(wait_for(listening_is, 1, 5), "%s: listening", how);
    if (rc == 0 && !events_reach((long)base + 1)) { /* sent before LISTEN was back: resync's */
        rc = sdfd_catalog_put(c, SDFD_ITEM_MESH, "back", "2", 1, "obj", NULL, &v, NULL, err,
                              sizeof err);
        CHECK(rc == 0, "%s: put: %s", how, err);
    }
    CHECK(wait_for(events_reach, (long)base + 1, 5), "%s: a change heard after the resync",
          how);
}

/* Puts of distinct names, acknowledged or not, until told to stop. */
typedef struct writer {
    sdfd_catalog *c;
    atomic_int stop;
    int made, acked[2000];
} writer;

static void *write_until_stopped(void *arg)
{
    writer *w = arg;
    for (w->made = 0; !atomic_load(&w->stop) && w->made < 2000; w->made++) {
        char name[32], err[512];
        uint64_t v;
        snprintf(name, sizeof name, "kill%d", w->made);
        w->acked[w->made] = sdfd_catalog_put(w->c, SDFD_ITEM_MESH, name, name, strlen(name),
                                             "obj", NULL, &v, NULL, err, sizeof err) == 0;
        if (!w->acked[w->made])
            usleep(2000);
    }
    return NULL;
}

static void kill_under_writer(sdfd_catalog *c)
{
    writer w = {.c = c};
    pthread_t t;
    pthread_create(&t, NULL, write_until_stopped, &w);
    usleep(300000);
    CHECK(pg_control("kill") == 0, "kill PostgreSQL");
    usleep(300000);
    atomic_store(&w.stop, 1);
    pthread_join(t, NULL);
    check_unavailable(c, "killed");
    int resyncs = atomic_load(&rec.resyncs);
    CHECK(pg_control("start") == 0, "start PostgreSQL");
    check_recovered(c, "killed", resyncs);
    int acked = 0, missing = 0;
    for (int i = 0; i < w.made; i++) {
        if (!w.acked[i])
            continue;
        char name[32], err[512];
        snprintf(name, sizeof name, "kill%d", i);
        sdfd_catalog_item item;
        void *data = NULL;
        acked++;
        int ok = sdfd_catalog_read(c, SDFD_ITEM_MESH, name, &item, &data, err, sizeof err) == 0 &&
                 item.bytes == strlen(name) && !memcmp(data, name, item.bytes);
        missing += !ok;
        free(data);
        if (!ok)
            continue;
        free(item.info);
    }
    printf("SIGKILL under a writer: %d puts, %d acknowledged, %d of those missing\n", w.made,
           acked, missing);
    CHECK(acked > 0 && missing == 0, "%d acknowledged puts missing after the kill", missing);
}

void test_outage(sdfd_catalog *c, const char *db)
{
    (void)db;
    CHECK(pg_control("stop") == 0, "stop PostgreSQL");
    check_unavailable(c, "stopped");
    int resyncs = atomic_load(&rec.resyncs);
    CHECK(pg_control("start") == 0, "start PostgreSQL");
    check_recovered(c, "stopped", resyncs);
    kill_under_writer(c);
    /* The listener, stopped while it waits to reconnect, ends at once. */
    CHECK(pg_control("stop") == 0, "stop PostgreSQL");
    CHECK(wait_for(listening_is, 0, 10), "not listening");
    usleep(300000);
    double t0 = now_seconds();
    sdfd_catlisten_stop(listener);
    double took = now_seconds() - t0;
    printf("listener stopped in %.3f ms while PostgreSQL was down\n", took * 1e3);
    CHECK(took < 0.5, "stopping took %.3f s", took);
    CHECK(pg_control("start") == 0, "start PostgreSQL");
}
