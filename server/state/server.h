/* server.h - the state every part of sdfd shares: settings, the mesh registry, the volumes,
 * the cache (the store behind both), metrics, the batcher, the worker threads, and the
 * lifecycle flags that drive /readyz and graceful shutdown. */
#ifndef SDFD_SERVER_H
#define SDFD_SERVER_H

#include <stdatomic.h>

#include "core/config.h"
#include "core/metrics.h"
#include "state/batcher.h"
#include "state/cache.h"
#include "state/catmetrics.h"
#include "state/jobrunner.h"
#include "state/registry.h"
#include "state/volumes.h"
#include "state/workers.h"

typedef struct sdfd_server {
    sdfd_config cfg;
    sdfd_registry *registry;
    sdfd_metrics *metrics;
    sdfd_batcher *batcher;
    sdfd_volumes *volumes;   /* baked volumes and bake jobs */
    sdfd_cache *cache;       /* lookups, uploads and deletes of both, through the store if any */
    sdfd_catalog_metrics catalog_metrics; /* with --catalog: its talks with PostgreSQL */
    sdfd_jobrunner *jobs;    /* with --catalog: the shared jobs (jobrunner.h); else NULL;
                              * set before `ready`, so read it only once ready */
    struct sdfd_tls *tls;    /* --tls-cert and --tls-key, or NULL: no TLS (transport/tls.h) */
    sdfd_workers *workers;   /* threads for uploads, slices and volume queries */
    atomic_int ready;        /* meshes loaded: /readyz 200 */
    atomic_int draining;     /* SIGTERM seen: /readyz 503, new work refused */
    atomic_long in_flight;   /* requests received and not yet answered (both protocols) */
    atomic_size_t buffered;  /* bytes of request bodies and binary input held (both) */
} sdfd_server;

/* Why the server takes no new work now, or NULL: a request other than a health check, the
 * metrics or the readiness probe is refused 503 EUNAVAILABLE with this reason while sdfd loads
 * its meshes (a restarted replica listens before it has them: a 404 then would be wrong) and
 * once it drains. */
static inline const char *sdfd_unavailable(sdfd_server *srv)
{
    if (atomic_load(&srv->draining))
        return "the server is shutting down";
    if (!atomic_load(&srv->ready))
        return "the server is still loading its meshes; retry when /readyz answers 200";
    return NULL;
}

/* Reserve n bytes of the --max-buffered-bytes budget for a body or frame about to be
 * received; 0, or -1 (nothing reserved) when it would pass the budget. Every connection's
 * own limit (--max-body-bytes, the protocol's max_payload) still applies: this one keeps
 * many connections together from holding more memory than the machine has. */
static inline int sdfd_buffer_reserve(sdfd_server *srv, size_t n)
{
    size_t before = atomic_fetch_add(&srv->buffered, n);
    if (before + n > srv->cfg.max_buffered_bytes || before + n < before) {
        atomic_fetch_sub(&srv->buffered, n);
        return -1;
    }
    return 0;
}

/* What both front ends answer (429 EBUSY) when sdfd_buffer_reserve says no; takes the
 * budget (%zu). */
#define SDFD_BUFFER_BUSY_FMT \
    "the server holds too many request bytes at once (--max-buffered-bytes %zu); retry later"

static inline void sdfd_buffer_release(sdfd_server *srv, size_t n)
{
    atomic_fetch_sub(&srv->buffered, n);
}

#endif
