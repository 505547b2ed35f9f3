/* backcat.c - the catalog behind backing.h's calls (backcat.h): a table of the versions the
 * catalog announced, the listener that keeps it current, and a thread that takes the full
 * lists (after each reconnection, and as a backstop) so that the listener's thread never
 * waits for one. Updates to the table keep the largest version of each name, so the order in
 * which notifications, lists, writes and reads report versions does not matter. */
#include "state/backcat.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/catalog.h"
#include "state/blobcache.h"
#include "state/catblob.h"
#include "state/catconn.h"
#include "state/catlisten.h"

#define BACKOFF_FIRST 0.1
#define BACKOFF_MAX 5.0

typedef struct known {
    struct known *next;
    sdfd_item_kind kind;
    uint64_t version;
    int deleted;
    char name[];
} known;

typedef struct backcat {
    char *conninfo;
    sdfd_catalog_metrics *m;
    sdfd_blobcache *blobs; /* local copies of blobs, or NULL */
    sdfd_catalog *cat;
    sdfd_catlisten *listen;
    sdfd_backing_changed changed;
    void *changed_arg;
    pthread_mutex_t lock; /* guards what follows */
    pthread_cond_t wake;  /* the sync thread: a list is wanted, or stop */
    pthread_cond_t synced_cond;
    known **buckets;
    size_t nbuckets, count;
    unsigned long long wanted, synced; /* listener (re)connections, and the last listed */
    int stopping, started;
    pthread_t sync_thread;
} backcat;

/* ---- the table ------------------------------------------------------------------------- */

static size_t bucket_of(const backcat *b, sdfd_item_kind kind, const char *name)
{
    uint64_t h = 1469598103934665603ull ^ (uint64_t)kind;
    for (const unsigned char *p = (const unsigned char *)name; *p; p++)
        h = (h ^ *p) * 1099511628211ull;
    return (size_t)(h % b->nbuckets);
}

/* Under the lock. */
static known *find(backcat *b, sdfd_item_kind kind, const char *name)
{
    for (known *k = b->buckets[bucket_of(b, kind, name)]; k; k = k->next)
        if (k->kind == kind && !strcmp(k->name, name))
            return k;
    return NULL;
}

/* Under the lock: twice the buckets once the table holds twice as many names. */
static void grow(backcat *b)
{
    size_t n = b->nbuckets * 2;
    known **nb = calloc(n, sizeof *nb);
    if (!nb)
        return; /* longer chains, still correct */
    known **old = b->buckets;
    size_t on = b->nbuckets;
    b->buckets = nb, b->nbuckets = n;
    for (size_t i = 0; i < on; i++)
        for (known *k = old[i], *next; k; k = next) {
            next = k->next;
            size_t j = bucket_of(b, k->kind, k->name);
            k->next = nb[j], nb[j] = k;
        }
    free(old);
}

/* Record (kind, name) at version (deleted or not) unless a later version is known; tell the
 * cache when it changed what a lookup would see. */
static void learn(backcat *b, sdfd_item_kind kind, const char *name, uint64_t version,
                  int deleted)
{
    pthread_mutex_lock(&b->lock);
    known *k = find(b, kind, name);
    int news = 0;
    if (!k && (k = calloc(1, sizeof *k + strlen(name) + 1))) {
        size_t i = bucket_of(b, kind, name);
        k->kind = kind, strcpy(k->name, name);
        k->next = b->buckets[i], b->buckets[i] = k;
        if (++b->count > 2 * b->nbuckets)
            grow(b);
    }
    if (k && (version > k->version || !k->version)) {
        news = k->version != 0;
        k->version = version, k->deleted = deleted;
    }
    pthread_mutex_unlock(&b->lock);
    if (news && b->changed)
        b->changed(b->changed_arg, kind, name);
}

/* ---- lists ------------------------------------------------------------------------------ */

/* Take both kinds' lists into the table: 0 or an error (logged). */
static int resync(backcat *b)
{
    for (int kind = SDFD_ITEM_MESH; kind <= SDFD_ITEM_VOLUME; kind++) {
        sdfd_catalog_version *list;
        size_t n;
        char err[512];
        int rc = sdfd_catalog_versions(b->cat, kind, &list, &n, err, sizeof err);
        if (rc) {
            sdfd_log("warn", "catalog_resync", "listing the catalog's %ss: %s",
                     sdfd_catalog_kind_name(kind), err);
            return rc;
        }
        for (size_t i = 0; i < n; i++)
            learn(b, kind, list[i].name, list[i].version, list[i].deleted);
        free(list);
    }
    return 0;
}

