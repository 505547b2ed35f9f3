/* resident.h - which of the store's items are in memory, for the cache (cache.h) and its
 * loader (loader.h): the table of the names this process has looked up, under one mutex,
 * the claim a load or a write holds on a name, and residency within the byte budget (the
 * least recently used items leave memory first).
 *
 * The table is the cache's private state, shared by cache.c and loader.c: its fields are
 * read and written under `lock`, and the functions below marked "under the lock" expect the
 * caller to hold it. Nothing here reads or writes the store. */
#ifndef SDFD_RESIDENT_H
#define SDFD_RESIDENT_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include "state/backing.h"
#include "state/registry.h"
#include "state/store.h"
#include "state/volumes.h"

/* One lookup of a name that may have to wait for a load: the caller's memory, untouched by
 * the cache once `done` has been called. */
typedef struct sdfd_lookup sdfd_lookup;
struct sdfd_lookup {
    /* in */
    sdfd_item_kind kind;
    char name[SDFD_MAX_NAME + 1];
    void (*done)(sdfd_lookup *l); /* when the lookup had to wait: once, on another thread */
    void *user;
    /* out: 0 and `item` (a retained sdf_mesh or sdfd_stored_volume), or an error and why */
    int status;
    void *item;
    char message[768];
    /* private: the queue of lookups waiting on a name */
    sdfd_lookup *next;
};

/* A name this process has looked up, written or pinned. */
typedef struct sdfd_cached {
    sdfd_item_kind kind;
    char name[SDFD_MAX_NAME + 1];
    int busy;           /* claimed: a load or write of this name is under way */
    int reloading;      /* busy with a load of a new version while the old one is resident */
    int resident;       /* in the registry / the volumes, as the store's version `hash` */
    int pinned;         /* from the flags: memory only */
    uint64_t hash;
    sdfd_seen seen;     /* the backing's version, when last read */
    double checked;     /* when it was last compared with the backing's */
    unsigned changes;   /* the backing's change notices so far (a load or write that saw
                         * this count change while it ran must not trust what it read) */
    unsigned long long used;
    sdfd_lookup *waiting;      /* lookups to answer or retry once it is no longer busy */
    struct sdfd_cached *queued; /* the loader's queue */
} sdfd_cached;

typedef struct sdfd_resident {
    pthread_mutex_t lock;
    pthread_cond_t idle; /* an entry stopped being busy */
    sdfd_registry *registry;
    sdfd_volumes *volumes;
    size_t budget;
    sdfd_cached **entries;
    size_t count, cap;
    unsigned long long tick, loads, evictions, quarantined, hits;
} sdfd_resident;

void sdfd_resident_init(sdfd_resident *r, sdfd_registry *registry, sdfd_volumes *volumes,
                        size_t budget);
void sdfd_resident_free(sdfd_resident *r);

/* "mesh" or "volume", as messages name a kind. */
const char *sdfd_kind_name(sdfd_item_kind kind);

/* Under the lock: the entry of (kind, name), created if `create`; NULL if absent or out of
 * memory. */
sdfd_cached *sdfd_resident_find(sdfd_resident *r, sdfd_item_kind kind, const char *name,
                                int create);
/* Under the lock: wait until (kind, name) is not busy, then mark it busy; NULL: no memory. */
sdfd_cached *sdfd_resident_claim(sdfd_resident *r, sdfd_item_kind kind, const char *name);
/* Under the lock: e is no longer busy. Returns the lookups that waited on it (answer or
 * retry them once the lock is released); an entry of nothing in memory is forgotten (so
 * lookups of names that do not exist cannot grow the table). */
sdfd_lookup *sdfd_resident_unclaim(sdfd_resident *r, sdfd_cached *e);

/* Under the lock: e's item, retained, or NULL. */
void *sdfd_resident_get(sdfd_resident *r, const sdfd_cached *e);
/* Under the lock: e leaves memory. */
void sdfd_resident_drop(sdfd_resident *r, sdfd_cached *e);
/* Under the lock: make `item` (a mesh or a stored volume; the caller's reference stays its
 * own) resident as e, evicting others of its kind while the registry's or the volumes' own
 * limits refuse it. 0 or SDF_ELIMIT. */
int sdfd_resident_put(sdfd_resident *r, sdfd_cached *e, void *item);
/* Under the lock: keep the resident bytes within the budget, `keep` aside. */
void sdfd_resident_enforce_budget(sdfd_resident *r, const sdfd_cached *keep);
/* What the registry and the volumes hold now (pinned meshes too). */
size_t sdfd_resident_bytes(sdfd_resident *r);

/* Take or release a reference to an item of `kind` (NULL is a no-op). */
void *sdfd_item_retain(sdfd_item_kind kind, void *item);
void sdfd_item_release(sdfd_item_kind kind, void *item);

#endif
