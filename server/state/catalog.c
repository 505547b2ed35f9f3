/* catalog.c - items and their versions in PostgreSQL (see catalog.h; tables: catschema.c).
 *
 * A put is one transaction of three statements: lock the name's row (inserting a
 * placeholder when the name is new), store the blob (catblob.c: touch its row, or insert it
 * and its chunks), then set the row to a version drawn from the sequence only now, while the
 * row is locked, and notify. Drawing the version after the lock is what makes the write
 * committed last the one with the largest version: a second writer of the name waits for the
 * first's commit before it draws. A remove is one statement of the same kind.
 *
 * Why a racing put of the same bytes never loses its blob to the sweeper, under READ
 * COMMITTED. The danger: a remove (or a replacement) leaves blob H unreferenced, the sweeper
 * decides to delete H, and meanwhile a put of the same bytes finds H present and so writes
 * no chunks of its own. Two rules close it:
 * 1. the put locks H's row before it refers to H, and holds the lock until it commits: an
 *    UPDATE setting `touched` when the row is there, else the INSERT of the row and its
 *    chunks. If the sweeper's DELETE of H came first, the UPDATE waits for it, finds no row
 *    once it commits, and the put inserts H afresh; if the UPDATE came first, the DELETE
 *    waits for the put to end;
 * 2. a foreign key from sdfd_items.hash to sdfd_blobs.hash. A DELETE that waited for the put
 *    re-checks its condition on H's new row version, but judges "no item refers to H" in its
 *    own snapshot, which does not show the put's item; the key's check reads the latest
 *    committed state instead, finds that item and refuses the delete, which the sweeper takes
 *    as "in use" and moves on.
 * So a committed item's blob exists, with its chunks (committed with its row), whatever the
 * order of the statements; test_catalog's race loses acknowledged puts without rule 2 and
 * fails puts without rule 1. The grace period adds nothing to this safety: it keeps the
 * sweeper off blobs written recently (a put of the same bytes renews `touched`), so it seldom
 * meets the key's refusal, and leaves room for writers that store a blob before they refer
 * to it.
 *
 * Every call runs through one driver: take a connection, BEGIN, the call's statements,
 * COMMIT, give the connection back. A deadlock or serialization failure runs the call
 * again; a reused connection that fails at BEGIN (nothing done yet) is replaced by the next
 * idle one or a new one. */
#include "state/catalog.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "state/catblob.h"
#include "state/catconn.h"
#include "state/catschema.h"

_Static_assert(SDFD_CATALOG_HASH_BYTES == SDFD_CATBLOB_HASH_BYTES, "one hash size");

struct sdfd_catalog {
    sdfd_catconn_pool *pool;
    sdfd_catalog_metrics *metrics; /* the caller's, or own */
    sdfd_catalog_metrics own;
    size_t chunk, max_blob, pool_size;
};

#define ATTEMPTS 5 /* of a call that meets a deadlock or serialization failure */

static const char LOCK_NAME[] =
    "INSERT INTO sdfd_items (kind, name, version, updated) VALUES ($1, $2, 0, now())"
    " ON CONFLICT (kind, name) DO UPDATE SET updated = sdfd_items.updated"
    " RETURNING hash IS NOT NULL";
static const char SET_ITEM[] =
    "WITH u AS (UPDATE sdfd_items SET version = nextval('sdfd_version_seq'), hash = $3,"
    " format = $4, info = $5, size = $6::bigint, updated = now()"
    " WHERE kind = $1 AND name = $2 RETURNING version)"
    " SELECT version, pg_notify('" SDFD_CATALOG_CHANNEL "', $1 || ' ' || version || ' put ' || $2)"
    " FROM u";
static const char TOMBSTONE[] =
    "WITH u AS (UPDATE sdfd_items SET version = nextval('sdfd_version_seq'), hash = NULL,"
    " format = NULL, info = NULL, size = NULL, updated = now()"
    " WHERE kind = $1 AND name = $2 AND hash IS NOT NULL RETURNING version)"
    " SELECT version, pg_notify('" SDFD_CATALOG_CHANNEL "', $1 || ' ' || version || ' del ' || $2)"
    " FROM u";
