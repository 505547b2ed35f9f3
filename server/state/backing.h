/* backing.h - where the cache's items live beyond memory, behind one set of calls: the
 * single-node file store (--data-dir, backfile.h) or the PostgreSQL catalog (--catalog,
 * backcat.h). The cache (cache.h) and its loader (loader.h) hold one rule for both: an item
 * is written there before its upload is answered, read from there when it is not in memory,
 * and compared with what is there (stat, cheap: a file's stamp, or the version the catalog's
 * notifications announced) before memory is trusted again.
 *
 * An interface only: each backing fills a table of its functions. They are called from any
 * thread. Items are described by the store's sidecar type (store.h): name, format, a 64-bit
 * content hash (FNV-1a of the file store's data file, or the first bytes of the catalog's
 * SHA-256), bytes and the info JSON. */
#ifndef SDFD_BACKING_H
#define SDFD_BACKING_H

#include <stddef.h>
#include <stdint.h>

#include "state/store.h"

/* Which version of an item a reader saw: the file store's sidecar stamp, or the catalog's
 * version number (and whether that version is a deletion). */
typedef struct sdfd_seen {
    sdfd_stamp stamp;
    uint64_t version;
    int deleted;
} sdfd_seen;

/* The lookups of (kind, name) must compare with the backing again: another replica changed
 * it. Called by a backing that hears of changes (the catalog), on its own thread. */
typedef void (*sdfd_backing_changed)(void *arg, sdfd_item_kind kind, const char *name);

typedef struct sdfd_backing_ops {
    /* "--data-dir" or "--catalog": how messages name it. */
    const char *flag;
    /* The longest name it stores. */
    size_t max_name;
    /* Make it ready to use (connect, wait for the first list): 0, or an error it cannot
     * recover from (err says why; sdfd stops). */
    int (*start)(void *self, char *err, size_t cap);
    /* 0 when it can be read and written now; else why not, in msg, and non-zero. */
    int (*probe)(void *self, char *msg, size_t cap);
    /* Write an item (meta's name, format, info read; hash and bytes set): committed on 0,
     * *existed says whether it replaced one, *seen is the new version. SDFD_EUNAVAILABLE,
     * SDF_EINVAL, SDF_ELIMIT, ENOSPACE as sdfd's errors; err says why. */
    int (*write)(void *self, sdfd_item_kind kind, sdfd_sidecar *meta, const void *data,
                 size_t n, int *existed, sdfd_seen *seen, char *err, size_t cap);
    /* Delete: 0, SDF_ENOTFOUND, SDFD_EUNAVAILABLE. */
    int (*remove)(void *self, sdfd_item_kind kind, const char *name, char *err, size_t cap);
    /* The version there now, without reading the item: 0, SDF_ENOTFOUND, SDFD_EUNAVAILABLE. */
    int (*stat)(void *self, sdfd_item_kind kind, const char *name, sdfd_seen *seen, char *err,
                size_t cap);
    /* Is `now` (a stat's) a version other than `loaded` that must be read? */
    int (*changed)(const sdfd_seen *now, const sdfd_seen *loaded);
    /* The item's description and, with data, its bytes (checked): 0; SDF_ENOTFOUND;
     * SDFD_EUNAVAILABLE; SDF_EFORMAT (damaged: err says how). Free meta->info and *data. */
    int (*read)(void *self, sdfd_item_kind kind, const char *name, sdfd_sidecar *meta,
                void **data, sdfd_seen *seen, char *err, size_t cap);
    /* A damaged item is set aside (the file store moves its files) and logged. */
    void (*quarantine)(void *self, sdfd_item_kind kind, const char *name, const char *why);
    /* The items' names, sorted (free the list); `start` says it is the start's scan, when the
     * file store also clears what a crash left. */
    size_t (*names)(void *self, sdfd_item_kind kind, int start,
                    char (**names)[SDFD_MAX_NAME + 1]);
    /* Tell `fn` of other replicas' changes from now on (a backing that cannot hear of them
     * never calls it; its stat is a file's). */
    void (*watch)(void *self, sdfd_backing_changed fn, void *arg);
    void (*close)(void *self);
} sdfd_backing_ops;

typedef struct sdfd_backing {
    const sdfd_backing_ops *ops;
    void *self;
    sdfd_store *store; /* the file store's job records, when the backing is the file store */
} sdfd_backing;

#endif
