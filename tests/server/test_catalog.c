/* test_catalog.c - server/state/catalog.c and its modules against a real PostgreSQL, which
 * run_catalog.py starts (tests/server/pgserver.py) and can stop, start and kill on request:
 *  - the schema: opening twice migrates once; four processes opening a fresh database at
 *    once migrate once between them; a schema newer than ours is refused; a bad string is
 *    refused with a message; TLS through sslmode, the server's certificate verified against
 *    the CA that signed it and refused against another;
 *  - items: put and read round trips (bytes, SHA-256 as PostgreSQL computes it, format,
 *    info), arguments refused, limits, damage found on read;
 *  - versions only grow; remove leaves a tombstone; the version list;
 *  - two threads writing one name: the write committed last (the largest version) is what
 *    the name holds;
 * and in test_catalog_blobs.c and test_catalog_listen.c: shared blobs, the sweeper, the
 * put-versus-delete-and-sweep race, the listener, and PostgreSQL going away and coming back. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "../common/check.h"
#include "catfixture.h"
#include "core/errors.h"
#include "state/catblob.h"
#include "state/catschema.h"

static sdfd_catalog *open_db(const char *db, const sdfd_catalog_options *opt)
{
    char err[512] = "";
    sdfd_catalog *c = NULL;
    int rc = sdfd_catalog_open(pg_uri(db), opt, &c, err, sizeof err);
    CHECK(rc == 0 && c, "open %s: %d %s", db, rc, err);
    return c;
}

/* ---- the schema ------------------------------------------------------------------------- */

static void test_migrate_twice(void)
{
    CHECK(pg_create_db("mig_twice") == 0, "create database");
    sdfd_catalog_metrics m1 = {0}, m2 = {0};
    sdfd_catalog_options opt = {.metrics = &m1};
    sdfd_catalog_close(open_db("mig_twice", &opt));
    CHECK(atomic_load(&m1.migrations) == SDFD_CATSCHEMA_VERSION, "first open applied %llu",
          (unsigned long long)atomic_load(&m1.migrations));
    /* The second open, by a key=value string this time, finds the schema current. */
    char conninfo[256], err[512] = "";
    snprintf(conninfo, sizeof conninfo, "host=127.0.0.1 port=%s user=postgres dbname=mig_twice",
             pg_port());
    opt.metrics = &m2;
    sdfd_catalog *c = NULL;
    int rc = sdfd_catalog_open(conninfo, &opt, &c, err, sizeof err);
    CHECK(rc == 0, "open by key=value: %s", err);
    CHECK(atomic_load(&m2.migrations) == 0, "second open applied %llu",
          (unsigned long long)atomic_load(&m2.migrations));
    CHECK(atomic_load(&m2.connects) >= 1 && atomic_load(&m2.round_trips) >= 3,
          "the metrics count connections and round trips");
    sdfd_catalog_close(c);
    CHECK(pg_number("mig_twice", "SELECT version FROM sdfd_schema") == SDFD_CATSCHEMA_VERSION,
          "schema version recorded");
}

/* A child: wait at the gate, open, exit with the steps it applied (10+: failed). */
static void migrate_child(int gate)
{
    char b;
    while (read(gate, &b, 1) > 0)
        ;
    sdfd_catalog_metrics m = {0};
    sdfd_catalog_options opt = {.metrics = &m};
    sdfd_catalog *c = NULL;
    char err[512] = "";
    int rc = sdfd_catalog_open(pg_uri("mig_race"), &opt, &c, err, sizeof err);
    if (rc)
        fprintf(stderr, "child open: %s\n", err);
    sdfd_catalog_close(c);
    _exit(rc ? 10 : (int)atomic_load(&m.migrations));
}