static const char SELECT_ITEM[] =
    "SELECT version, encode(hash, 'hex'), format, info, size FROM sdfd_items"
    " WHERE kind = $1 AND name = $2 AND hash IS NOT NULL";
static const char SELECT_VERSIONS[] =
    "SELECT name, version, hash IS NULL FROM sdfd_items WHERE kind = $1 AND version > 0"
    " ORDER BY name";
static const char BEGIN_WRITE[] = "BEGIN";
static const char BEGIN_READ[] = "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY";

const char *sdfd_catalog_kind_name(sdfd_item_kind kind)
{
    return kind == SDFD_ITEM_MESH ? "mesh" : "volume";
}

/* ---- the driver ------------------------------------------------------------------------- */

typedef int (*call_fn)(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap);

static int exec0(sdfd_catalog *c, PGconn *conn, const char *sql, char *err, size_t cap)
{
    return sdfd_catconn_exec(c->metrics, conn, sql, 0, NULL, NULL, NULL, 0, NULL, err, cap);
}

/* One attempt: `begin`, fn, COMMIT (begin NULL: fn alone, each statement its own
 * transaction); *at_begin says the failure came at BEGIN. */
static int attempt(sdfd_catalog *c, PGconn *conn, const char *begin, call_fn fn, void *arg,
                   int *at_begin, char *err, size_t cap)
{
    int rc = begin ? exec0(c, conn, begin, err, cap) : 0;
    *at_begin = rc != 0;
    if (!rc)
        rc = fn(c, conn, arg, err, cap);
    if (!begin)
        return rc;
    if (rc) {
        if (PQstatus(conn) == CONNECTION_OK && !*at_begin)
            PQclear(PQexec(conn, "ROLLBACK"));
        return rc;
    }
    rc = exec0(c, conn, "COMMIT", err, cap);
    if (rc == SDFD_EUNAVAILABLE && begin == BEGIN_WRITE) {
        size_t len = strlen(err);
        snprintf(err + len, cap > len ? cap - len : 0, " (the write may have committed)");
    }
    return rc;
}

/* The positive codes of catconn.h stay inside the catalog. */
static int public_code(int rc, char *err, size_t cap)
{
    if (rc == SDFD_CATCONN_RETRY) {
        size_t len = strlen(err);
        snprintf(err + len, cap > len ? cap - len : 0, " (after %d attempts)", ATTEMPTS);
        return SDFD_EUNAVAILABLE;
    }
    return rc == SDFD_CATCONN_CONFLICT ? SDF_EIO : rc;
}

static int run(sdfd_catalog *c, const char *begin, call_fn fn, void *arg, char *err, size_t cap)
{
    int rc = 0;
    size_t stale = 0;
    for (int n = 0; n < ATTEMPTS; n++) {
        PGconn *conn = NULL;
        int reused = 0, at_begin = 0;
        if ((rc = sdfd_catconn_get(c->pool, &conn, &reused, err, cap)))
            return rc;
        rc = attempt(c, conn, begin, fn, arg, &at_begin, err, cap);
        sdfd_catconn_put(c->pool, conn); /* closed if it failed */
        if (rc == SDFD_EUNAVAILABLE && reused && at_begin && stale++ < c->pool_size) {
            n--; /* the server dropped it while it sat idle: try the next, or a new one */
            continue;
        }
        if (rc != SDFD_CATCONN_RETRY)
            break;
    }
    return public_code(rc, err, cap);
}

/* ---- open and close --------------------------------------------------------------------- */

static int migrate(sdfd_catalog *c, char *err, size_t cap)
{
    PGconn *conn = NULL;
    int reused = 0, applied = 0;
    int rc = sdfd_catconn_get(c->pool, &conn, &reused, err, cap);
    if (rc)
        return rc;
    rc = sdfd_catschema_migrate(c->metrics, conn, &applied, err, cap);
    sdfd_catconn_put(c->pool, conn);
    return public_code(rc, err, cap);
}

