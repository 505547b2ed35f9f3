/* catlisten.h - hearing of the catalog's changes as they commit (PostgreSQL LISTEN/NOTIFY),
 * so a replica drops or reloads what another replica replaced without asking the database
 * on a query's path.
 *
 * A listener is one thread with a connection of its own: LISTEN on SDFD_CATALOG_CHANNEL,
 * then wait on the socket and pass each notification to `change`, in commit order. When the
 * connection is lost it reconnects with backoff (0.1 s doubling to 5 s), and each time its
 * LISTEN is in place, the first time included, it calls `resync`: notifications sent while
 * nobody listened are gone, so the owner compares every version (sdfd_catalog_versions)
 * against what it holds. Calling sdfd_catalog_versions from the first resync, rather than
 * before starting the listener, is what leaves no gap between the list and the stream. */
#ifndef SDFD_CATLISTEN_H
#define SDFD_CATLISTEN_H

#include <stddef.h>
#include <stdint.h>

#include "state/catalog.h"

typedef struct sdfd_catlisten sdfd_catlisten;

/* Called on the listener's thread, one at a time (either may be NULL); they may call the
 * catalog (its pool has other connections) but hold up every later notification while they
 * run. */
typedef struct sdfd_catlisten_callbacks {
    /* A committed put (deleted 0) or remove (deleted 1) of `name` at `version`. */
    void (*change)(void *arg, sdfd_item_kind kind, const char *name, uint64_t version,
                   int deleted);
    /* LISTEN is (again) in place: changes may have been missed before it. */
    void (*resync)(void *arg);
    void *arg;
} sdfd_catlisten_callbacks;

/* Start listening with conninfo (as for sdfd_catalog_open). Returns at once: connecting,
 * and reconnecting, happen on the thread, so an unreachable server is not an error here.
 * m (may be NULL) counts notifications, resyncs and connections and says whether LISTEN
 * is in place. 0 with *out set; SDF_EINVAL (bad string), SDF_ENOMEM; err says why. */
int sdfd_catlisten_start(const char *conninfo, const sdfd_catlisten_callbacks *cb,
                         sdfd_catalog_metrics *m, sdfd_catlisten **out, char *err, size_t cap);

/* End the thread promptly (it is woken from any wait, connecting included) and free the
 * listener; no callback runs once this returns. NULL is a no-op. */
void sdfd_catlisten_stop(sdfd_catlisten *l);

/* Parse a notification's payload ("KIND VERSION put|del NAME"): 0, or -1 when it is not
 * one of the catalog's. */
int sdfd_catlisten_parse(const char *payload, sdfd_item_kind *kind, char *name, size_t cap,
                         uint64_t *version, int *deleted);

#endif
