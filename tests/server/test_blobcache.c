/* test_blobcache.c - the local copies of the catalog's blobs (server/state/blobcache.c), in a
 * temporary directory: what is put is got back byte for byte; a copy damaged on disk
 * (a byte changed, cut short, replaced by a directory) is refused, removed and counted, never
 * returned; the least recently used copies go past the bound, a get counting as a use; a
 * reopened cache knows its copies and clears a crash's temporaries; threads putting and
 * getting at once only ever get the right bytes. */
#include <dirent.h>
#include <gnutls/crypto.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../common/check.h"
#include "state/blobcache.h"

#define H SDFD_BLOBCACHE_HASH_BYTES

typedef struct blob {
    unsigned char hash[H];
    unsigned char *bytes;
    size_t n;
} blob;

static blob make_blob(unsigned seed, size_t n)
{
    blob b = {.n = n, .bytes = malloc(n)};
    for (size_t i = 0; i < n; i++)
        b.bytes[i] = (unsigned char)((seed * 2654435761u + i * 40503u) >> 7);
    gnutls_hash_fast(GNUTLS_DIG_SHA256, b.bytes, n, b.hash);
    return b;
}

static char dir[256];

static void fresh_dir(void)
{
    snprintf(dir, sizeof dir, "/tmp/sdfd-blobcache-XXXXXX");
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
}

static void remove_dir(void)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0, "rm -rf %s", dir);
}

static void copy_path(const blob *b, char *out, size_t cap)
{
    int at = snprintf(out, cap, "%s/%s/", dir, SDFD_BLOBCACHE_DIR);
    for (int i = 0; i < H; i++)
        at += snprintf(out + at, cap - (size_t)at, "%02x", b->hash[i]);
}

static int got_back(sdfd_blobcache *c, const blob *b)
{
    void *data = NULL;
    if (sdfd_blobcache_get(c, b->hash, b->n, &data))
        return 0;
    int same = !memcmp(data, b->bytes, b->n);
    free(data);
    return same ? 1 : -1;
}

static sdfd_blobcache *open_cache(uint64_t max, sdfd_catalog_metrics *m)
{
    sdfd_blobcache *c = NULL;
    char err[256] = "";
    CHECK(sdfd_blobcache_open(dir, max, m, &c, err, sizeof err) == 0, "open: %s", err);
    return c;
}

static void put(sdfd_blobcache *c, const blob *b)
{
    char err[256] = "";
    CHECK(sdfd_blobcache_put(c, b->hash, b->bytes, b->n, err, sizeof err) == 0, "put: %s", err);
}

static void test_round_trip(void)
{
    static sdfd_catalog_metrics m;
    fresh_dir();
    sdfd_blobcache *c = open_cache(0, &m);
    blob a = make_blob(1, 100000), b = make_blob(2, 1);
    CHECK(got_back(c, &a) == 0 && m.cache_misses == 1, "a miss before any put");
    put(c, &a);
    put(c, &b);
    put(c, &a); /* known: not written again */
    CHECK(m.cache_fills == 2, "fills %llu", (unsigned long long)m.cache_fills);
    CHECK(got_back(c, &a) == 1 && got_back(c, &b) == 1, "both back, whole");
    CHECK(m.cache_hits == 2 && m.cache_bytes == 100001, "hits %llu bytes %llu",
          (unsigned long long)m.cache_hits, (unsigned long long)m.cache_bytes);
    /* the wrong size asked: not a hit, and the copy is taken as damaged */
    void *data = NULL;
    CHECK(sdfd_blobcache_get(c, a.hash, a.n - 1, &data) != 0 && !data, "size checked");
    sdfd_blobcache_close(c);
    free(a.bytes), free(b.bytes);
    remove_dir();
}

static void test_damaged(void)
{
    static sdfd_catalog_metrics m;
    fresh_dir();
    sdfd_blobcache *c = open_cache(0, &m);
    blob a = make_blob(3, 5000), b = make_blob(4, 5000), d = make_blob(5, 5000);
    char path[512];
    put(c, &a), put(c, &b), put(c, &d);
    copy_path(&a, path, sizeof path); /* one byte changed */
    FILE *f = fopen(path, "r+b");
    CHECK(f && fseek(f, 2500, SEEK_SET) == 0 && fputc(a.bytes[2500] ^ 1, f) != EOF, "flip");
    if (f)
        fclose(f);
    copy_path(&b, path, sizeof path); /* cut short */
    CHECK(truncate(path, 4000) == 0, "truncate");
    copy_path(&d, path, sizeof path); /* not a file */
    CHECK(unlink(path) == 0 && mkdir(path, 0700) == 0, "a directory in its place");
    CHECK(got_back(c, &a) == 0 && got_back(c, &b) == 0 && got_back(c, &d) == 0,
          "no damaged copy is returned");
    CHECK(m.cache_damaged == 3 && m.cache_hits == 0, "damaged %llu",
          (unsigned long long)m.cache_damaged);
    struct stat st;
    copy_path(&a, path, sizeof path);
    CHECK(stat(path, &st) != 0, "the damaged copy was removed");
    CHECK(m.cache_bytes == 0, "and left the index: %llu", (unsigned long long)m.cache_bytes);
    put(c, &a); /* fetched again from the catalog, kept again */
    CHECK(got_back(c, &a) == 1, "a fresh copy is good");
    sdfd_blobcache_close(c);
    free(a.bytes), free(b.bytes), free(d.bytes);
    remove_dir();
}

