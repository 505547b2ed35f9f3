/* catmetrics.h - the counters the catalog (catalog.h) and its listener (catlisten.h) keep
 * about their talks with PostgreSQL, for /metrics.
 *
 * The caller owns the struct (zeroed: static, or calloc) and hands the same one to
 * sdfd_catalog_open and sdfd_catlisten_start; the modules only add to it, with atomics, from
 * any thread, so /metrics reads it whenever it likes without a lock (sdfd_catalog_metrics_render
 * writes it in Prometheus's text format). */
#ifndef SDFD_CATMETRICS_H
#define SDFD_CATMETRICS_H

#include <stdatomic.h>
#include <stddef.h>

/* Upper bounds, in seconds, of the round-trip histogram's buckets (+Inf implied), for
 * `static const double b[] = SDFD_CATALOG_RT_BOUNDS;`. */
#define SDFD_CATALOG_RT_BUCKETS 12
#define SDFD_CATALOG_RT_BOUNDS \
    {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.5, 2.5}

typedef struct sdfd_catalog_metrics {
    /* Round trips: every statement sent and answered (or failed), with its seconds. */
    atomic_ullong round_trips;
    atomic_ullong round_trip_ns;                         /* their sum */
    atomic_ullong round_trip_le[SDFD_CATALOG_RT_BUCKETS + 1]; /* per bucket, not cumulative */
    atomic_ullong unavailable;     /* calls answered SDFD_EUNAVAILABLE */
    atomic_ullong connects;        /* connections opened (pool and listener) */
    atomic_ullong connect_failures;
    atomic_ullong migrations;      /* schema steps this process applied */
    atomic_ullong notifications;   /* changes the listener passed on */
    atomic_ullong resyncs;         /* resync callbacks (each LISTEN put in place) */
    /* The local copies of blobs (--data-dir with --catalog, blobcache.h). */
    atomic_ullong cache_hits;      /* reads answered by a copy whose hash checked */
    atomic_ullong cache_misses;    /* reads that found no copy */
    atomic_ullong cache_fills;     /* copies written */
    atomic_ullong cache_evictions; /* copies removed past the size bound */
    atomic_ullong cache_damaged;   /* copies removed because their size or hash was wrong */
    atomic_ullong cache_bytes;     /* bytes of the copies kept now */
    int cache_on;                  /* set once at start: render the cache's lines */
    atomic_int up;                 /* 1: the last attempt to reach PostgreSQL worked */
    atomic_int listening;          /* 1: the listener's LISTEN is in place */
} sdfd_catalog_metrics;

static inline void sdfd_catalog_metrics_round_trip(sdfd_catalog_metrics *m, double seconds)
{
    static const double bounds[SDFD_CATALOG_RT_BUCKETS] = SDFD_CATALOG_RT_BOUNDS;
    int i = 0;
    while (i < SDFD_CATALOG_RT_BUCKETS && seconds > bounds[i])
        i++;
    atomic_fetch_add(&m->round_trip_le[i], 1);
    atomic_fetch_add(&m->round_trips, 1);
    atomic_fetch_add(&m->round_trip_ns, (unsigned long long)(seconds * 1e9));
}

/* The counters as Prometheus text (sdfd_catalog_*), with the shared jobs' counts (claimed,
 * re-queued, failed as lost; NULL: none): a malloc'd string, *len bytes, or NULL on out of
 * memory. */
typedef struct sdfd_catalog_job_counts {
    unsigned long long claimed, requeued, lost;
} sdfd_catalog_job_counts;
char *sdfd_catalog_metrics_render(sdfd_catalog_metrics *m, const sdfd_catalog_job_counts *jobs,
                                  size_t *len);

#endif