static void test_migrate_concurrently(void)
{
    enum { CHILDREN = 4 };
    CHECK(pg_create_db("mig_race") == 0, "create database");
    int gate[2];
    CHECK(pipe(gate) == 0, "pipe");
    pid_t pids[CHILDREN];
    for (int i = 0; i < CHILDREN; i++)
        if ((pids[i] = fork()) == 0) {
            close(gate[1]);
            migrate_child(gate[0]);
        }
    close(gate[0]);
    usleep(100000);
    close(gate[1]); /* all children start at once */
    int applied = 0, failed = 0;
    for (int i = 0; i < CHILDREN; i++) {
        int status = 0;
        waitpid(pids[i], &status, 0);
        int code = WIFEXITED(status) ? WEXITSTATUS(status) : 99;
        failed += code >= 10;
        applied += code < 10 ? code : 0;
    }
    CHECK(failed == 0, "%d of %d concurrent opens failed", failed, CHILDREN);
    CHECK(applied == SDFD_CATSCHEMA_VERSION, "%d processes applied %d steps in all, not %d",
          CHILDREN, applied, SDFD_CATSCHEMA_VERSION);
    CHECK(pg_number("mig_race", "SELECT count(*) FROM sdfd_schema") == 1, "one version row");
}

static void test_open_refusals(void)
{
    char err[512] = "";
    sdfd_catalog *c = NULL;
    int rc = sdfd_catalog_open("postgresql://[bad", NULL, &c, err, sizeof err);
    CHECK(rc == SDF_EINVAL && !c && strstr(err, "connection string"), "bad URI: %d %s", rc,
          err);
    /* TLS through the string: the server's certificate verified against the CA that signed
     * it, and refused against another. */
    char tls[1024];
    snprintf(tls, sizeof tls, "%s?sslmode=verify-full&sslrootcert=%s", pg_uri("mig_twice"),
             getenv("SDFD_TEST_PG_CA") ? getenv("SDFD_TEST_PG_CA") : "");
    rc = sdfd_catalog_open(tls, NULL, &c, err, sizeof err);
    CHECK(rc == 0, "sslmode=verify-full: %d %s", rc, err);
    CHECK(pg_number("postgres", "SELECT count(*) FROM pg_stat_ssl s JOIN pg_stat_activity a"
                                " USING (pid) WHERE s.ssl AND a.application_name = 'sdfd'") == 1,
          "the catalog's connection is encrypted");
    sdfd_catalog_close(c);
    snprintf(tls, sizeof tls, "%s?sslmode=verify-full&sslrootcert=%s", pg_uri("mig_twice"),
             getenv("SDFD_TEST_PG_OTHER_CA") ? getenv("SDFD_TEST_PG_OTHER_CA") : "");
    c = NULL;
    rc = sdfd_catalog_open(tls, NULL, &c, err, sizeof err);
    CHECK(rc == SDFD_EUNAVAILABLE && !c && strstr(err, "certificate"),
          "a certificate from another CA: %d %s", rc, err);
    printf("another CA: %s\n", err);
    CHECK(pg_create_db("mig_newer") == 0, "create database");
    sdfd_catalog_close(open_db("mig_newer", NULL));
    free(pg_value("mig_newer", "UPDATE sdfd_schema SET version = 99"));
    rc = sdfd_catalog_open(pg_uri("mig_newer"), NULL, &c, err, sizeof err);
    CHECK(rc == SDF_EFORMAT && strstr(err, "99"), "newer schema: %d %s", rc, err);
}

/* ---- items ------------------------------------------------------------------------------ */

/* The SHA-256 PostgreSQL computes over the stored chunks, as hex. */
static char *stored_sha256(const char *db, const unsigned char hash[SDFD_CATALOG_HASH_BYTES])
{
    char lit[70], sql[512];
    hash_literal(hash, lit);
    snprintf(sql, sizeof sql, "SELECT encode(sha256(coalesce(string_agg(data, ''::bytea ORDER BY"
             " seq), ''::bytea)), 'hex') FROM sdfd_chunks WHERE hash = '%s'", lit);
    return pg_value(db, sql);
}

