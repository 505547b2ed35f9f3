/* catalog.h - sdfd's shared state in PostgreSQL (--catalog URI): the names, versions,
 * metadata and bytes of meshes and volumes, for replicas that share no filesystem.
 *
 * Every item (kind, name) has a version from one sequence: a put or a remove is one
 * transaction that gives the name a new, larger version, and a remove leaves a tombstone
 * (the version, no bytes), so a name's version never goes back and the write committed last
 * has the largest. The bytes are blobs stored once by their SHA-256 whatever the number of
 * items that hold them (catblob.h); a blob no item refers to is deleted by the sweeper only.
 * Each put and remove also sends a notification on SDFD_CATALOG_CHANNEL inside its
 * transaction, so listeners (catlisten.h) hear of exactly the committed changes, in commit
 * order; the payload is "KIND VERSION put|del NAME" (KIND: sdfd_catalog_kind_name).
 *
 * Calls come from any thread, each on a connection of its own from a small pool; a call that
 * finds PostgreSQL unreachable or going away answers SDFD_EUNAVAILABLE with libpq's message,
 * and a later call connects again: nothing needs reopening after the server comes back.
 * Errors are sdfd's codes with a message in err (cut to fit its cap bytes). Buffers are
 * the caller's, except the bytes and info a read returns (malloc'd: free them). */
#ifndef SDFD_CATALOG_H
#define SDFD_CATALOG_H

#include <libpq-fe.h>
#include <stddef.h>
#include <stdint.h>

#include "state/catmetrics.h"
#include "state/store.h" /* sdfd_item_kind */

typedef struct sdfd_catalog sdfd_catalog;

#define SDFD_CATALOG_CHANNEL "sdfd_catalog"
#define SDFD_CATALOG_HASH_BYTES 32                /* SHA-256 */
#define SDFD_CATALOG_CHUNK (1u << 20)             /* default blob chunk */
#define SDFD_CATALOG_MAX_BLOB ((size_t)4 << 30)   /* default cap on one blob */
#define SDFD_CATALOG_MAX_INFO (1u << 20)          /* an item's info text, bytes */
#define SDFD_CATALOG_MAX_FORMAT 15                /* "obj", "exr": [a-z0-9], 1..15 */

/* Zeroed means the defaults. */
typedef struct sdfd_catalog_options {
    size_t pool_size;              /* connections at most; 0: 4 */
    size_t chunk_bytes;            /* blob chunk written; 0: SDFD_CATALOG_CHUNK; <= 64 MiB */
    size_t max_blob_bytes;         /* larger puts and reads are SDF_ELIMIT; 0: MAX_BLOB */
    sdfd_catalog_metrics *metrics; /* counters to update (the caller's), or NULL */
} sdfd_catalog_options;

/* Connect (conninfo: a libpq URI or key=value string; TLS through sslmode) and create or
 * migrate the schema (catschema.h). 0 with *out set; SDF_EINVAL (bad string or options),
 * SDFD_EUNAVAILABLE (PostgreSQL unreachable: retry later), SDF_EFORMAT (the schema is
 * newer than this sdfd), SDF_EIO, SDF_ENOMEM; err says why. */
int sdfd_catalog_open(const char *conninfo, const sdfd_catalog_options *opt,
                      sdfd_catalog **out, char *err, size_t cap);
/* Close every connection. NULL is a no-op; no call may be running. */
void sdfd_catalog_close(sdfd_catalog *c);

/* "mesh" or "volume": the kind's word in notifications and in the items table. */
const char *sdfd_catalog_kind_name(sdfd_item_kind kind);

/* Store n bytes (a copy; the caller keeps its buffer) as `name`, with its format and info
 * (JSON text, or NULL), replacing what the name held. On 0 the write is committed:
 * *version is its new version, *replaced (may be NULL) says whether a live item was
 * replaced. SDF_EINVAL (bad name or format), SDF_ELIMIT (n or info too large),
 * SDFD_EUNAVAILABLE, SDF_EIO. */
