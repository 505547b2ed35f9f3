/* test_catalog_blobs.c - the catalog's blobs (part of test_catalog):
 *  - one blob for two names holding the same bytes, which survives the removal of one and a
 *    sweep;
 *  - the sweeper deletes the blobs no item refers to once older than the grace period, and
 *    nothing else;
 *  - "put the same bytes on A" against "remove on B, then sweep with no grace", run many
 *    times on two threads at once: no acknowledged put ever loses its bytes. */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/check.h"
#include "catfixture.h"
#include "core/errors.h"

static long long blob_rows(const char *db, const unsigned char hash[SDFD_CATALOG_HASH_BYTES])
{
    char lit[70], sql[256];
    hash_literal(hash, lit);
    snprintf(sql, sizeof sql, "SELECT count(*) FROM sdfd_blobs WHERE hash = '%s'", lit);
    return pg_number(db, sql);
}

static int hash_of(sdfd_catalog *c, const char *name, unsigned char hash[SDFD_CATALOG_HASH_BYTES])
{
    sdfd_catalog_item item;
    char err[512] = "";
    int rc = sdfd_catalog_read(c, SDFD_ITEM_MESH, name, &item, NULL, err, sizeof err);
    CHECK(rc == 0, "read %s: %s", name, err);
    memcpy(hash, item.hash, SDFD_CATALOG_HASH_BYTES);
    free(item.info);
    return rc;
}

static uint64_t put(sdfd_catalog *c, const char *name, const void *bytes, size_t n)
{
    char err[512] = "";
    uint64_t v = 0;
    int rc = sdfd_catalog_put(c, SDFD_ITEM_MESH, name, bytes, n, "obj", NULL, &v, NULL, err,
                              sizeof err);
    CHECK(rc == 0, "put %s: %s", name, err);
    return v;
}

static size_t sweep(sdfd_catalog *c, double grace)
{
    char err[512] = "";
    size_t deleted = 0;
    int rc = sdfd_catalog_sweep(c, grace, &deleted, err, sizeof err);
    CHECK(rc == 0, "sweep: %s", err);
    return deleted;
}

/* Reads back exactly these bytes. */
static int holds(sdfd_catalog *c, const char *name, const void *bytes, size_t n)
{
    sdfd_catalog_item item;
    void *data = NULL;
    char err[512] = "";
    int rc = sdfd_catalog_read(c, SDFD_ITEM_MESH, name, &item, &data, err, sizeof err);
    int ok = rc == 0 && item.bytes == n && !memcmp(data, bytes, n);
    if (!ok)
        fprintf(stderr, "%s: %d %s\n", name, rc, err);
    free(data);
    free(item.info);
    return ok;
}

void test_blobs(sdfd_catalog *c, const char *db)
{
    unsigned char bytes[6000], ha[SDFD_CATALOG_HASH_BYTES], hb[SDFD_CATALOG_HASH_BYTES];
    fill_bytes(bytes, sizeof bytes, 7);
    put(c, "share_a", bytes, sizeof bytes);
    put(c, "share_b", bytes, sizeof bytes);
    hash_of(c, "share_a", ha);
    hash_of(c, "share_b", hb);
    CHECK(!memcmp(ha, hb, sizeof ha) && blob_rows(db, ha) == 1, "one blob for both names");
    char err[512] = "";
    uint64_t v;
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_MESH, "share_a", &v, err, sizeof err) == 0, "%s",
          err);
    sweep(c, 0);
    CHECK(blob_rows(db, ha) == 1 && holds(c, "share_b", bytes, sizeof bytes),
          "the blob survives the removal of one of its names");
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_MESH, "share_b", &v, err, sizeof err) == 0, "%s",
          err);
    CHECK(sweep(c, 0) >= 1 && blob_rows(db, ha) == 0, "and goes with the last");
    char lit[70], sql[256];
    hash_literal(ha, lit);
    snprintf(sql, sizeof sql, "SELECT count(*) FROM sdfd_chunks WHERE hash = '%s'", lit);
    CHECK(pg_number(db, sql) == 0, "with its chunks");
}

void test_sweeper(sdfd_catalog *c, const char *db)
{
    unsigned char p1[5000], p2[5000], p3[5000];
    unsigned char h1[SDFD_CATALOG_HASH_BYTES], h2[SDFD_CATALOG_HASH_BYTES];
    unsigned char h3[SDFD_CATALOG_HASH_BYTES];
    fill_bytes(p1, sizeof p1, 11), fill_bytes(p2, sizeof p2, 12), fill_bytes(p3, sizeof p3, 13);
    sweep(c, 0); /* what earlier tests left unreferenced */
    put(c, "sw_x", p1, sizeof p1);
    hash_of(c, "sw_x", h1);
    put(c, "sw_x", p2, sizeof p2); /* p1 is unreferenced from now */
    hash_of(c, "sw_x", h2);
    CHECK(sweep(c, 3600) == 0, "nothing is an hour old");
    usleep(1500000);
    put(c, "sw_y", p3, sizeof p3);
    hash_of(c, "sw_y", h3);
    char err[512] = "";
    uint64_t v;
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_MESH, "sw_y", &v, err, sizeof err) == 0, "%s", err);
    /* p1: unreferenced for 1.5 s; p3: unreferenced just now; p2: referenced. */
    size_t deleted = sweep(c, 1.0);
    CHECK(deleted == 1 && blob_rows(db, h1) == 0, "deleted %zu; p1's blob %lld rows", deleted,
          blob_rows(db, h1));
    CHECK(blob_rows(db, h2) == 1 && holds(c, "sw_x", p2, sizeof p2), "a referenced blob stays");
    CHECK(blob_rows(db, h3) == 1, "an unreferenced blob within its grace stays");
    /* A write of the same bytes touches the blob: its grace starts again. */
    usleep(1100000);
    put(c, "sw_z", p3, sizeof p3);
    CHECK(sdfd_catalog_remove(c, SDFD_ITEM_MESH, "sw_z", &v, err, sizeof err) == 0, "%s", err);
    CHECK(sweep(c, 1.0) == 0 && blob_rows(db, h3) == 1, "touched by a write, kept");
    CHECK(sweep(c, 0) == 1 && blob_rows(db, h3) == 0, "no grace: deleted");
}