static void check_read(sdfd_catalog *c, const char *db, sdfd_item_kind kind, const char *name,
                       const void *bytes, size_t n, uint64_t version, const char *info)
{
    sdfd_catalog_item item;
    void *data = NULL;
    char err[512] = "", hex[65];
    int rc = sdfd_catalog_read(c, kind, name, &item, &data, err, sizeof err);
    CHECK(rc == 0, "read %s: %d %s", name, rc, err);
    if (rc)
        return;
    CHECK(item.version == version, "%s: version %llu, put %llu", name,
          (unsigned long long)item.version, (unsigned long long)version);
    CHECK(item.bytes == n && !memcmp(data, bytes, n), "%s: %zu bytes back, %zu put", name,
          item.bytes, n);
    CHECK(!strcmp(item.format, "obj"), "%s: format %s", name, item.format);
    CHECK(info ? item.info && !strcmp(item.info, info) : !item.info, "%s: info %s", name,
          item.info ? item.info : "(null)");
    for (int i = 0; i < SDFD_CATALOG_HASH_BYTES; i++)
        snprintf(hex + 2 * i, 3, "%02x", item.hash[i]);
    char *pg = stored_sha256(db, item.hash);
    CHECK(pg && !strcmp(pg, hex), "%s: hash %s, PostgreSQL's SHA-256 of the chunks %s", name,
          hex, pg ? pg : "?");
    free(pg);
    free(item.info);
    free(data);
}

static void test_round_trip(sdfd_catalog *c, const char *db)
{
    enum { N = 10000 }; /* three chunks of 4096 */
    unsigned char *bytes = malloc(N);
    fill_bytes(bytes, N, 1);
    const char *info = "{\"triangles\":12,\"note\":\"caf\\u00e9\"}";
    uint64_t v1 = 0, v2 = 0, v3 = 0;
    int replaced = -1;
    char err[512] = "";
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "rt", bytes, N, "obj", info, &v1, &replaced, err,
                           sizeof err) == 0 && replaced == 0, "put: %s", err);
    check_read(c, db, SDFD_ITEM_MESH, "rt", bytes, N, v1, info);
    CHECK(pg_number(db, "SELECT count(*) FROM sdfd_chunks c JOIN sdfd_items i USING (hash)"
                        " WHERE i.name = 'rt'") == 3, "10000 bytes in 3 chunks");
    /* A volume of the same name is another item; an empty item and no info are allowed. */
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_VOLUME, "rt", "", 0, "obj", NULL, &v2, &replaced, err,
                           sizeof err) == 0 && replaced == 0 && v2 > v1, "put volume: %s", err);
    check_read(c, db, SDFD_ITEM_VOLUME, "rt", "", 0, v2, NULL);
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "rt", "abc", 3, "obj", NULL, &v3, &replaced, err,
                           sizeof err) == 0 && replaced == 1 && v3 > v2, "replace: %s", err);
    check_read(c, db, SDFD_ITEM_MESH, "rt", "abc", 3, v3, NULL);
    /* Metadata alone, then the blob by its hash; SHA-256("abc") is FIPS 180-2's example. */
    sdfd_catalog_item item;
    void *data = NULL;
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "rt", &item, NULL, err, sizeof err) == 0 &&
          item.bytes == 3 && item.hash[0] == 0xba && item.hash[1] == 0x78 &&
          item.hash[31] == 0xad, "metadata read: %s", err);
    CHECK(sdfd_catalog_read_blob(c, item.hash, 3, &data, err, sizeof err) == 0 && data &&
          !memcmp(data, "abc", 3), "blob read: %s", err);
    free(data);
    free(bytes);
}

static void test_refusals(sdfd_catalog *c)
{
    char err[512] = "";
    uint64_t v;
    sdfd_catalog_item item;
    static const char *const names[] = {"", ".hidden", "a/b", "a b", "caf\xc3\xa9"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, names[i], "x", 1, "obj", NULL, &v, NULL, err,
                               sizeof err) == SDF_EINVAL, "name '%s' accepted", names[i]);
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "ok", "x", 1, "OBJ", NULL, &v, NULL, err,
                           sizeof err) == SDF_EINVAL && strstr(err, "format"), "format: %s",
          err);
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "ok", "x", 1, "", NULL, &v, NULL, err,
                           sizeof err) == SDF_EINVAL, "empty format");
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "never", &item, NULL, err, sizeof err) ==
          SDF_ENOTFOUND && strstr(err, "never"), "read of a missing name: %s", err);
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_VOLUME, "never", &v, err, sizeof err) ==
          SDF_ENOTFOUND, "remove of a missing name");
}

