/* catblob.h - the catalog's blobs: bytes stored once in PostgreSQL under their SHA-256, as
 * chunks of bytea, whatever number of items refers to them.
 *
 * Writing goes through the caller's transaction, so a blob and the item that refers to it
 * commit together; reading streams the chunks into one buffer of the recorded size and
 * checks the size and the hash before the bytes are trusted; the sweeper deletes blobs no
 * item refers to once their grace period is over. catalog.c's opening comment explains why a
 * write of the same bytes racing a sweep can never lose its blob. */
#ifndef SDFD_CATBLOB_H
#define SDFD_CATBLOB_H

#include <libpq-fe.h>
#include <stddef.h>

#include "state/catmetrics.h"

#define SDFD_CATBLOB_HASH_BYTES 32
#define SDFD_CATBLOB_MAX_CHUNK (64u << 20) /* a chunk is one bytea parameter and one row */

/* SHA-256 of the bytes. 0, or SDF_EIO (GnuTLS refused). */
int sdfd_catblob_hash(const void *data, size_t n, unsigned char out[SDFD_CATBLOB_HASH_BYTES]);

/* Inside the caller's transaction on conn: make the blob of these n bytes (whose hash is
 * `hash`) exist and hold its row lock until the transaction ends: touch it when it is there
 * (its recorded size must be n: SDF_EFORMAT otherwise), or insert it with its chunks of
 * `chunk` bytes (1..SDFD_CATBLOB_MAX_CHUNK). 0 or an error code (catconn.h) with err set. */
int sdfd_catblob_store(sdfd_catalog_metrics *m, PGconn *conn,
                       const unsigned char hash[SDFD_CATBLOB_HASH_BYTES], const void *data,
                       size_t n, size_t chunk, char *err, size_t cap);

/* Read a blob into *data (malloc'd, free it; *n bytes). `expect`: the size the referring item
 * records (the blob's own must match), or (size_t)-1 for any; more than max_bytes is
 * SDF_ELIMIT before anything is allocated. Chunks out of order or of the wrong lengths, or
 * bytes whose hash differs, are SDF_EFORMAT (the blob is damaged); SDF_ENOTFOUND when no
 * such blob exists. Run it inside a REPEATABLE READ transaction to read it with its item. */
int sdfd_catblob_load(sdfd_catalog_metrics *m, PGconn *conn,
                      const unsigned char hash[SDFD_CATBLOB_HASH_BYTES], size_t expect,
                      size_t max_bytes, void **data, size_t *n, char *err, size_t cap);

/* Delete the blobs no item refers to whose last write is more than grace_seconds old, each
 * in its own statement (conn outside a transaction); *deleted counts them. 0 or an error
 * code with err set. */
int sdfd_catblob_sweep(sdfd_catalog_metrics *m, PGconn *conn, double grace_seconds,
                       size_t *deleted, char *err, size_t cap);

#endif
