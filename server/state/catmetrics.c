/* catmetrics.c - the catalog's counters as Prometheus text (catmetrics.h). */
#include "state/catmetrics.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct text {
    char *s;
    size_t len, cap;
    int failed;
} text;

static void add(text *t, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void add(text *t, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = t->failed ? -1 : vsnprintf(t->s + t->len, t->cap - t->len, fmt, ap);
        va_end(ap);
        if (n < 0)
            return;
        if (t->len + (size_t)n < t->cap) {
            t->len += (size_t)n;
            return;
        }
        size_t cap = (t->cap + (size_t)n) * 2;
        char *s = realloc(t->s, cap);
        if (!s) {
            t->failed = 1;
            return;
        }
        t->s = s, t->cap = cap;
    }
}

static void counter(text *t, const char *name, const char *help, unsigned long long v)
{
    add(t, "# HELP %s %s\n# TYPE %s counter\n%s %llu\n", name, help, name, name, v);
}

static void round_trips(text *t, sdfd_catalog_metrics *m)
{
    static const double bounds[SDFD_CATALOG_RT_BUCKETS] = SDFD_CATALOG_RT_BOUNDS;
    const char *name = "sdfd_catalog_round_trip_seconds";
    add(t, "# HELP %s Statements sent to PostgreSQL and answered (or failed).\n"
           "# TYPE %s histogram\n", name, name);
    unsigned long long cumulative = 0;
    for (int i = 0; i <= SDFD_CATALOG_RT_BUCKETS; i++) {
        cumulative += atomic_load(&m->round_trip_le[i]);
        if (i < SDFD_CATALOG_RT_BUCKETS)
            add(t, "%s_bucket{le=\"%g\"} %llu\n", name, bounds[i], cumulative);
        else
            add(t, "%s_bucket{le=\"+Inf\"} %llu\n", name, cumulative);
    }
    add(t, "%s_sum %.9g\n%s_count %llu\n", name, atomic_load(&m->round_trip_ns) * 1e-9, name,
        atomic_load(&m->round_trips));
}

static void blob_cache(text *t, sdfd_catalog_metrics *m)
{
    counter(t, "sdfd_blob_cache_hits_total", "Items read from a local copy of their bytes.",
            atomic_load(&m->cache_hits));
    counter(t, "sdfd_blob_cache_misses_total",
            "Items read from PostgreSQL: no local copy of their bytes.",
            atomic_load(&m->cache_misses));
    counter(t, "sdfd_blob_cache_fills_total", "Local copies written.",
            atomic_load(&m->cache_fills));
    counter(t, "sdfd_blob_cache_evictions_total", "Local copies removed past --cache-bytes.",
            atomic_load(&m->cache_evictions));
    counter(t, "sdfd_blob_cache_damaged_total",
            "Local copies removed because their size or SHA-256 was wrong.",
            atomic_load(&m->cache_damaged));
    add(t, "# HELP sdfd_blob_cache_bytes Bytes of the local copies kept now.\n"
           "# TYPE sdfd_blob_cache_bytes gauge\nsdfd_blob_cache_bytes %llu\n",
        atomic_load(&m->cache_bytes));
}

char *sdfd_catalog_metrics_render(sdfd_catalog_metrics *m, const sdfd_catalog_job_counts *jobs,
                                  size_t *len)
{
    text t = {malloc(4096), 0, 4096, 0};
    t.failed = !t.s;
    round_trips(&t, m);
    add(&t, "# HELP sdfd_catalog_up 1 while the listener's LISTEN is in place (PostgreSQL "
            "reached).\n# TYPE sdfd_catalog_up gauge\nsdfd_catalog_up %d\n",
        atomic_load(&m->listening));
    counter(&t, "sdfd_catalog_notifications_total", "Changes heard of through LISTEN/NOTIFY.",
            atomic_load(&m->notifications));
    counter(&t, "sdfd_catalog_resyncs_total", "LISTEN put in place (each followed by a list).",
            atomic_load(&m->resyncs));
    counter(&t, "sdfd_catalog_connects_total", "Connections to PostgreSQL opened.",
            atomic_load(&m->connects));
    counter(&t, "sdfd_catalog_connect_failures_total", "Connections that failed to open.",
            atomic_load(&m->connect_failures));
    counter(&t, "sdfd_catalog_unavailable_total", "Calls refused: PostgreSQL unreachable.",
            atomic_load(&m->unavailable));
    if (m->cache_on)
        blob_cache(&t, m);
    if (jobs) {
        counter(&t, "sdfd_jobs_claimed_total", "Shared jobs this replica claimed.",
                jobs->claimed);
        counter(&t, "sdfd_jobs_requeued_total",
                "Shared jobs this replica queued again after their replica's lease ran out.",
                jobs->requeued);
        counter(&t, "sdfd_jobs_lost_total",
                "Shared jobs this replica failed after a second lost lease.", jobs->lost);
    }
    if (t.failed) {
        free(t.s);
        return NULL;
    }
    *len = t.len;
    return t.s;
}