/* A small max_blob_bytes refuses larger puts, and larger items on read, before reading. */
static void test_limits(sdfd_catalog *c, const char *db)
{
    char err[512] = "";
    uint64_t v;
    unsigned char big[2000];
    fill_bytes(big, sizeof big, 2);
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "big", big, sizeof big, "obj", NULL, &v, NULL,
                           err, sizeof err) == 0, "put: %s", err);
    sdfd_catalog_options opt = {.max_blob_bytes = 1000};
    sdfd_catalog *small = open_db(db, &opt);
    sdfd_catalog_item item;
    void *data = NULL;
    CHECK(sdfd_catalog_put(small, SDFD_ITEM_MESH, "big2", big, sizeof big, "obj", NULL, &v,
                           NULL, err, sizeof err) == SDF_ELIMIT, "put past the limit");
    CHECK(sdfd_catalog_read(small, SDFD_ITEM_MESH, "big", &item, &data, err, sizeof err) ==
          SDF_ELIMIT && !data, "read past the limit: %s", err);
    sdfd_catalog_close(small);
    char *info = malloc(SDFD_CATALOG_MAX_INFO + 2);
    memset(info, ' ', SDFD_CATALOG_MAX_INFO + 1);
    info[SDFD_CATALOG_MAX_INFO + 1] = '\0';
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "big", "x", 1, "obj", info, &v, NULL, err,
                           sizeof err) == SDF_ELIMIT, "info past the limit");
    free(info);
}

/* Chunks changed, missing or reordered behind the catalog's back are found on read. */
static void test_damage(sdfd_catalog *c, const char *db)
{
    static const char *const damage[] = {
        "UPDATE sdfd_chunks SET data = overlay(data placing '\\x00'::bytea from 5) WHERE"
        " hash = (SELECT hash FROM sdfd_items WHERE name = 'hurt') AND seq = 1",
        "DELETE FROM sdfd_chunks WHERE hash = (SELECT hash FROM sdfd_items WHERE name ="
        " 'hurt') AND seq = 2",
        "UPDATE sdfd_chunks SET seq = seq + 10 WHERE hash = (SELECT hash FROM sdfd_items WHERE"
        " name = 'hurt') AND seq = 0",
        "UPDATE sdfd_chunks SET data = data || '\\x00'::bytea WHERE hash = (SELECT hash FROM"
        " sdfd_items WHERE name = 'hurt') AND seq = 2",
    };
    for (size_t i = 0; i < sizeof damage / sizeof *damage; i++) {
        unsigned char bytes[9000];
        fill_bytes(bytes, sizeof bytes, 100 + i);
        char err[512] = "";
        uint64_t v;
        CHECK(sdfd_catalog_put(c, SDFD_ITEM_MESH, "hurt", bytes, sizeof bytes, "obj", NULL, &v,
                               NULL, err, sizeof err) == 0, "put: %s", err);
        free(pg_value(db, damage[i]));
        sdfd_catalog_item item;
        void *data = NULL;
        int rc = sdfd_catalog_read(c, SDFD_ITEM_MESH, "hurt", &item, &data, err, sizeof err);
        CHECK(rc == SDF_EFORMAT && !data && strstr(err, "blob"), "damage %zu read: %d %s", i,
              rc, err);
        printf("damage %zu: %s\n", i, err);
    }
}

/* ---- versions --------------------------------------------------------------------------- */