static void wait_seconds(backcat *b, double seconds)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    double t = ts.tv_sec + ts.tv_nsec * 1e-9 + seconds;
    ts.tv_sec = (time_t)t, ts.tv_nsec = (long)((t - (double)ts.tv_sec) * 1e9);
    pthread_cond_timedwait(&b->wake, &b->lock, &ts);
}

/* The sync thread: a list after each LISTEN, retried with backoff until one is read, and one
 * every SDFD_BACKCAT_RESYNC_SECONDS. */
static void *sync_main(void *arg)
{
    backcat *b = arg;
    double backoff = BACKOFF_FIRST;
    pthread_mutex_lock(&b->lock);
    while (!b->stopping) {
        unsigned long long want = b->wanted;
        pthread_mutex_unlock(&b->lock);
        int rc = want ? resync(b) : -1;
        pthread_mutex_lock(&b->lock);
        if (!rc) {
            b->synced = want, backoff = BACKOFF_FIRST;
            pthread_cond_broadcast(&b->synced_cond);
        }
        if (b->stopping)
            break;
        if (b->wanted == want) /* nothing new asked meanwhile */
            wait_seconds(b, rc ? backoff : SDFD_BACKCAT_RESYNC_SECONDS);
        if (rc)
            backoff = backoff * 2 < BACKOFF_MAX ? backoff * 2 : BACKOFF_MAX;
    }
    pthread_mutex_unlock(&b->lock);
    return NULL;
}

/* ---- the listener's callbacks ----------------------------------------------------------- */

static void on_change(void *arg, sdfd_item_kind kind, const char *name, uint64_t version,
                      int deleted)
{
    learn(arg, kind, name, version, deleted);
}

/* LISTEN is in place again: the table is not trusted until a list taken after it is read. */
static void on_resync(void *arg)
{
    backcat *b = arg;
    pthread_mutex_lock(&b->lock);
    b->wanted = atomic_load(&b->m->resyncs);
    pthread_cond_signal(&b->wake);
    pthread_mutex_unlock(&b->lock);
}

/* Under the lock: may stat answer from the table? */
static int trusted(backcat *b)
{
    return atomic_load(&b->m->listening) && b->synced &&
           b->synced == atomic_load(&b->m->resyncs);
}

/* ---- the backing's calls ---------------------------------------------------------------- */

