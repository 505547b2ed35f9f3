/* cache.h - the meshes and volumes in memory as a cache of the backing (backing.h: the file
 * store of --data-dir, or the catalog of --catalog), and the one place that reads, writes and
 * checks the backing for them.
 *
 * Without a backing it passes every call straight to the registry and the volumes: memory
 * only, as if it were not there. With one:
 * - a lookup of a name not in memory loads it from the backing on a loader thread (loader.h:
 *   one load at a time per name; the lookups of that name wait for it), so an item another
 *   replica wrote is found;
 * - a lookup of a name in memory compares its version with the backing's at most once a
 *   second (SDFD_LOADER_RECHECK_SECONDS), and at once after the backing told of a change (the
 *   catalog's notifications), and drops the item another replica deleted, or reloads the one
 *   it replaced (serving the old version until the new one is in);
 * - with a byte budget, the items used least recently are dropped from memory once the
 *   resident bytes pass it (and reloaded on their next use);
 * - an item that fails its checks is logged and set aside, never served;
 * - uploads and deletes go to the backing first, and are answered once it has them.
 * Meshes named by --mesh/--mesh-dir are pinned: in memory only, never checked or dropped.
 * Thread-safe. sdfd_cache_lookup never waits for a load (the query handlers use it, on the
 * front ends' threads); sdfd_cache_get waits on its caller's. */
#ifndef SDFD_CACHE_H
#define SDFD_CACHE_H

#include <cjson/cJSON.h>
#include <stddef.h>

#include "core/metrics.h"
#include "state/backing.h"
#include "state/loader.h"
#include "state/registry.h"
#include "state/store.h"
#include "state/volumes.h"

typedef struct sdfd_cache sdfd_cache;

/* `backing` may be NULL (memory only); the cache owns what it holds from now on (and closes it
 * if creation fails). max_resident_bytes 0: no budget. max_triangles: the loader's limit for
 * one mesh. */
sdfd_cache *sdfd_cache_create(const sdfd_backing *backing, sdfd_registry *registry,
                              sdfd_volumes *volumes, sdfd_metrics *metrics,
                              size_t max_resident_bytes, size_t max_triangles);
void sdfd_cache_destroy(sdfd_cache *c); /* NULL is a no-op */
/* Shutdown: finish the loads under way and answer their lookups (before the batcher they
 * submit to stops); lookups that would load answer SDFD_EUNAVAILABLE from then on. */
void sdfd_cache_stop_loads(sdfd_cache *c);

/* A mesh put in the registry at start from the flags: kept in memory, never from the store. */
void sdfd_cache_pin(sdfd_cache *c, const char *name);
/* With a backing: make it ready (the catalog: connect, retrying while PostgreSQL cannot be
 * reached); with the file store, restore the jobs a restart interrupted (as failed) and
 * install the volumes' hooks (the catalog's are the job runner's); then load what the
 * backing holds (while under the budget; the rest when first used). 0, or an error the
 * backing cannot recover from (err says why). */
int sdfd_cache_start(sdfd_cache *c, char *err, size_t cap);

/* Lookups of a `kind` (SDFD_ITEM_MESH: an sdf_mesh *, SDFD_ITEM_VOLUME: an
 * sdfd_stored_volume *): a retained reference in *out and 0; SDF_ENOTFOUND;
 * SDFD_EUNAVAILABLE (the store is unreadable, and the item not in memory); SDF_ELIMIT (it
 * does not fit --max-meshes / --max-triangles / --max-volumes / --max-volume-bytes). msg
 * says why. A load of the item runs on a loader thread while the caller waits. */
int sdfd_cache_get(sdfd_cache *c, sdfd_item_kind kind, const char *name, size_t n, void **out,
                   char *msg, size_t cap);

/* The same lookup without waiting: l->kind and l->name set, 0 (l->item), an error
 * (l->message), or SDFD_LOOKUP_PENDING and l->done will be called with the answer
 * (sdfd_loader_lookup). */
int sdfd_cache_lookup(sdfd_cache *c, sdfd_lookup *l);

/* Uploads: `item` (an sdf_mesh *, or an sdf_volume * for SDFD_ITEM_VOLUME) taken over;
 * `file` is the bytes as uploaded (a volume: its EXR). 0 (*replaced set) or an error with
 * msg. */
int sdfd_cache_put(sdfd_cache *c, sdfd_item_kind kind, const char *name, void *item,
                   const void *file, size_t n, int *replaced, char *msg, size_t cap);
/* A volume's surface (sdf_volume_extract by opts) stored as the mesh `name`, as an upload of
 * its binary PLY would be (surface.h), refused past the triangle bound the cache was made
 * with (SDF_ELIMIT). 0 (*replaced set; *mesh, unless mesh is NULL, a reference to the mesh
 * stored) or an error with msg. The POST of a volume's mesh and a bake's "mesh" both. */
int sdfd_cache_put_surface(sdfd_cache *c, const char *name, const sdf_volume *v,
                           const sdf_extract_options *opts, int *replaced, sdf_mesh **mesh,
                           char *msg, size_t cap);
/* Deletes: 0, SDF_ENOTFOUND, or SDFD_EUNAVAILABLE. */
int sdfd_cache_remove(sdfd_cache *c, sdfd_item_kind kind, const char *name, char *msg,
                      size_t cap);

/* Listings of everything served (with a store: its sidecars, and the pinned meshes). */
typedef struct sdfd_mesh_summary {
    char name[SDFD_MAX_NAME + 1];
    size_t triangles;
    int closed;
    sdf_sign_method sign;
} sdfd_mesh_summary;
size_t sdfd_cache_list_meshes(sdfd_cache *c, sdfd_mesh_summary **out); /* free *out */
/* With a store, the volumes' descriptions (an array to delete); without, NULL. */
cJSON *sdfd_cache_list_volumes(sdfd_cache *c);
/* Describe a stored volume as GET /v1/volumes/{name} does (a new object). */
cJSON *sdfd_cache_volume_json(const sdfd_stored_volume *s);

/* A finished job's volume `s`, into the backing (and memory) before its job says done: 0 or
 * an error with err (the job fails with it). The volumes' `keep` hook. */
int sdfd_cache_keep_baked(sdfd_cache *c, const sdfd_stored_volume *s, char *err, size_t cap);
/* After a keep that returned 0: the job listed the volume named `name` in memory (rc 0) or
 * could not (rc); the name's lookups, held until now, go on. The volumes' `listed` hook. */
void sdfd_cache_baked_listed(sdfd_cache *c, const char *name, int rc);

/* A job no longer (or never) in this process's memory, from its record in the store:
 * 0 or SDF_ENOTFOUND. */
int sdfd_cache_job(sdfd_cache *c, const char *id, sdfd_job_status *out);

/* 0 when the backing (if any) can be used now; else non-zero and why in msg. */
int sdfd_cache_probe(sdfd_cache *c, char *msg, size_t cap);

typedef struct sdfd_cache_stats {
    size_t resident_bytes, budget;
    unsigned long long loads, evictions, quarantined, hits;
} sdfd_cache_stats;
void sdfd_cache_stats_get(sdfd_cache *c, sdfd_cache_stats *out);

#endif
