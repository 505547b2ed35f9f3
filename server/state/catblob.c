/* catblob.c - content-addressed blobs as chunked bytea (see catblob.h).
 *
 * Bytes travel as binary parameters and results, straight from the caller's buffer and
 * straight into the reader's, one chunk (one row) at a time: nothing is hex-encoded and no
 * copy of the whole blob is made beside the one buffer it is read into. A row of
 * sdfd_blobs commits in the same transaction as all its chunks, so a blob that exists is
 * whole unless something outside sdfd damaged it, which the size and hash checks catch. */
#include "state/catblob.h"

#include <arpa/inet.h>
#include <gnutls/crypto.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "state/catconn.h"

/* A touch (or an insert) holds the blob's row lock to the end of the writer's transaction. */
static const char TOUCH[] =
    "UPDATE sdfd_blobs SET touched = clock_timestamp() WHERE hash = $1 RETURNING size";
static const char INSERT_BLOB[] =
    "INSERT INTO sdfd_blobs (hash, size, chunks, touched)"
    " VALUES ($1, $2::bigint, $3::integer, clock_timestamp())"
    " ON CONFLICT (hash) DO NOTHING RETURNING 1";
static const char INSERT_CHUNK[] =
    "INSERT INTO sdfd_chunks (hash, seq, data) VALUES ($1, $2::integer, $3)";
static const char SELECT_BLOB[] = "SELECT size, chunks FROM sdfd_blobs WHERE hash = $1";
static const char SELECT_CHUNKS[] =
    "SELECT seq, data FROM sdfd_chunks WHERE hash = $1 ORDER BY seq";
/* Unreferenced and older than the grace: a candidate, and again at its delete, which waits
 * for a writer holding the row and then re-checks `touched` on the row it wrote. */
#define UNREFERENCED_AND_OLD                                                           \
    "touched < clock_timestamp() - make_interval(secs => $2::double precision)"       \
    " AND NOT EXISTS (SELECT 1 FROM sdfd_items i WHERE i.hash = b.hash)"
static const char SELECT_SWEEP[] =
    "SELECT hash FROM sdfd_blobs b WHERE " UNREFERENCED_AND_OLD
    " LIMIT $1::integer";
static const char DELETE_SWEEP[] =
    "DELETE FROM sdfd_blobs b WHERE hash = $1 AND " UNREFERENCED_AND_OLD;
#define SWEEP_BATCH 256

int sdfd_catblob_hash(const void *data, size_t n, unsigned char out[SDFD_CATBLOB_HASH_BYTES])
{
    return gnutls_hash_fast(GNUTLS_DIG_SHA256, data, n, out) == 0 ? 0 : SDF_EIO;
}

static void hex(const unsigned char hash[SDFD_CATBLOB_HASH_BYTES], char out[17])
{
    for (int i = 0; i < 8; i++) /* the first 8 bytes name a blob well enough in a message */
        snprintf(out + 2 * i, 3, "%02x", hash[i]);
}

/* Touch the blob's row; *found says whether it exists (then it is locked and checked). */
static int touch(sdfd_catalog_metrics *m, PGconn *conn, const unsigned char *hash, size_t n,
                 int *found, char *err, size_t cap)
{
    const char *values[] = {(const char *)hash};
    const int lengths[] = {SDFD_CATBLOB_HASH_BYTES}, formats[] = {1};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(m, conn, TOUCH, 1, values, lengths, formats, 0, &r, err, cap);
    if (rc)
        return rc;
    *found = PQntuples(r) > 0;
    unsigned long long size = *found ? strtoull(PQgetvalue(r, 0, 0), NULL, 10) : 0;
    PQclear(r);
    if (*found && size != n) {
        char h[17];
        hex(hash, h);
        snprintf(err, cap, "catalog blob %s... records %llu bytes, not %zu", h, size, n);
        return SDF_EFORMAT;
    }
    return 0;
}

/* Insert the blob's row; *inserted is 0 when another transaction committed it first. */
static int insert_row(sdfd_catalog_metrics *m, PGconn *conn, const unsigned char *hash,
                      size_t n, size_t chunks, int *inserted, char *err, size_t cap)
{
    char size_text[24], chunks_text[24];
    snprintf(size_text, sizeof size_text, "%zu", n);
    snprintf(chunks_text, sizeof chunks_text, "%zu", chunks);
    const char *values[] = {(const char *)hash, size_text, chunks_text};
    const int lengths[] = {SDFD_CATBLOB_HASH_BYTES, 0, 0}, formats[] = {1, 0, 0};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(m, conn, INSERT_BLOB, 3, values, lengths, formats, 0, &r, err,
                               cap);
    if (!rc)
        *inserted = PQntuples(r) > 0;
    PQclear(r);
    return rc;
}