/* ---- the race --------------------------------------------------------------------------- */

enum { ROUNDS = 200, RACE_BYTES = 10000 };

typedef struct race {
    sdfd_catalog *c;
    pthread_barrier_t start;
    const unsigned char *bytes;
    const char *put_name, *remove_name;
    uint64_t put_version, remove_version;
    int put_rc, remove_rc;
    size_t swept;
    double put_start, put_end, remove_start, sweep_end;
} race;

static void *race_put(void *arg)
{
    race *r = arg;
    char err[512] = "";
    pthread_barrier_wait(&r->start);
    r->put_start = now_seconds();
    r->put_rc = sdfd_catalog_put(r->c, SDFD_ITEM_MESH, r->put_name, r->bytes, RACE_BYTES, "obj",
                                 NULL, &r->put_version, NULL, err, sizeof err);
    r->put_end = now_seconds();
    return NULL;
}

static void *race_remove_sweep(void *arg)
{
    race *r = arg;
    char err[512] = "";
    pthread_barrier_wait(&r->start);
    r->remove_start = now_seconds();
    r->remove_rc = sdfd_catalog_remove(r->c, SDFD_ITEM_MESH, r->remove_name, &r->remove_version,
                                       err, sizeof err);
    r->swept = 0;
    CHECK(sdfd_catalog_sweep(r->c, 0, &r->swept, err, sizeof err) == 0, "sweep: %s", err);
    r->sweep_end = now_seconds();
    return NULL;
}

static void run_round(race *r)
{
    pthread_t a, b;
    pthread_barrier_init(&r->start, NULL, 2);
    pthread_create(&a, NULL, race_put, r);
    pthread_create(&b, NULL, race_remove_sweep, r);
    pthread_join(a, NULL);
    pthread_join(b, NULL);
    pthread_barrier_destroy(&r->start);
}

/* Each round uses new bytes, held at first by the name that is removed. Two forms: the put
 * names another item (the blob loses its last reference while a put takes it up), and the
 * put and the remove name the same item (the later commit decides what it holds). */
void test_put_delete_sweep_race(sdfd_catalog *c)
{
    unsigned char *bytes = malloc(RACE_BYTES);
    int lost = 0, overlapped = 0, put_last = 0;
    double t0 = now_seconds();
    for (int round = 0; round < ROUNDS; round++) {
        int same = round % 2;
        fill_bytes(bytes, RACE_BYTES, 1000 + (uint64_t)round);
        race r = {.c = c, .bytes = bytes, .put_name = same ? "race_n" : "race_a",
                  .remove_name = same ? "race_n" : "race_b"};
        put(c, r.remove_name, bytes, RACE_BYTES);
        run_round(&r);
        CHECK(r.put_rc == 0, "round %d: put %d", round, r.put_rc);
        CHECK(r.remove_rc == 0 || (same && r.remove_rc == SDF_ENOTFOUND), "round %d: remove %d",
              round, r.remove_rc);
        overlapped += r.put_start < r.sweep_end && r.remove_start < r.put_end;
        int put_won = !same || r.remove_rc != 0 || r.put_version > r.remove_version;
        put_last += same && put_won;
        if (r.put_rc == 0 && put_won && !holds(c, r.put_name, bytes, RACE_BYTES)) {
            lost++;
            CHECK(0, "round %d: the acknowledged put of %s lost its bytes", round, r.put_name);
        }
        sdfd_catalog_item item;
        char err[512] = "";
        if (same && !put_won)
            CHECK(sdfd_catalog_read(c, SDFD_ITEM_MESH, "race_n", &item, NULL, err, sizeof err) ==
                  SDF_ENOTFOUND, "round %d: the remove committed last", round);
    }
    printf("put vs remove+sweep: %d rounds in %.1f s, the two overlapped in time in %d, %d"
           " acknowledged puts lost; same name: the put committed last in %d of %d\n", ROUNDS,
           now_seconds() - t0, overlapped, lost, put_last, ROUNDS / 2);
    CHECK(overlapped >= ROUNDS / 4, "only %d rounds raced", overlapped);
    free(bytes);
}