int sdfd_catalog_open(const char *conninfo, const sdfd_catalog_options *opt,
                      sdfd_catalog **out, char *err, size_t cap)
{
    static const sdfd_catalog_options defaults = {0};
    opt = opt ? opt : &defaults;
    *out = NULL;
    int rc = sdfd_catconn_check(conninfo, err, cap);
    if (rc)
        return rc;
    if (opt->chunk_bytes > SDFD_CATBLOB_MAX_CHUNK) {
        snprintf(err, cap, "catalog chunk of %zu bytes: at most %u", opt->chunk_bytes,
                 SDFD_CATBLOB_MAX_CHUNK);
        return SDF_EINVAL;
    }
    size_t pool_size = opt->pool_size ? opt->pool_size : 4;
    sdfd_catalog *c = calloc(1, sizeof *c);
    if (!c || !(c->pool = sdfd_catconn_pool_create(conninfo, pool_size,
                                                   opt->metrics ? opt->metrics : &c->own))) {
        free(c);
        snprintf(err, cap, "out of memory opening the catalog");
        return SDF_ENOMEM;
    }
    c->metrics = opt->metrics ? opt->metrics : &c->own;
    c->pool_size = pool_size;
    c->chunk = opt->chunk_bytes ? opt->chunk_bytes : SDFD_CATALOG_CHUNK;
    c->max_blob = opt->max_blob_bytes ? opt->max_blob_bytes : SDFD_CATALOG_MAX_BLOB;
    if ((rc = migrate(c, err, cap))) {
        sdfd_catalog_close(c);
        return rc;
    }
    *out = c;
    return 0;
}

void sdfd_catalog_close(sdfd_catalog *c)
{
    if (!c)
        return;
    sdfd_catconn_pool_destroy(c->pool);
    free(c);
}

/* ---- arguments -------------------------------------------------------------------------- */

static int check_name(sdfd_item_kind kind, const char *name, char *err, size_t cap)
{
    if ((kind != SDFD_ITEM_MESH && kind != SDFD_ITEM_VOLUME) || !name ||
        !sdfd_valid_name(name, strlen(name))) {
        snprintf(err, cap, "invalid %s name", kind == SDFD_ITEM_VOLUME ? "volume" : "mesh");
        return SDF_EINVAL;
    }
    return 0;
}

static int check_put(const sdfd_catalog *c, size_t n, const char *format, const char *info,
                     char *err, size_t cap)
{
    size_t len = format ? strlen(format) : 0;
    if (len == 0 || len > SDFD_CATALOG_MAX_FORMAT || strspn(format, "abcdefghijklmnopqrstuvwxyz"
                                                                   "0123456789") != len) {
        snprintf(err, cap, "invalid format: 1 to %d characters of [a-z0-9]",
                 SDFD_CATALOG_MAX_FORMAT);
        return SDF_EINVAL;
    }
    if (n > c->max_blob) {
        snprintf(err, cap, "%zu bytes: more than the catalog's limit of %zu", n, c->max_blob);
        return SDF_ELIMIT;
    }
    if (info && strlen(info) > SDFD_CATALOG_MAX_INFO) {
        snprintf(err, cap, "info text longer than the catalog's limit of %u bytes",
                 SDFD_CATALOG_MAX_INFO);
        return SDF_ELIMIT;
    }
    return 0;
}

/* The version a statement returned in its first column; 0 (no row) when none. */
static uint64_t version_of(const PGresult *r)
{
    return PQntuples(r) ? strtoull(PQgetvalue(r, 0, 0), NULL, 10) : 0;
}

/* ---- put and remove --------------------------------------------------------------------- */

typedef struct put_args {
    sdfd_item_kind kind;
    const char *name, *format, *info;
    const void *bytes;
    size_t n;
    unsigned char hash[SDFD_CATALOG_HASH_BYTES];
    uint64_t version;
    int replaced;
} put_args;

static int lock_name(sdfd_catalog *c, PGconn *conn, put_args *a, char *err, size_t cap)
{
    const char *values[] = {sdfd_catalog_kind_name(a->kind), a->name};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(c->metrics, conn, LOCK_NAME, 2, values, NULL, NULL, 0, &r, err,
                               cap);
    if (!rc)
        a->replaced = PQntuples(r) == 1 && !strcmp(PQgetvalue(r, 0, 0), "t");
    PQclear(r);
    return rc;
}