static int insert_chunks(sdfd_catalog_metrics *m, PGconn *conn, const unsigned char *hash,
                         const unsigned char *data, size_t n, size_t chunk, char *err,
                         size_t cap)
{
    for (size_t seq = 0, off = 0; off < n; seq++, off += chunk) {
        size_t len = n - off < chunk ? n - off : chunk;
        char seq_text[24];
        snprintf(seq_text, sizeof seq_text, "%zu", seq);
        const char *values[] = {(const char *)hash, seq_text, (const char *)data + off};
        const int lengths[] = {SDFD_CATBLOB_HASH_BYTES, 0, (int)len}, formats[] = {1, 0, 1};
        int rc = sdfd_catconn_exec(m, conn, INSERT_CHUNK, 3, values, lengths, formats, 0, NULL,
                                   err, cap);
        if (rc)
            return rc;
    }
    return 0;
}

int sdfd_catblob_store(sdfd_catalog_metrics *m, PGconn *conn,
                       const unsigned char hash[SDFD_CATBLOB_HASH_BYTES], const void *data,
                       size_t n, size_t chunk, char *err, size_t cap)
{
    if (chunk == 0 || chunk > SDFD_CATBLOB_MAX_CHUNK || n / chunk >= INT32_MAX) {
        snprintf(err, cap, "catalog blob of %zu bytes in chunks of %zu: out of range", n, chunk);
        return SDF_ELIMIT;
    }
    /* Each turn either finds the row, inserts it, or sees another transaction commit it
     * between the two statements (found by the next turn's touch). */
    for (int turn = 0; turn < 4; turn++) {
        int found = 0, inserted = 0;
        int rc = touch(m, conn, hash, n, &found, err, cap);
        if (rc || found)
            return rc;
        rc = insert_row(m, conn, hash, n, (n + chunk - 1) / chunk, &inserted, err, cap);
        if (rc || inserted)
            return rc ? rc : insert_chunks(m, conn, hash, data, n, chunk, err, cap);
    }
    snprintf(err, cap, "catalog blob: the row came and went four times");
    return SDFD_CATCONN_RETRY;
}

/* Where the chunks of one blob are read to. */
typedef struct reader {
    unsigned char *buf;
    size_t size, got;
    long long next_seq, chunks;
    const char *name; /* hex prefix, for messages */
} reader;

static int read_chunk(void *arg, const PGresult *row, char *err, size_t cap)
{
    reader *rd = arg;
    uint32_t seq_be;
    size_t len = (size_t)PQgetlength(row, 0, 1);
    if (PQgetlength(row, 0, 0) != 4) {
        snprintf(err, cap, "catalog blob %s...: a chunk number is not 4 bytes", rd->name);
        return SDF_EFORMAT;
    }
    memcpy(&seq_be, PQgetvalue(row, 0, 0), 4);
    if ((long long)ntohl(seq_be) != rd->next_seq || rd->next_seq >= rd->chunks ||
        len > rd->size - rd->got || len == 0) {
        snprintf(err, cap, "catalog blob %s...: chunk %u (%zu bytes) does not follow %zu of"
                 " %zu bytes in %lld chunks", rd->name, (unsigned)ntohl(seq_be), len, rd->got,
                 rd->size, rd->chunks);
        return SDF_EFORMAT;
    }
    memcpy(rd->buf + rd->got, PQgetvalue(row, 0, 1), len);
    rd->got += len;
    rd->next_seq++;
    return 0;
}

/* The blob's recorded size and chunk count, checked against the caller's expectations. */
static int blob_row(sdfd_catalog_metrics *m, PGconn *conn, const unsigned char *hash,
                    size_t expect, size_t max_bytes, reader *rd, char *err, size_t cap)
{
    const char *values[] = {(const char *)hash};
    const int lengths[] = {SDFD_CATBLOB_HASH_BYTES}, formats[] = {1};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(m, conn, SELECT_BLOB, 1, values, lengths, formats, 0, &r, err,
                               cap);
    if (rc)
        return rc;
    if (PQntuples(r) == 0) {
        PQclear(r);
        snprintf(err, cap, "catalog blob %s... not found", rd->name);
        return SDF_ENOTFOUND;
    }
    unsigned long long size = strtoull(PQgetvalue(r, 0, 0), NULL, 10);
    rd->chunks = strtoll(PQgetvalue(r, 0, 1), NULL, 10);
    PQclear(r);
    if (size > max_bytes) {
        snprintf(err, cap, "catalog blob %s... has %llu bytes, more than the limit of %zu",
                 rd->name, size, max_bytes);
        return SDF_ELIMIT;
    }
    rd->size = (size_t)size;
    if ((expect != (size_t)-1 && rd->size != expect) || rd->chunks < (rd->size > 0) ||
        (unsigned long long)rd->chunks > size) {
        snprintf(err, cap, "catalog blob %s... records %llu bytes in %lld chunks, expected %zu"
                 " bytes", rd->name, size, rd->chunks, expect);
        return SDF_EFORMAT;
    }
    return 0;
}

