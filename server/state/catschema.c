/* catschema.c - the catalog's schema and its migration (see catschema.h).
 *
 * Version 1:
 * - sdfd_version_seq: every item version comes from this one sequence, so versions only
 *   grow, across names and kinds (a name's later write always has the larger one);
 * - sdfd_blobs (hash, size, chunks, touched): content-addressed blobs by SHA-256; `touched`
 *   is when a write last referred to the blob, which the sweeper's grace period counts from;
 * - sdfd_chunks (hash, seq, data): a blob's bytes in order, stored uncompressed out of line
 *   (meshes and EXR files gain little from pglz; the copy costs time on every read), deleted
 *   with their blob;
 * - sdfd_items (kind, name) -> version, hash, format, info, size: a row without a hash is a
 *   tombstone, left by a delete so a name's version never goes back. The foreign key from
 *   items to blobs is what makes deleting a referenced blob impossible (catalog.c's opening
 *   comment says why the sweeper's race is safe). */
#include "state/catschema.h"

#include <stdio.h>
#include <stdlib.h>

#include "core/errors.h"
#include "state/catconn.h"

/* The advisory lock migrations hold: "sdfd" in the high 32 bits, 1 in the low. */
#define MIGRATION_LOCK "8314883391715540993"

static const char *const version_1[] = {
    "CREATE SEQUENCE sdfd_version_seq",
    "CREATE TABLE sdfd_blobs ("
    " hash bytea PRIMARY KEY CHECK (octet_length(hash) = 32),"
    " size bigint NOT NULL CHECK (size >= 0),"
    " chunks integer NOT NULL CHECK (chunks >= 0),"
    " touched timestamptz NOT NULL)",
    "CREATE INDEX sdfd_blobs_touched ON sdfd_blobs (touched)",
    "CREATE TABLE sdfd_chunks ("
    " hash bytea NOT NULL REFERENCES sdfd_blobs (hash) ON DELETE CASCADE,"
    " seq integer NOT NULL CHECK (seq >= 0),"
    " data bytea NOT NULL,"
    " PRIMARY KEY (hash, seq))",
    "ALTER TABLE sdfd_chunks ALTER COLUMN data SET STORAGE EXTERNAL",
    "CREATE TABLE sdfd_items ("
    " kind text NOT NULL CHECK (kind IN ('mesh', 'volume')),"
    " name text NOT NULL,"
    " version bigint NOT NULL,"
    " hash bytea REFERENCES sdfd_blobs (hash),"
    " format text,"
    " info text,"
    " size bigint CHECK (size >= 0),"
    " updated timestamptz NOT NULL,"
    " PRIMARY KEY (kind, name),"
    " CHECK ((hash IS NULL) = (size IS NULL) AND (hash IS NULL) = (format IS NULL)))",
    "CREATE INDEX sdfd_items_hash ON sdfd_items (hash) WHERE hash IS NOT NULL",
    NULL,
};

/* Jobs (catjobs.h): one row each, the request that started it, who runs it and until when. */
static const char *const version_2[] = {
    "CREATE TABLE sdfd_jobs ("
    " id text PRIMARY KEY,"
    " kind text NOT NULL CHECK (kind IN ('bake', 'ops')),"
    " state text NOT NULL CHECK (state IN ('queued', 'running', 'done', 'failed', 'canceled')),"
    " target text NOT NULL,"
    " request bytea NOT NULL,"
    " mesh text NOT NULL, source text NOT NULL, volume text NOT NULL,"
    " has_ops boolean NOT NULL,"
    " progress double precision NOT NULL DEFAULT 0,"
    " owner text, attempts integer NOT NULL DEFAULT 0, lease_until timestamptz,"
    " cancel_requested boolean NOT NULL DEFAULT false,"
    " error integer NOT NULL DEFAULT 0, message text NOT NULL DEFAULT '',"
    " caveats integer NOT NULL DEFAULT 0, warning text NOT NULL DEFAULT '',"
    " created timestamptz NOT NULL, ended timestamptz)",
    "CREATE INDEX sdfd_jobs_queued ON sdfd_jobs (created) WHERE state = 'queued'",
    "CREATE INDEX sdfd_jobs_running ON sdfd_jobs (lease_until) WHERE state = 'running'",
    "CREATE INDEX sdfd_jobs_created ON sdfd_jobs (created)",
    NULL,
};