static int set_item(sdfd_catalog *c, PGconn *conn, put_args *a, char *err, size_t cap)
{
    char size_text[24];
    snprintf(size_text, sizeof size_text, "%zu", a->n);
    const char *values[] = {sdfd_catalog_kind_name(a->kind), a->name, (const char *)a->hash,
                            a->format, a->info, size_text};
    const int lengths[] = {0, 0, SDFD_CATALOG_HASH_BYTES, 0, 0, 0};
    const int formats[] = {0, 0, 1, 0, 0, 0};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(c->metrics, conn, SET_ITEM, 6, values, lengths, formats, 0, &r,
                               err, cap);
    if (!rc && !(a->version = version_of(r))) {
        snprintf(err, cap, "catalog: the locked row of %s vanished", a->name);
        rc = SDF_EIO;
    }
    PQclear(r);
    return rc;
}

static int put_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    put_args *a = arg;
    int rc = lock_name(c, conn, a, err, cap);
    if (!rc)
        rc = sdfd_catblob_store(c->metrics, conn, a->hash, a->bytes, a->n, c->chunk, err, cap);
    if (!rc)
        rc = set_item(c, conn, a, err, cap);
    return rc;
}

/* A put's arguments: 0, or SDF_EINVAL / SDF_ELIMIT with err. */
static int check_put_args(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                          const void *bytes, size_t n, const char *format, const char *info,
                          char *err, size_t cap)
{
    int rc = check_name(kind, name, err, cap);
    if (!rc)
        rc = check_put(c, n, format, info, err, cap);
    if (!rc && (!bytes && n)) {
        snprintf(err, cap, "no bytes to store");
        rc = SDF_EINVAL;
    }
    return rc;
}

int sdfd_catalog_put(sdfd_catalog *c, sdfd_item_kind kind, const char *name, const void *bytes,
                     size_t n, const char *format, const char *info, uint64_t *version,
                     int *replaced, char *err, size_t cap)
{
    unsigned char hash[SDFD_CATALOG_HASH_BYTES];
    int rc = check_put_args(c, kind, name, bytes, n, format, info, err, cap);
    if (rc) /* before hashing what would be refused */
        return rc;
    if (sdfd_catblob_hash(bytes ? bytes : "", n, hash)) {
        snprintf(err, cap, "cannot compute SHA-256 (GnuTLS)");
        return SDF_EIO;
    }
    return sdfd_catalog_put_hashed(c, kind, name, bytes, n, hash, format, info, version,
                                   replaced, err, cap);
}

int sdfd_catalog_put_hashed(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                            const void *bytes, size_t n,
                            const unsigned char hash[SDFD_CATALOG_HASH_BYTES],
                            const char *format, const char *info, uint64_t *version,
                            int *replaced, char *err, size_t cap)
{
    put_args a = {.kind = kind, .name = name, .format = format, .info = info,
                  .bytes = bytes, .n = n};
    memcpy(a.hash, hash, sizeof a.hash);
    int rc = check_put_args(c, kind, name, bytes, n, format, info, err, cap);
    if (!rc)
        rc = run(c, BEGIN_WRITE, put_call, &a, err, cap);
    if (rc)
        return rc;
    *version = a.version;
    if (replaced)
        *replaced = a.replaced;
    return 0;
}

typedef struct remove_args {
    sdfd_item_kind kind;
    const char *name;
    uint64_t version;
} remove_args;

static int remove_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    remove_args *a = arg;
    const char *values[] = {sdfd_catalog_kind_name(a->kind), a->name};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(c->metrics, conn, TOMBSTONE, 2, values, NULL, NULL, 0, &r, err,
                               cap);
    if (!rc && !(a->version = version_of(r))) {
        snprintf(err, cap, "no %s named %s in the catalog", sdfd_catalog_kind_name(a->kind),
                 a->name);
        rc = SDF_ENOTFOUND;
    }
    PQclear(r);
    return rc;
}