static void test_eviction(void)
{
    static sdfd_catalog_metrics m;
    fresh_dir();
    sdfd_blobcache *c = open_cache(3000, &m);
    blob b[5];
    for (int i = 0; i < 5; i++)
        b[i] = make_blob(10 + (unsigned)i, 1000);
    put(c, &b[0]), put(c, &b[1]), put(c, &b[2]);
    CHECK(got_back(c, &b[0]) == 1, "0 used again: 1 is now the oldest");
    put(c, &b[3]);
    CHECK(m.cache_evictions == 1 && m.cache_bytes == 3000, "one eviction, %llu bytes",
          (unsigned long long)m.cache_bytes);
    CHECK(got_back(c, &b[1]) == 0, "1 went");
    CHECK(got_back(c, &b[0]) == 1 && got_back(c, &b[2]) == 1 && got_back(c, &b[3]) == 1,
          "the others stay");
    blob big = make_blob(99, 3001);
    put(c, &big);
    CHECK(got_back(c, &big) == 0 && m.cache_bytes == 3000, "a blob over the bound is not kept");
    sdfd_blobcache_close(c);
    for (int i = 0; i < 5; i++)
        free(b[i].bytes);
    free(big.bytes);
    remove_dir();
}

static void test_reopen(void)
{
    static sdfd_catalog_metrics m1, m2;
    fresh_dir();
    sdfd_blobcache *c = open_cache(0, &m1);
    blob b[3];
    for (int i = 0; i < 3; i++) {
        b[i] = make_blob(20 + (unsigned)i, 2000);
        put(c, &b[i]);
        usleep(20000); /* distinct modification times: their order is the use order */
    }
    sdfd_blobcache_close(c);
    char path[512];
    snprintf(path, sizeof path, "%s/%s/.tmp-abcdef", dir, SDFD_BLOBCACHE_DIR);
    FILE *f = fopen(path, "wb"); /* what a crash mid-write leaves */
    CHECK(f && fputs("partial", f) >= 0, "temporary");
    if (f)
        fclose(f);
    char other[512];
    snprintf(other, sizeof other, "%s/%s/README", dir, SDFD_BLOBCACHE_DIR);
    CHECK((f = fopen(other, "wb")) != NULL, "a file of someone else's");
    if (f)
        fclose(f);
    c = open_cache(4000, &m2); /* smaller: the oldest copy goes at once */
    struct stat st;
    CHECK(stat(path, &st) != 0, "the temporary was removed");
    CHECK(stat(other, &st) == 0, "a name that is no hash is left alone");
    CHECK(m2.cache_bytes == 4000 && m2.cache_evictions == 1, "bytes %llu evictions %llu",
          (unsigned long long)m2.cache_bytes, (unsigned long long)m2.cache_evictions);
    CHECK(got_back(c, &b[0]) == 0 && got_back(c, &b[1]) == 1 && got_back(c, &b[2]) == 1,
          "the oldest went, the newer two are back");
    sdfd_blobcache_close(c);
    for (int i = 0; i < 3; i++)
        free(b[i].bytes);
    remove_dir();
}

#define SHARED_BLOBS 12
#define THREADS 4
static blob shared[SHARED_BLOBS];
static sdfd_blobcache *shared_cache;
static _Atomic int wrong;

static void *worker(void *arg)
{
    unsigned r = (unsigned)(size_t)arg * 7919u + 1;
    for (int i = 0; i < 400; i++) {
        r = r * 1103515245u + 12345u;
        const blob *b = &shared[(r >> 8) % SHARED_BLOBS];
        char err[256];
        if ((r >> 4) & 1)
            sdfd_blobcache_put(shared_cache, b->hash, b->bytes, b->n, err, sizeof err);
        else if (got_back(shared_cache, b) < 0)
            wrong++;
    }
    return NULL;
}

static void test_threads(void)
{
    static sdfd_catalog_metrics m;
    fresh_dir();
    for (int i = 0; i < SHARED_BLOBS; i++)
        shared[i] = make_blob(40 + (unsigned)i, 3000 + 100 * (size_t)i);
    shared_cache = open_cache(4 * 3500, &m); /* about a third of them fit */
    pthread_t t[THREADS];
    for (size_t i = 0; i < THREADS; i++)
        pthread_create(&t[i], NULL, worker, (void *)i);
    for (int i = 0; i < THREADS; i++)
        pthread_join(t[i], NULL);
    CHECK(wrong == 0, "%d gets returned other bytes", (int)wrong);
    CHECK(m.cache_hits > 0 && m.cache_evictions > 0 && m.cache_damaged == 0,
          "hits %llu evictions %llu damaged %llu", (unsigned long long)m.cache_hits,
          (unsigned long long)m.cache_evictions, (unsigned long long)m.cache_damaged);
    CHECK(m.cache_bytes <= 4 * 3500, "bound kept: %llu", (unsigned long long)m.cache_bytes);
    sdfd_blobcache_close(shared_cache);
    for (int i = 0; i < SHARED_BLOBS; i++)
        free(shared[i].bytes);
    remove_dir();
}

static const check_case cases[] = {
    {"round_trip", test_round_trip}, {"damaged", test_damaged}, {"eviction", test_eviction},
    {"reopen", test_reopen},         {"threads", test_threads},
};

int main(int argc, char **argv)
{
    return check_main("server_blobcache", cases, CHECK_COUNT_OF(cases), argc, argv);
}