/* steps[v - 1] takes the schema from version v - 1 to v. */
static const char *const *const steps[SDFD_CATSCHEMA_VERSION] = {version_1, version_2};

static int run(sdfd_catalog_metrics *m, PGconn *conn, const char *sql, char *err, size_t cap)
{
    return sdfd_catconn_exec(m, conn, sql, 0, NULL, NULL, NULL, 0, NULL, err, cap);
}

/* The version the database is at (0: none yet), read under the lock. */
static int current_version(sdfd_catalog_metrics *m, PGconn *conn, int *version, char *err,
                           size_t cap)
{
    int rc = run(m, conn,
                 "CREATE TABLE IF NOT EXISTS sdfd_schema (one boolean PRIMARY KEY DEFAULT true"
                 " CHECK (one), version integer NOT NULL)", err, cap);
    PGresult *r = NULL;
    if (!rc)
        rc = sdfd_catconn_exec(m, conn, "SELECT version FROM sdfd_schema", 0, NULL, NULL, NULL,
                               0, &r, err, cap);
    if (!rc)
        *version = PQntuples(r) ? atoi(PQgetvalue(r, 0, 0)) : 0;
    PQclear(r);
    return rc;
}

static int apply_steps(sdfd_catalog_metrics *m, PGconn *conn, int from, char *err, size_t cap)
{
    for (int v = from + 1; v <= SDFD_CATSCHEMA_VERSION; v++)
        for (const char *const *sql = steps[v - 1]; *sql; sql++) {
            int rc = run(m, conn, *sql, err, cap);
            if (rc)
                return rc;
        }
    char text[16];
    snprintf(text, sizeof text, "%d", SDFD_CATSCHEMA_VERSION);
    const char *values[] = {text};
    return sdfd_catconn_exec(m, conn,
                             "INSERT INTO sdfd_schema (version) VALUES ($1::integer)"
                             " ON CONFLICT (one) DO UPDATE SET version = EXCLUDED.version",
                             1, values, NULL, NULL, 0, NULL, err, cap);
}

static int migrate_locked(sdfd_catalog_metrics *m, PGconn *conn, int *applied, char *err,
                          size_t cap)
{
    int version = 0;
    int rc = run(m, conn, "SELECT pg_advisory_xact_lock(" MIGRATION_LOCK ")", err, cap);
    if (!rc)
        rc = current_version(m, conn, &version, err, cap);
    if (rc)
        return rc;
    if (version > SDFD_CATSCHEMA_VERSION) {
        snprintf(err, cap, "the catalog's schema is at version %d, newer than this sdfd's %d:"
                 " run a newer sdfd", version, SDFD_CATSCHEMA_VERSION);
        return SDF_EFORMAT;
    }
    if (version < SDFD_CATSCHEMA_VERSION && (rc = apply_steps(m, conn, version, err, cap)))
        return rc;
    *applied = SDFD_CATSCHEMA_VERSION - version;
    return 0;
}

int sdfd_catschema_migrate(sdfd_catalog_metrics *m, PGconn *conn, int *applied, char *err,
                           size_t cap)
{
    *applied = 0;
    int rc = run(m, conn, "BEGIN", err, cap);
    if (rc)
        return rc;
    rc = migrate_locked(m, conn, applied, err, cap);
    if (!rc)
        rc = run(m, conn, "COMMIT", err, cap);
    if (rc) {
        PQclear(PQexec(conn, "ROLLBACK"));
        *applied = 0;
        return rc;
    }
    if (m)
        atomic_fetch_add(&m->migrations, (unsigned long long)*applied);
    return 0;
}