static void test_versions(sdfd_catalog *c, const char *db)
{
    char err[512] = "";
    uint64_t last = 0, v = 0;
    for (int i = 0; i < 30; i++) {
        char name[16];
        snprintf(name, sizeof name, "v%d", i % 3);
        int rc = i % 5 == 4 ? sdfd_catalog_remove(c, SDFD_ITEM_VOLUME, name, &v, err, sizeof err)
                            : sdfd_catalog_put(c, SDFD_ITEM_VOLUME, name, name, 2, "exr", NULL,
                                               &v, NULL, err, sizeof err);
        CHECK(rc == 0 && v > last, "change %d: %d, version %llu after %llu (%s)", i, rc,
              (unsigned long long)v, (unsigned long long)last, err);
        last = v;
    }
    /* Tombstone: a remove's version stays in the row, without bytes; reads say not found. */
    uint64_t vp = 0, vd = 0, va = 0;
    sdfd_catalog_item item;
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_VOLUME, "gone", "x", 1, "exr", NULL, &vp, NULL, err,
                           sizeof err) == 0, "put");
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_VOLUME, "gone", &vd, err, sizeof err) == 0 && vd > vp,
          "remove");
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_VOLUME, "gone", &item, NULL, err, sizeof err) ==
          SDF_ENOTFOUND, "read after remove");
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_VOLUME, "gone", &v, err, sizeof err) == SDF_ENOTFOUND,
          "second remove");
    CHECK(pg_number(db, "SELECT version FROM sdfd_items WHERE kind = 'volume' AND name = 'gone'"
                        " AND hash IS NULL AND size IS NULL") == (long long)vd, "tombstone row");
    sdfd_catalog_version *list = NULL;
    size_t n = 0;
    CHECK(sdfd_catalog_versions(c, SDFD_ITEM_VOLUME, &list, &n, err, sizeof err) == 0, "%s", err);
    long long all = pg_number(db, "SELECT count(*) FROM sdfd_items WHERE kind = 'volume'"),
              live = pg_number(db, "SELECT count(*) FROM sdfd_items WHERE kind = 'volume' AND"
                                   " hash IS NOT NULL");
    size_t listed_live = 0;
    CHECK((long long)n == all && n >= 2, "versions lists %zu of %lld", n, all);
    for (size_t i = 0; i < n; i++) {
        char sql[400], dead[400];
        snprintf(sql, sizeof sql, "SELECT version FROM sdfd_items WHERE kind = 'volume' AND"
                 " name = '%s'", list[i].name);
        snprintf(dead, sizeof dead, "SELECT count(*) FROM sdfd_items WHERE kind = 'volume' AND"
                 " name = '%s' AND hash IS NULL", list[i].name);
        listed_live += !list[i].deleted;
        CHECK(pg_number(db, sql) == (long long)list[i].version &&
                  list[i].deleted == pg_number(db, dead) &&
                  (strcmp(list[i].name, "gone") || list[i].deleted),
              "versions: %s %llu deleted %d", list[i].name, (unsigned long long)list[i].version,
              list[i].deleted);
        CHECK(i == 0 || strcmp(list[i - 1].name, list[i].name) < 0, "sorted");
    }
    CHECK((long long)listed_live == live, "%zu live listed, %lld live", listed_live, live);
    free(list);
    CHECK(sdfd_catalog_put(c, SDFD_ITEM_VOLUME, "gone", "y", 1, "exr", NULL, &va, NULL, err,
                           sizeof err) == 0 && va > vd, "put after the tombstone");
}

/* ---- two writers of one name ------------------------------------------------------------ */

enum { WRITES = 40 };
typedef struct writer {
    sdfd_catalog *c;
    int id;
    uint64_t versions[WRITES];
} writer;

static void *write_loop(void *arg)
{
    writer *w = arg;
    for (int i = 0; i < WRITES; i++) {
        char bytes[64], err[512] = "";
        snprintf(bytes, sizeof bytes, "writer %d write %d", w->id, i);
        int rc = sdfd_catalog_put(w->c, SDFD_ITEM_MESH, "contended", bytes, strlen(bytes),
                                  "obj", NULL, &w->versions[i], NULL, err, sizeof err);
        CHECK(rc == 0, "writer %d: %s", w->id, err);
    }
    return NULL;
}