int sdfd_catalog_remove(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                        uint64_t *version, char *err, size_t cap)
{
    remove_args a = {.kind = kind, .name = name};
    int rc = check_name(kind, name, err, cap);
    if (!rc)
        rc = run(c, BEGIN_WRITE, remove_call, &a, err, cap);
    if (!rc)
        *version = a.version;
    return rc;
}

/* ---- reads ------------------------------------------------------------------------------ */

typedef struct read_args {
    sdfd_item_kind kind;
    const char *name;
    sdfd_catalog_item *item;
    void **data;
    const unsigned char *hash; /* read_blob: the blob alone */
    size_t bytes;
} read_args;

static int unhex(const char *text, unsigned char *out, size_t n)
{
    if (strlen(text) != 2 * n)
        return -1;
    for (size_t i = 0; i < n; i++) {
        unsigned v;
        if (sscanf(text + 2 * i, "%2x", &v) != 1)
            return -1;
        out[i] = (unsigned char)v;
    }
    return 0;
}

/* The item row's columns into *item, every length checked. */
static int parse_item(const sdfd_catalog *c, const PGresult *r, sdfd_catalog_item *item,
                      char *err, size_t cap)
{
    unsigned long long size = strtoull(PQgetvalue(r, 0, 4), NULL, 10);
    item->version = strtoull(PQgetvalue(r, 0, 0), NULL, 10);
    if (unhex(PQgetvalue(r, 0, 1), item->hash, SDFD_CATALOG_HASH_BYTES) ||
        PQgetlength(r, 0, 2) > SDFD_CATALOG_MAX_FORMAT ||
        PQgetlength(r, 0, 3) > (int)SDFD_CATALOG_MAX_INFO || !item->version) {
        snprintf(err, cap, "catalog: a damaged item row");
        return SDF_EFORMAT;
    }
    if (size > c->max_blob) {
        snprintf(err, cap, "catalog item of %llu bytes: more than the limit of %zu", size,
                 c->max_blob);
        return SDF_ELIMIT;
    }
    item->bytes = (size_t)size;
    snprintf(item->format, sizeof item->format, "%s", PQgetvalue(r, 0, 2));
    if (!PQgetisnull(r, 0, 3) && !(item->info = strdup(PQgetvalue(r, 0, 3)))) {
        snprintf(err, cap, "out of memory reading the catalog");
        return SDF_ENOMEM;
    }
    return 0;
}

static int item_row(sdfd_catalog *c, PGconn *conn, read_args *a, char *err, size_t cap)
{
    const char *values[] = {sdfd_catalog_kind_name(a->kind), a->name};
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(c->metrics, conn, SELECT_ITEM, 2, values, NULL, NULL, 0, &r,
                               err, cap);
    if (!rc && PQntuples(r) == 0) {
        snprintf(err, cap, "no %s named %s in the catalog", sdfd_catalog_kind_name(a->kind),
                 a->name);
        rc = SDF_ENOTFOUND;
    }
    if (!rc)
        rc = parse_item(c, r, a->item, err, cap);
    PQclear(r);
    return rc;
}

static int read_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    read_args *a = arg;
    size_t n = 0;
    free(a->item->info); /* from an attempt that failed later */
    memset(a->item, 0, sizeof *a->item);
    if (a->data) {
        free(*a->data);
        *a->data = NULL;
    }
    int rc = item_row(c, conn, a, err, cap);
    if (!rc && a->data) {
        rc = sdfd_catblob_load(c->metrics, conn, a->item->hash, a->item->bytes, c->max_blob,
                               a->data, &n, err, cap);
        if (rc == SDF_ENOTFOUND) /* the foreign key forbids it: damage */
            rc = SDF_EFORMAT;
    }
    return rc;
}

int sdfd_catalog_read(sdfd_catalog *c, sdfd_item_kind kind, const char *name,
                      sdfd_catalog_item *item, void **data, char *err, size_t cap)
{
    read_args a = {.kind = kind, .name = name, .item = item, .data = data};
    memset(item, 0, sizeof *item);
    if (data)
        *data = NULL;
    int rc = check_name(kind, name, err, cap);
    if (!rc)
        rc = run(c, BEGIN_READ, read_call, &a, err, cap);
    if (rc) {
        free(item->info);
        item->info = NULL;
        if (data) {
            free(*data);
            *data = NULL;
        }
    }
    return rc;
}

