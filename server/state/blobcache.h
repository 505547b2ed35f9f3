/* blobcache.h - a replica's local copies of the catalog's blobs (--data-dir with --catalog):
 * files named by their SHA-256 in DIR/blobs/, so that an item loaded again after it left
 * memory, or after a restart that kept the directory (a Kubernetes emptyDir survives a
 * container's restart), comes from the local disk instead of PostgreSQL.
 *
 * A file's name is its content's hash and never changes meaning, so a copy is never stale and
 * replicas need not agree on anything about it. Nothing here is trusted: a read checks the
 * size and the SHA-256 and removes a file that fails (counted as damaged; the caller fetches
 * the blob from the catalog again). Files are written whole (a temporary renamed into place)
 * and the least recently used go once the copies pass max_bytes. The cache only ever saves a
 * round trip: any of its calls may fail and the caller goes on with the catalog.
 *
 * Thread-safe: any thread may call get and put at once (a mutex guards the index; file work
 * happens outside it). Counters go to the catalog's metrics (catmetrics.h). */
#ifndef SDFD_BLOBCACHE_H
#define SDFD_BLOBCACHE_H

#include <stddef.h>
#include <stdint.h>

#include "state/catmetrics.h"

#define SDFD_BLOBCACHE_HASH_BYTES 32
#define SDFD_BLOBCACHE_DIR "blobs"

typedef struct sdfd_blobcache sdfd_blobcache;

/* Open (creating DIR/blobs) and index what a previous run left there, oldest use first by
 * modification time; temporaries a crash left are removed, and names that are no hash are
 * left alone. Copies past max_bytes (> 0) go at once. m: counters (kept while the cache lives).
 * 0, or -1 with err set (DIR cannot be made or read). */
int sdfd_blobcache_open(const char *dir, uint64_t max_bytes, sdfd_catalog_metrics *m,
                        sdfd_blobcache **out, char *err, size_t cap);

/* The copy of the blob `hash` of `bytes` bytes into *data (malloc'd, free it): 0 on a hit
 * whose size and hash check; -1 otherwise (*data NULL): no copy, a damaged one (removed), or
 * a read error. */
int sdfd_blobcache_get(sdfd_blobcache *c, const unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES],
                       size_t bytes, void **data);

/* Keep a copy of data (n bytes, whose SHA-256 the caller checked is `hash`), then drop the
 * least recently used copies past max_bytes. A blob larger than max_bytes is not kept. 0, or
 * -1 with err set (nothing kept; the cache is as before). */
int sdfd_blobcache_put(sdfd_blobcache *c, const unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES],
                       const void *data, size_t n, char *err, size_t cap);

/* Bytes of the copies indexed now. */
uint64_t sdfd_blobcache_bytes(sdfd_blobcache *c);

void sdfd_blobcache_close(sdfd_blobcache *c);

#endif