static void test_last_writer_wins(sdfd_catalog *c)
{
    writer w[2] = {{.c = c, .id = 0}, {.c = c, .id = 1}};
    pthread_t t[2];
    for (int i = 0; i < 2; i++)
        pthread_create(&t[i], NULL, write_loop, &w[i]);
    for (int i = 0; i < 2; i++)
        pthread_join(t[i], NULL);
    uint64_t top = 0;
    int top_writer = -1, top_write = -1, repeated = 0;
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < WRITES; j++) {
            if (w[i].versions[j] > top)
                top = w[i].versions[j], top_writer = i, top_write = j;
            repeated += w[1 - i].versions[j] == w[i].versions[j];
        }
    CHECK(repeated == 0, "two writes got one version");
    char expect[64], err[512] = "";
    snprintf(expect, sizeof expect, "writer %d write %d", top_writer, top_write);
    sdfd_catalog_item item;
    void *data = NULL;
    CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "contended", &item, &data, err, sizeof err) == 0,
          "%s", err);
    CHECK(item.version == top && item.bytes == strlen(expect) && data &&
          !memcmp(data, expect, item.bytes), "the name holds version %llu, the largest"
          " acknowledged is %llu (%s)", (unsigned long long)item.version,
          (unsigned long long)top, expect);
    free(data);
    free(item.info);
}

/* ---- the cases --------------------------------------------------------------------------- */

/* The cases after the schema's share one database and one handle, opened by the first of
 * them that runs (each can also run alone: `test_catalog NAME`). */
static const char *const db = "items";
static sdfd_catalog_metrics metrics;
static sdfd_catalog *items;

static sdfd_catalog *shared(void)
{
    static int tried;
    if (!tried) {
        tried = 1;
        CHECK(pg_create_db(db) == 0, "create database");
        static sdfd_catalog_options opt = {.chunk_bytes = 4096, .metrics = &metrics};
        items = open_db(db, &opt);
    }
    CHECK(items != NULL, "the shared catalog is open");
    return items;
}

#define ON_SHARED(name, call)                                                                \
    static void name(void)                                                                   \
    {                                                                                        \
        sdfd_catalog *c = shared();                                                          \
        if (c)                                                                               \
            call;                                                                            \
    }
ON_SHARED(round_trip, test_round_trip(c, db))
ON_SHARED(refusals, test_refusals(c))
ON_SHARED(limits, test_limits(c, db))
ON_SHARED(damage, test_damage(c, db))
ON_SHARED(versions, test_versions(c, db))
ON_SHARED(last_writer_wins, test_last_writer_wins(c))
ON_SHARED(blobs, test_blobs(c, db))
ON_SHARED(sweeper, test_sweeper(c, db))
ON_SHARED(put_delete_sweep_race, test_put_delete_sweep_race(c))
ON_SHARED(listener, test_listener(c))
ON_SHARED(outage, test_outage(c, db))

int main(int argc, char **argv)
{
    setvbuf(stdout, NULL, _IOLBF, 0);
    /* migrate_concurrently forks: it comes first, before any case has started a thread */
    static const check_case cases[] = {
        {"migrate_concurrently", test_migrate_concurrently},
        {"migrate_twice", test_migrate_twice},
        {"open_refusals", test_open_refusals},
        {"round_trip", round_trip},
        {"refusals", refusals},
        {"limits", limits},
        {"damage", damage},
        {"versions", versions},
        {"last_writer_wins", last_writer_wins},
        {"blobs", blobs},
        {"sweeper", sweeper},
        {"put_delete_sweep_race", put_delete_sweep_race},
        {"listener", listener},
        {"outage", outage},
    };
    int rc = check_main("test_catalog", cases, CHECK_COUNT_OF(cases), argc, argv);
    unsigned long long trips = atomic_load(&metrics.round_trips);
    printf("round trips: %llu, %.3f ms mean\n", trips,
           (double)atomic_load(&metrics.round_trip_ns) / 1e6 / (double)(trips ? trips : 1));
    sdfd_catalog_close(items);
    return rc;
}