/* Every chunk arrived and the bytes are the ones the hash names. */
static int check_read(const reader *rd, const unsigned char *hash, char *err, size_t cap)
{
    unsigned char got[SDFD_CATBLOB_HASH_BYTES];
    if (rd->got != rd->size || rd->next_seq != rd->chunks) {
        snprintf(err, cap, "catalog blob %s...: %zu of %zu bytes in %lld of %lld chunks",
                 rd->name, rd->got, rd->size, rd->next_seq, rd->chunks);
        return SDF_EFORMAT;
    }
    if (sdfd_catblob_hash(rd->buf, rd->size, got) ||
        memcmp(got, hash, SDFD_CATBLOB_HASH_BYTES)) {
        snprintf(err, cap, "catalog blob %s...: its bytes do not have its hash", rd->name);
        return SDF_EFORMAT;
    }
    return 0;
}

int sdfd_catblob_load(sdfd_catalog_metrics *m, PGconn *conn,
                      const unsigned char hash[SDFD_CATBLOB_HASH_BYTES], size_t expect,
                      size_t max_bytes, void **data, size_t *n, char *err, size_t cap)
{
    char name[17];
    hex(hash, name);
    reader rd = {.name = name};
    *data = NULL, *n = 0;
    int rc = blob_row(m, conn, hash, expect, max_bytes, &rd, err, cap);
    if (rc)
        return rc;
    if (!(rd.buf = malloc(rd.size ? rd.size : 1))) {
        snprintf(err, cap, "out of memory for a catalog blob of %zu bytes", rd.size);
        return SDF_ENOMEM;
    }
    const char *values[] = {(const char *)hash};
    const int lengths[] = {SDFD_CATBLOB_HASH_BYTES}, formats[] = {1};
    rc = sdfd_catconn_stream(m, conn, SELECT_CHUNKS, 1, values, lengths, formats, 1, read_chunk,
                             &rd, err, cap);
    if (!rc)
        rc = check_read(&rd, hash, err, cap);
    if (rc) {
        free(rd.buf);
        return rc;
    }
    *data = rd.buf, *n = rd.size;
    return 0;
}

/* Up to SWEEP_BATCH candidates (binary hashes; PQclear the result). */
static int candidates(sdfd_catalog_metrics *m, PGconn *conn, const char *grace, PGresult **r,
                      char *err, size_t cap)
{
    char limit[16];
    snprintf(limit, sizeof limit, "%d", SWEEP_BATCH);
    const char *values[] = {limit, grace};
    return sdfd_catconn_exec(m, conn, SELECT_SWEEP, 2, values, NULL, NULL, 1, r, err, cap);
}

/* Delete one candidate if it still qualifies; a constraint's refusal (an item committed a
 * reference to it since) leaves it: it is in use. */
static int delete_one(sdfd_catalog_metrics *m, PGconn *conn, const char *hash, int len,
                      const char *grace, size_t *deleted, char *err, size_t cap)
{
    const char *values[] = {hash, grace};
    const int lengths[] = {len, 0}, formats[] = {1, 0};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(m, conn, DELETE_SWEEP, 2, values, lengths, formats, 0, &r, err,
                               cap);
    if (!rc)
        *deleted += (size_t)atoi(PQcmdTuples(r));
    PQclear(r);
    return rc == SDFD_CATCONN_CONFLICT ? 0 : rc;
}

int sdfd_catblob_sweep(sdfd_catalog_metrics *m, PGconn *conn, double grace_seconds,
                       size_t *deleted, char *err, size_t cap)
{
    char grace[32];
    snprintf(grace, sizeof grace, "%.6f", grace_seconds > 0 ? grace_seconds : 0);
    *deleted = 0;
    for (;;) {
        PGresult *r = NULL;
        int rc = candidates(m, conn, grace, &r, err, cap);
        if (rc)
            return rc;
        int rows = PQntuples(r);
        size_t before = *deleted;
        for (int i = 0; i < rows && !rc; i++)
            rc = delete_one(m, conn, PQgetvalue(r, i, 0), PQgetlength(r, i, 0), grace, deleted,
                            err, cap);
        PQclear(r);
        if (rc || rows < SWEEP_BATCH || *deleted == before)
            return rc;
    }
}