int sdfd_catalog_put(sdfd_catalog *c, sdfd_item_kind kind, const char *name, const void *bytes,
                     size_t n, const char *format, const char *info, uint64_t *version,
                     int *replaced, char *err, size_t cap);

/* The same, for a caller that has the bytes' SHA-256 already (sdfd_catblob_hash's): it is
 * trusted here, and a read checks it. */
int sdfd_catalog_put_hashed(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                            const void *bytes, size_t n,
                            const unsigned char hash[SDFD_CATALOG_HASH_BYTES],
                            const char *format, const char *info, uint64_t *version,
                            int *replaced, char *err, size_t cap);

/* Delete `name`, leaving a tombstone: 0 with *version the tombstone's; SDF_ENOTFOUND when
 * the name holds nothing live; SDF_EINVAL, SDFD_EUNAVAILABLE, SDF_EIO. */
int sdfd_catalog_remove(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                        uint64_t *version, char *err, size_t cap);

/* What the catalog records about a live item. */
typedef struct sdfd_catalog_item {
    uint64_t version;
    char format[SDFD_CATALOG_MAX_FORMAT + 1];
    char *info;                                  /* malloc'd JSON text, or NULL */
    unsigned char hash[SDFD_CATALOG_HASH_BYTES]; /* SHA-256 of the bytes */
    size_t bytes;
} sdfd_catalog_item;

/* The live item `name` and, when data is non-NULL, its bytes (malloc'd, item->bytes long,
 * checked against the recorded size and hash), read in one snapshot. 0; SDF_ENOTFOUND (no
 * such item, or only a tombstone); SDF_ELIMIT (larger than max_blob_bytes); SDF_EFORMAT (the
 * stored bytes are damaged); SDFD_EUNAVAILABLE; SDF_EIO. On 0 free item->info and *data. */
int sdfd_catalog_read(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                      sdfd_catalog_item *item, void **data, char *err, size_t cap);

/* The bytes of the blob with this hash and size (as a read's item gives them), for a
 * caller that read the item without them and found no local copy. Errors as for read;
 * SDF_ENOTFOUND once the blob is swept (read the item again). */
int sdfd_catalog_read_blob(sdfd_catalog *c, const unsigned char hash[SDFD_CATALOG_HASH_BYTES],
                           size_t bytes, void **data, char *err, size_t cap);

/* Every item of a kind with its version, live or a tombstone (deleted), sorted by name: the
 * start's list and the check after a lost notification stream; the tombstones are what tells
 * a listener that a name it holds was removed while it did not listen. On 0 *out holds *n
 * entries (free it; NULL when there are none). SDFD_EUNAVAILABLE, SDF_EIO, SDF_ENOMEM. */
typedef struct sdfd_catalog_version {
    uint64_t version;
    int deleted;
    char name[SDFD_MAX_NAME + 1];
} sdfd_catalog_version;
int sdfd_catalog_versions(sdfd_catalog *c, sdfd_item_kind kind, sdfd_catalog_version **out,
                          size_t *n, char *err, size_t cap);

/* For the catalog's other tables (catjobs.h): run fn as one transaction on a pooled
 * connection (write: READ COMMITTED; else a REPEATABLE READ READ ONLY snapshot), run again
 * as a whole after a deadlock or serialization failure, as every call here is. fn sends its
 * statements with sdfd_catconn_exec(m, conn, ...) and returns 0 or a code of catconn.h with
 * err set; the result is 0 or an sdfd error code. */
typedef int (*sdfd_catalog_fn)(PGconn *conn, sdfd_catalog_metrics *m, void *arg, char *err,
                               size_t cap);
int sdfd_catalog_transact(sdfd_catalog *c, int write, sdfd_catalog_fn fn, void *arg, char *err,
                          size_t cap);

/* Delete the blobs no item refers to that no write has touched for grace_seconds; *deleted
 * (may be NULL) counts them. Safe beside any number of writers on any replica. 0,
 * SDFD_EUNAVAILABLE, SDF_EIO. */
int sdfd_catalog_sweep(sdfd_catalog *c, double grace_seconds, size_t *deleted, char *err,
                       size_t cap);

#endif
