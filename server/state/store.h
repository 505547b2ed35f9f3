/* store.h - sdfd's files under --data-dir: the single-node store. One sdfd at a time holds
 * it (a flock on DIR/sdfd-store.lock, taken at open and held until the process ends): a
 * second one refuses to start, since nothing here coordinates writers. Replicas that share
 * their state are to use PostgreSQL (--catalog), not a shared directory.
 *
 * Layout 2 (docs/api.md, "Data directory"): DIR/sdfd-store.json marks the store and its
 * layout; DIR/meshes/NAME.json and DIR/volumes/NAME.json are the sidecars, each naming its
 * data file DIR/KIND/data/NAME.<hash>.<ext> (the bytes as uploaded, or the volume's EXR), a
 * directory of their own so that no item name can collide with them; DIR/jobs/ID.json are
 * job records; DIR/quarantine/ holds what failed its checks. Layout 1 (data files beside the
 * sidecars) is moved to layout 2 at open.
 *
 * The sidecar is the commit record. A write puts the new data file under a name of its own
 * (its content hash), then the sidecar, then unlinks the old data file; a delete removes the
 * sidecar first. Each file is written to a temporary name in its directory, fsynced,
 * renamed over the final name, and the directory fsynced, so a crash at any instant leaves
 * the old or the new item whole, plus at most an unreferenced data file (an "orphan"), which
 * is never served and is deleted by a later start once older than SDFD_STORE_GRACE_SECONDS
 * (a margin for a write that lands late: NFS may hand the lock to a new holder while a
 * partitioned old one still has writes in flight). Thread-safe. */
#ifndef SDFD_STORE_H
#define SDFD_STORE_H

#include <stddef.h>
#include <stdint.h>

#include "state/registry.h" /* SDFD_MAX_NAME */

typedef struct sdfd_store sdfd_store;

typedef enum sdfd_item_kind { SDFD_ITEM_MESH, SDFD_ITEM_VOLUME } sdfd_item_kind;

/* The longest name an item in the store may have: its sidecar and data file names must fit
 * the file system's 255 bytes. */
#define SDFD_STORE_MAX_NAME 200
/* Temporary and orphaned files younger than this are left alone at start. */
#define SDFD_STORE_GRACE_SECONDS 600

/* What a sidecar says about its item. `info` is a JSON object the server lists the item by
 * without loading it (a mesh's triangle count, a volume's description). */
typedef struct sdfd_sidecar {
    char name[SDFD_MAX_NAME + 1];
    char file[SDFD_MAX_NAME + 64]; /* the data file, in the kind's data/ directory */
    char format[16];               /* obj, ply, stl, off; exr */
    uint64_t hash;                 /* FNV-1a 64 of the data file */
    size_t bytes;
    char *info;                    /* malloc'd JSON text, or NULL */
} sdfd_sidecar;

/* Which version of a sidecar a reader saw: a rewrite is a rename, so a new inode. */
typedef struct sdfd_stamp {
    unsigned long long dev, ino, size;
    long long mtime_ns;
} sdfd_stamp;

/* Open (creating what is missing) the store at dir, take its lock and bring it to layout 2.
 * 0, or -1 with err set (another sdfd holds the lock: err names its pid and host, and
 * --catalog; or a layout newer than 2). */
int sdfd_store_open(const char *dir, sdfd_store **out, char *err, size_t cap);
void sdfd_store_close(sdfd_store *s); /* releases the lock; NULL is a no-op */

/* Is the store readable (its marker file and directories)? 0, or an errno value. */
int sdfd_store_probe(sdfd_store *s);

uint64_t sdfd_fnv1a64(const void *data, size_t n);

/* Write an item: data file, then sidecar (meta's name, format and info are read; its file,
 * hash and bytes are set). *existed says whether a sidecar was replaced; *stamp is the new
 * sidecar's. 0, or SDFD_EUNAVAILABLE with err set. */
int sdfd_store_write(sdfd_store *s, sdfd_item_kind kind, sdfd_sidecar *meta, const void *data,
                     size_t n, int *existed, sdfd_stamp *stamp, char *err, size_t cap);
/* Delete: sidecar, then data file. 0, SDF_ENOTFOUND, or SDFD_EUNAVAILABLE with err set. */
int sdfd_store_remove(sdfd_store *s, sdfd_item_kind kind, const char *name, char *err,
                      size_t cap);

/* The sidecar's stamp: 0, SDF_ENOTFOUND (no such item), SDFD_EUNAVAILABLE (the store cannot
 * be read; err says why). */
int sdfd_store_stat(sdfd_store *s, sdfd_item_kind kind, const char *name, sdfd_stamp *stamp,
                    char *err, size_t cap);
/* Read the sidecar (and with `data`, the data file, checked against the sidecar's length and
 * hash). 0; SDF_ENOTFOUND; SDFD_EUNAVAILABLE (the store is unreadable); SDF_EFORMAT (this
 * item is damaged: err says how, quarantine it). Free meta->info and *data. */
int sdfd_store_read(sdfd_store *s, sdfd_item_kind kind, const char *name, sdfd_sidecar *meta,
                    void **data, sdfd_stamp *stamp, char *err, size_t cap);
/* Move the item's sidecar and its data file to DIR/quarantine/, each with a .why file saying
 * `why`. Only the item's own: a sidecar that parses names NAME.<hash>.<format> (any other
 * file makes it damaged), and for one that does not, the data files named NAME.<hash>.<ext>
 * go. Another item's file never moves. */
void sdfd_store_quarantine(sdfd_store *s, sdfd_item_kind kind, const char *name,
                           const char *why);

/* Start: quarantine the kind directory's files sdfd never writes (bad names, strangers),
 * delete old temporaries and orphans, and list the items' names (sorted; free the list). */
size_t sdfd_store_scan(sdfd_store *s, sdfd_item_kind kind, char (**names)[SDFD_MAX_NAME + 1]);

/* The items' names, from their sidecars' names (sorted; free the list); no side effects. */
size_t sdfd_store_names(sdfd_store *s, sdfd_item_kind kind, char (**names)[SDFD_MAX_NAME + 1]);

/* ---- bake job records ---- */

/* Write DIR/jobs/ID.json (`json`, one object) atomically. 0 or SDFD_EUNAVAILABLE. */
int sdfd_store_write_job(sdfd_store *s, const char *id, const char *json);
/* The record, malloc'd, or NULL. */
char *sdfd_store_read_job(sdfd_store *s, const char *id);
void sdfd_store_remove_job(sdfd_store *s, const char *id);
/* Hold DIR/jobs/ID.lock (an fcntl lock, which NFS carries) while this process runs the job;
 * the fd, or -1. Released by sdfd_store_unlock_job, or by the process's death. */
int sdfd_store_lock_job(sdfd_store *s, const char *id);
void sdfd_store_unlock_job(sdfd_store *s, const char *id, int fd);
/* The ids of the records in DIR/jobs (free the list). */
size_t sdfd_store_job_ids(sdfd_store *s, char (**ids)[64]);

#endif
