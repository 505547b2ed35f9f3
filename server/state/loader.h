/* loader.h - lookups of the backing's items (backing.h: the file store or the catalog) that
 * never hold their caller for a load: the cache (cache.h) looks names up here when it has a
 * backing.
 *
 * A lookup answers at once from memory when it can: the item is pinned, resident and
 * compared with the backing less than SDFD_LOADER_RECHECK_SECONDS ago (and no change of it
 * heard of since), or resident while a new version of it loads (the old one is served until
 * the new one is ready). Otherwise it compares with the backing there and then (its stat, and
 * a read of the item's description when the version changed), and when the item has to be
 * read and parsed (not in memory, or replaced by a different content) hands that to a pool
 * of SDFD_LOADER_THREADS threads: one load per name, its lookups queued on the name and
 * answered through their `done` when it ends. So the thread that looked up never waits for a
 * parse or a BVH build, and lookups of other names go on meanwhile. Thread-safe. */
#ifndef SDFD_LOADER_H
#define SDFD_LOADER_H

#include "core/metrics.h"
#include "state/backing.h"
#include "state/resident.h"

#define SDFD_LOADER_RECHECK_SECONDS 1.0
#define SDFD_LOADER_THREADS 2
/* What a lookup returns when it waits for a load: its `done` will be called. Not an error
 * code (those are negative). */
#define SDFD_LOOKUP_PENDING 1

typedef struct sdfd_loader sdfd_loader;

/* The loader of backing `b` for the table `r` (both stay the caller's). max_triangles: the
 * limit for one mesh. NULL if its threads cannot start. */
sdfd_loader *sdfd_loader_create(const sdfd_backing *b, sdfd_resident *r, sdfd_metrics *metrics,
                                size_t max_triangles);
/* Finish the loads queued and stop the threads; lookups that would load answer
 * SDFD_EUNAVAILABLE from then on. */
void sdfd_loader_stop(sdfd_loader *ld);
void sdfd_loader_destroy(sdfd_loader *ld); /* stops first; NULL is a no-op */

/* Look up l->kind, l->name: 0 (l->item set), an error (SDF_ENOTFOUND, SDFD_EUNAVAILABLE,
 * SDF_ELIMIT, SDF_ENOMEM; l->message says why), or SDFD_LOOKUP_PENDING: the answer will be
 * in l->status, l->item and l->message when l->done runs, on a loader thread or on the
 * thread that releases the name, never inside this call. The caller must not touch l after
 * SDFD_LOOKUP_PENDING until done. */
int sdfd_loader_lookup(sdfd_loader *ld, sdfd_lookup *l);
/* The same, waiting for a load on the calling thread (l->done and l->user are set here);
 * never SDFD_LOOKUP_PENDING. */
int sdfd_loader_lookup_wait(sdfd_loader *ld, sdfd_lookup *l);
/* Look up again the lookups that waited on a name its writer has released
 * (sdfd_resident_unclaim's list), answering those that no longer wait. The lock not held. */
void sdfd_loader_retry(sdfd_loader *ld, sdfd_lookup *waiting);

#endif