static int blob_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    read_args *a = arg;
    size_t n = 0;
    return sdfd_catblob_load(c->metrics, conn, a->hash, a->bytes, c->max_blob, a->data, &n, err,
                             cap);
}

int sdfd_catalog_read_blob(sdfd_catalog *c, const unsigned char hash[SDFD_CATALOG_HASH_BYTES],
                           size_t bytes, void **data, char *err, size_t cap)
{
    read_args a = {.hash = hash, .bytes = bytes, .data = data};
    *data = NULL;
    return run(c, BEGIN_READ, blob_call, &a, err, cap);
}

typedef struct versions_args {
    sdfd_item_kind kind;
    sdfd_catalog_version *list;
    size_t n;
} versions_args;

static int versions_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    versions_args *a = arg;
    const char *values[] = {sdfd_catalog_kind_name(a->kind)};
    free(a->list); /* from an attempt that failed later */
    a->list = NULL, a->n = 0;
    PGresult *r = NULL;
    int rc = sdfd_catconn_exec(c->metrics, conn, SELECT_VERSIONS, 1, values, NULL, NULL, 0, &r,
                               err, cap);
    size_t rows = rc ? 0 : (size_t)PQntuples(r);
    if (!rc && rows && !(a->list = calloc(rows, sizeof *a->list))) {
        snprintf(err, cap, "out of memory listing %zu catalog items", rows);
        rc = SDF_ENOMEM;
    }
    for (size_t i = 0; !rc && i < rows; i++) {
        sdfd_catalog_version *v = &a->list[a->n++];
        v->version = strtoull(PQgetvalue(r, (int)i, 1), NULL, 10);
        v->deleted = PQgetvalue(r, (int)i, 2)[0] == 't';
        if (PQgetlength(r, (int)i, 0) > SDFD_MAX_NAME) {
            snprintf(err, cap, "catalog: a name longer than %d bytes", SDFD_MAX_NAME);
            rc = SDF_EFORMAT;
        } else
            memcpy(v->name, PQgetvalue(r, (int)i, 0), (size_t)PQgetlength(r, (int)i, 0) + 1);
    }
    PQclear(r);
    return rc;
}

int sdfd_catalog_versions(sdfd_catalog *c, sdfd_item_kind kind, sdfd_catalog_version **out,
                          size_t *n, char *err, size_t cap)
{
    versions_args a = {.kind = kind};
    *out = NULL, *n = 0;
    int rc = run(c, BEGIN_READ, versions_call, &a, err, cap);
    if (rc) {
        free(a.list);
        return rc;
    }
    *out = a.list, *n = a.n;
    return 0;
}

typedef struct transact_args {
    sdfd_catalog_fn fn;
    void *arg;
} transact_args;

static int transact_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    transact_args *a = arg;
    return a->fn(conn, c->metrics, a->arg, err, cap);
}

int sdfd_catalog_transact(sdfd_catalog *c, int write, sdfd_catalog_fn fn, void *arg, char *err,
                          size_t cap)
{
    transact_args a = {fn, arg};
    return run(c, write ? BEGIN_WRITE : BEGIN_READ, transact_call, &a, err, cap);
}

/* ---- the sweeper ------------------------------------------------------------------------ */

typedef struct sweep_args {
    double grace;
    size_t deleted;
} sweep_args;

static int sweep_call(sdfd_catalog *c, PGconn *conn, void *arg, char *err, size_t cap)
{
    sweep_args *a = arg;
    size_t deleted = 0;
    int rc = sdfd_catblob_sweep(c->metrics, conn, a->grace, &deleted, err, cap);
    a->deleted += deleted; /* each delete committed on its own */
    return rc;
}

int sdfd_catalog_sweep(sdfd_catalog *c, double grace_seconds, size_t *deleted, char *err,
                       size_t cap)
{
    sweep_args a = {.grace = grace_seconds};
    int rc = run(c, NULL, sweep_call, &a, err, cap);
    if (deleted)
        *deleted = a.deleted;
    return rc;
}
