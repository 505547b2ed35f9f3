/* backcat.h - the PostgreSQL catalog (catalog.h) as the cache's backing (backing.h): what
 * --catalog gives, for replicas that share no filesystem.
 *
 * Queries never wait for the database: the backing keeps, in memory, the version of every
 * name the catalog holds (tombstones included), learnt from a full list at start and kept
 * current by the listener's notifications (catlisten.h), and its stat answers from that
 * table. A write or read that returns a version also raises the table's (versions only
 * grow: the table keeps the largest it has seen of each name). The table is trusted only
 * while the listener's LISTEN is in place and the list taken since its (re)connection has
 * been read; otherwise stat answers SDFD_EUNAVAILABLE, so items in memory are still served
 * and nothing else is, and the probe (/readyz) fails. A list is taken again after each
 * reconnection, and every SDFD_BACKCAT_RESYNC_SECONDS as a backstop.
 *
 * Start (ops->start): connect and migrate the schema, retrying with backoff (0.1 s doubling
 * to 5 s, logged) while PostgreSQL cannot be reached; then the listener, and the first list. */
#ifndef SDFD_BACKCAT_H
#define SDFD_BACKCAT_H

#include <stdint.h>

#include "state/backing.h"
#include "state/catalog.h"
#include "state/catmetrics.h"

#define SDFD_BACKCAT_RESYNC_SECONDS 30.0

/* A backing for conninfo (checked here: SDF_EINVAL with err for a bad string; nothing
 * connects before ops->start). cache_dir: NULL, or a directory whose blobs/ keeps local
 * copies of the blobs read (blobcache.h), at most cache_bytes of them (0: no bound). m: the
 * caller's counters (zeroed, kept while the backing lives). 0 or SDF_EINVAL, SDF_ENOMEM,
 * SDF_EIO (the cache directory cannot be made or read). */
int sdfd_backcat_create(const char *conninfo, const char *cache_dir, uint64_t cache_bytes,
                        sdfd_catalog_metrics *m, sdfd_backing *out, char *err, size_t cap);

/* The catalog of a started backing made by sdfd_backcat_create (for its other tables:
 * jobs); NULL before ops->start returned 0. */
sdfd_catalog *sdfd_backcat_catalog(const sdfd_backing *b);

#endif