static void sleep_seconds(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Connect and migrate, retrying while PostgreSQL cannot be reached. */
static int open_catalog(backcat *b, char *err, size_t cap)
{
    double backoff = BACKOFF_FIRST;
    int failing = 0;
    sdfd_catalog_options o = {.metrics = b->m};
    int rc;
    while ((rc = sdfd_catalog_open(b->conninfo, &o, &b->cat, err, cap)) == SDFD_EUNAVAILABLE) {
        if (!failing++)
            sdfd_log("warn", "catalog", "%s; retrying with backoff (/readyz answers 503)", err);
        sleep_seconds(backoff);
        backoff = backoff * 2 < BACKOFF_MAX ? backoff * 2 : BACKOFF_MAX;
    }
    if (!rc && failing)
        sdfd_log("info", "catalog", "PostgreSQL reached after %d failed attempts", failing);
    return rc;
}

static int start(void *self, char *err, size_t cap)
{
    backcat *b = self;
    int rc = open_catalog(b, err, cap);
    if (rc)
        return rc;
    if (pthread_create(&b->sync_thread, NULL, sync_main, b)) {
        snprintf(err, cap, "cannot start the catalog's sync thread");
        return SDF_ENOMEM;
    }
    b->started = 1;
    sdfd_catlisten_callbacks cb = {on_change, on_resync, b};
    if ((rc = sdfd_catlisten_start(b->conninfo, &cb, b->m, &b->listen, err, cap)))
        return rc;
    pthread_mutex_lock(&b->lock);
    while (!b->synced)
        pthread_cond_wait(&b->synced_cond, &b->lock);
    pthread_mutex_unlock(&b->lock);
    sdfd_log("info", "catalog", "catalog ready: %zu names known", b->count);
    return 0;
}

static int probe(void *self, char *msg, size_t cap)
{
    backcat *b = self;
    pthread_mutex_lock(&b->lock);
    int ok = trusted(b);
    pthread_mutex_unlock(&b->lock);
    if (!ok)
        snprintf(msg, cap, "the catalog's PostgreSQL cannot be reached (or its changes are "
                 "being read again after a reconnection)");
    return !ok;
}

static int write_item(void *self, sdfd_item_kind kind, sdfd_sidecar *meta, const void *data,
                      size_t n, int *existed, sdfd_seen *seen, char *err, size_t cap)
{
    backcat *b = self;
    unsigned char sha[SDFD_CATALOG_HASH_BYTES];
    uint64_t version = 0;
    if (sdfd_catblob_hash(data, n, sha)) {
        snprintf(err, cap, "cannot hash the bytes (GnuTLS)");
        return SDF_EIO;
    }
    int rc = sdfd_catalog_put_hashed(b->cat, kind, meta->name, data, n, sha, meta->format,
                                     meta->info, &version, existed, err, cap);
    if (rc)
        return rc;
    memcpy(&meta->hash, sha, sizeof meta->hash);
    meta->bytes = n;
    *seen = (sdfd_seen){.version = version};
    learn(b, kind, meta->name, version, 0);
    return 0;
}

static int remove_item(void *self, sdfd_item_kind kind, const char *name, char *err,
                       size_t cap)
{
    backcat *b = self;
    uint64_t version = 0;
    int rc = sdfd_catalog_remove(b->cat, kind, name, &version, err, cap);
    if (!rc)
        learn(b, kind, name, version, 1);
    return rc;
}

static int stat_item(void *self, sdfd_item_kind kind, const char *name, sdfd_seen *seen,
                     char *err, size_t cap)
{
    backcat *b = self;
    *seen = (sdfd_seen){0};
    pthread_mutex_lock(&b->lock);
    int ok = trusted(b), rc = SDF_ENOTFOUND;
    known *k = ok ? find(b, kind, name) : NULL;
    if (!ok)
        rc = SDFD_EUNAVAILABLE;
    else if (k && !k->deleted)
        rc = 0, seen->version = k->version;
    pthread_mutex_unlock(&b->lock);
    if (rc == SDFD_EUNAVAILABLE)
        snprintf(err, cap, "the catalog's PostgreSQL cannot be reached");
    return rc;
}

/* Versions only grow: what was loaded is current unless a later version was announced. */
static int changed(const sdfd_seen *now, const sdfd_seen *loaded)
{
    return now->version > loaded->version;
}

/* The item's row, then its bytes from the local copy when one checks, else from the
 * catalog (and kept as a copy). A blob that went between the two reads (the item was
 * replaced, and the old bytes swept) is read again with its item, in one transaction. */
static int read_cached(backcat *b, sdfd_item_kind kind, const char *name,
                       sdfd_catalog_item *item, void **data, char *err, size_t cap)
{
    int rc = sdfd_catalog_read(b->cat, kind, name, item, NULL, err, cap);
    if (rc || !sdfd_blobcache_get(b->blobs, item->hash, item->bytes, data))
        return rc;
    rc = sdfd_catalog_read_blob(b->cat, item->hash, item->bytes, data, err, cap);
    if (rc == SDF_ENOTFOUND) {
        free(item->info);
        rc = sdfd_catalog_read(b->cat, kind, name, item, data, err, cap);
    }
    char why[256];
    if (!rc && sdfd_blobcache_put(b->blobs, item->hash, *data, item->bytes, why, sizeof why))
        sdfd_log("warn", "blob_cache", "%s (read from the catalog instead)", why);
    return rc;
}

static int read_item(void *self, sdfd_item_kind kind, const char *name, sdfd_sidecar *meta,
                     void **data, sdfd_seen *seen, char *err, size_t cap)
{
    backcat *b = self;
    sdfd_catalog_item item = {0};
    *meta = (sdfd_sidecar){0};
    *seen = (sdfd_seen){0};
    int rc = b->blobs && data ? read_cached(b, kind, name, &item, data, err, cap)
                              : sdfd_catalog_read(b->cat, kind, name, &item, data, err, cap);
    if (rc)
        return rc;
    snprintf(meta->name, sizeof meta->name, "%s", name);
    snprintf(meta->format, sizeof meta->format, "%s", item.format);
    memcpy(&meta->hash, item.hash, sizeof meta->hash);
    meta->bytes = item.bytes, meta->info = item.info;
    seen->version = item.version;
    learn(b, kind, name, item.version, 0);
    return 0;
}

/* The bytes failed their hash in PostgreSQL: nothing to move, so say so loudly; every read
 * checks again, and a new upload of the name replaces them. */
static void quarantine(void *self, sdfd_item_kind kind, const char *name, const char *why)
{
    (void)self;
    sdfd_log("error", "store_quarantine", "%s %s in the catalog is damaged and not served: %s",
             sdfd_catalog_kind_name(kind), name, why);
}

static int by_name(const void *a, const void *b) { return strcmp(a, b); }

static size_t names(void *self, sdfd_item_kind kind, int start,
                    char (**out)[SDFD_MAX_NAME + 1])
{
    backcat *b = self;
    (void)start;
    pthread_mutex_lock(&b->lock);
    size_t n = 0;
    *out = malloc((b->count + 1) * sizeof **out);
    for (size_t i = 0; *out && i < b->nbuckets; i++)
        for (known *k = b->buckets[i]; k; k = k->next)
            if (k->kind == kind && !k->deleted)
                snprintf((*out)[n++], sizeof **out, "%s", k->name);
    pthread_mutex_unlock(&b->lock);
    if (*out)
        qsort(*out, n, sizeof **out, by_name);
    return n;
}

static void watch(void *self, sdfd_backing_changed fn, void *arg)
{
    backcat *b = self;
    b->changed = fn, b->changed_arg = arg;
}

static void close_catalog(void *self)
{
    backcat *b = self;
    sdfd_catlisten_stop(b->listen); /* no callback after this */
    if (b->started) {
        pthread_mutex_lock(&b->lock);
        b->stopping = 1;
        pthread_cond_broadcast(&b->wake);
        pthread_mutex_unlock(&b->lock);
        pthread_join(b->sync_thread, NULL);
    }
    sdfd_catalog_close(b->cat);
    for (size_t i = 0; i < b->nbuckets; i++)
        for (known *k = b->buckets[i], *next; k; k = next)
            next = k->next, free(k);
    free(b->buckets);
    pthread_cond_destroy(&b->synced_cond);
    pthread_cond_destroy(&b->wake);
    pthread_mutex_destroy(&b->lock);
    sdfd_blobcache_close(b->blobs);
    free(b->conninfo);
    free(b);
}

static const sdfd_backing_ops ops = {
    .flag = "--catalog",
    .max_name = SDFD_MAX_NAME,
    .start = start,
    .probe = probe,
    .write = write_item,
    .remove = remove_item,
    .stat = stat_item,
    .changed = changed,
    .read = read_item,
    .quarantine = quarantine,
    .names = names,
    .watch = watch,
    .close = close_catalog,
};

int sdfd_backcat_create(const char *conninfo, const char *cache_dir, uint64_t cache_bytes,
                        sdfd_catalog_metrics *m, sdfd_backing *out, char *err, size_t cap)
{
    int rc = sdfd_catconn_check(conninfo, err, cap);
    if (rc)
        return rc;
    sdfd_blobcache *blobs = NULL;
    if (cache_dir && sdfd_blobcache_open(cache_dir, cache_bytes, m, &blobs, err, cap))
        return SDF_EIO;
    m->cache_on = blobs != NULL;
    backcat *b = calloc(1, sizeof *b);
    if (!b || !(b->conninfo = strdup(conninfo)) ||
        !(b->buckets = calloc(b->nbuckets = 64, sizeof *b->buckets))) {
        if (b)
            free(b->conninfo);
        free(b);
        sdfd_blobcache_close(blobs);
        snprintf(err, cap, "out of memory");
        return SDF_ENOMEM;
    }
    b->m = m, b->blobs = blobs;
    pthread_mutex_init(&b->lock, NULL);
    pthread_cond_init(&b->wake, NULL);
    pthread_cond_init(&b->synced_cond, NULL);
    *out = (sdfd_backing){.ops = &ops, .self = b};
    return 0;
}

sdfd_catalog *sdfd_backcat_catalog(const sdfd_backing *b)
{
    return ((backcat *)b->self)->cat;
}
