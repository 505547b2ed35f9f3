/* blobcache.c - local copies of the catalog's blobs by hash (see blobcache.h).
 *
 * The index is a plain array searched linearly: a replica holds some hundreds of copies at
 * most (each is a whole mesh or volume), and a search costs nothing beside reading a file.
 * Copies are not fsynced: a copy a crash left half-written fails its hash on the next read
 * and is removed, which costs one fetch from the catalog, never a wrong answer. */
#include "state/blobcache.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <gnutls/crypto.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "state/storefile.h"

#define HEX_LEN (2 * SDFD_BLOBCACHE_HASH_BYTES)

typedef struct entry {
    unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES];
    uint64_t bytes;
    uint64_t used; /* the clock at its last get or put: the smallest goes first */
} entry;

struct sdfd_blobcache {
    char *dir; /* DIR/blobs */
    uint64_t max_bytes;
    sdfd_catalog_metrics *m;
    pthread_mutex_t lock; /* guards what follows */
    entry *e;
    size_t n, cap;
    uint64_t total, clock;
};

static void to_hex(const unsigned char *hash, char out[HEX_LEN + 1])
{
    for (int i = 0; i < SDFD_BLOBCACHE_HASH_BYTES; i++)
        snprintf(out + 2 * i, 3, "%02x", hash[i]);
}

static int from_hex(const char *text, unsigned char *hash)
{
    if (strlen(text) != HEX_LEN || strspn(text, "0123456789abcdef") != HEX_LEN)
        return -1;
    for (int i = 0; i < SDFD_BLOBCACHE_HASH_BYTES; i++) {
        unsigned v;
        sscanf(text + 2 * i, "%2x", &v);
        hash[i] = (unsigned char)v;
    }
    return 0;
}

static void path_of(const sdfd_blobcache *c, const unsigned char *hash, char *out, size_t cap)
{
    char hex[HEX_LEN + 1];
    to_hex(hash, hex);
    snprintf(out, cap, "%s/%s", c->dir, hex);
}

/* ---- the index (under the lock) --------------------------------------------------------- */

static entry *find(sdfd_blobcache *c, const unsigned char *hash)
{
    for (size_t i = 0; i < c->n; i++)
        if (!memcmp(c->e[i].hash, hash, SDFD_BLOBCACHE_HASH_BYTES))
            return &c->e[i];
    return NULL;
}

static void publish(sdfd_blobcache *c)
{
    atomic_store(&c->m->cache_bytes, (unsigned long long)c->total);
}

static int add(sdfd_blobcache *c, const unsigned char *hash, uint64_t bytes)
{
    entry *old = find(c, hash);
    if (old) {
        old->used = ++c->clock;
        return 0;
    }
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 64;
        entry *e = realloc(c->e, cap * sizeof *e);
        if (!e)
            return -1;
        c->e = e, c->cap = cap;
    }
    entry *e = &c->e[c->n++];
    memcpy(e->hash, hash, SDFD_BLOBCACHE_HASH_BYTES);
    e->bytes = bytes, e->used = ++c->clock;
    c->total += bytes;
    publish(c);
    return 0;
}

static void drop(sdfd_blobcache *c, entry *e)
{
    c->total -= e->bytes;
    *e = c->e[--c->n];
    publish(c);
}

/* Remove the least recently used copies until the total fits, keeping `keep`. */
static void evict(sdfd_blobcache *c, const unsigned char *keep)
{
    while (c->max_bytes && c->total > c->max_bytes) {
        entry *oldest = NULL;
        for (size_t i = 0; i < c->n; i++)
            if ((!keep || memcmp(c->e[i].hash, keep, SDFD_BLOBCACHE_HASH_BYTES)) &&
                (!oldest || c->e[i].used < oldest->used))
                oldest = &c->e[i];
        if (!oldest)
            return;
        char path[4096];
        path_of(c, oldest->hash, path, sizeof path);
        unlink(path);
        drop(c, oldest);
        atomic_fetch_add(&c->m->cache_evictions, 1);
    }
}

/* ---- open: what a previous run left ---------------------------------------------------- */

typedef struct found {
    unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES];
    uint64_t bytes;
    struct timespec mtime;
} found;

static int by_mtime(const void *a, const void *b)
{
    const struct timespec *x = &((const found *)a)->mtime, *y = &((const found *)b)->mtime;
    if (x->tv_sec != y->tv_sec)
        return x->tv_sec < y->tv_sec ? -1 : 1;
    return (x->tv_nsec > y->tv_nsec) - (x->tv_nsec < y->tv_nsec);
}

static int scan(sdfd_blobcache *c, char *err, size_t cap)
{
    DIR *d = opendir(c->dir);
    if (!d) {
        snprintf(err, cap, "cannot read %s: %s", c->dir, strerror(errno));
        return -1;
    }
    found *list = NULL;
    size_t n = 0, room = 0;
    int rc = 0;
    for (struct dirent *de; !rc && (de = readdir(d));) {
        char path[4096];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", c->dir, de->d_name);
        if (!strncmp(de->d_name, ".tmp-", 5)) {
            unlink(path); /* a copy a crash interrupted */
            continue;
        }
        found f;
        if (from_hex(de->d_name, f.hash) || stat(path, &st) || !S_ISREG(st.st_mode))
            continue;
        f.bytes = (uint64_t)st.st_size, f.mtime = st.st_mtim;
        if (n == room) {
            found *grown = realloc(list, (room = room ? 2 * room : 64) * sizeof *list);
            if (!grown) {
                snprintf(err, cap, "out of memory indexing %s", c->dir);
                rc = -1;
                break;
            }
            list = grown;
        }
        list[n++] = f;
    }
    closedir(d);
    if (!rc && n)
        qsort(list, n, sizeof *list, by_mtime);
    for (size_t i = 0; !rc && i < n; i++)
        if (add(c, list[i].hash, list[i].bytes)) {
            snprintf(err, cap, "out of memory indexing %s", c->dir);
            rc = -1;
        }
    free(list);
    return rc;
}

int sdfd_blobcache_open(const char *dir, uint64_t max_bytes, sdfd_catalog_metrics *m,
                        sdfd_blobcache **out, char *err, size_t cap)
{
    *out = NULL;
    size_t len = strlen(dir) + sizeof "/" SDFD_BLOBCACHE_DIR;
    sdfd_blobcache *c = calloc(1, sizeof *c);
    if (!c || !(c->dir = malloc(len))) {
        free(c);
        snprintf(err, cap, "out of memory");
        return -1;
    }
    snprintf(c->dir, len, "%s/%s", dir, SDFD_BLOBCACHE_DIR);
    c->max_bytes = max_bytes, c->m = m;
    pthread_mutex_init(&c->lock, NULL);
    if ((mkdir(dir, 0700) && errno != EEXIST) || (mkdir(c->dir, 0700) && errno != EEXIST)) {
        snprintf(err, cap, "cannot create %s: %s", c->dir, strerror(errno));
        sdfd_blobcache_close(c);
        return -1;
    }
    if (scan(c, err, cap)) {
        sdfd_blobcache_close(c);
        return -1;
    }
    evict(c, NULL);
    *out = c;
    return 0;
}

/* ---- get and put ------------------------------------------------------------------------ */

/* The copy is not what its name says: remove it from the disk and the index. */
static void damaged(sdfd_blobcache *c, const unsigned char *hash, const char *path)
{
    unlink(path);
    pthread_mutex_lock(&c->lock);
    entry *e = find(c, hash);
    if (e)
        drop(c, e);
    pthread_mutex_unlock(&c->lock);
    atomic_fetch_add(&c->m->cache_damaged, 1);
}

int sdfd_blobcache_get(sdfd_blobcache *c, const unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES],
                       size_t bytes, void **data)
{
    char path[4096], *buf = NULL;
    size_t n = 0;
    unsigned char sum[SDFD_BLOBCACHE_HASH_BYTES];
    struct stat st;
    *data = NULL;
    path_of(c, hash, path, sizeof path);
    int e = sdfd_storefile_read(path, bytes, bytes, &buf, &n, &st);
    if (e == ENOENT) {
        atomic_fetch_add(&c->m->cache_misses, 1);
        return -1;
    }
    if (e || gnutls_hash_fast(GNUTLS_DIG_SHA256, buf, n, sum) ||
        memcmp(sum, hash, sizeof sum)) {
        free(buf);
        damaged(c, hash, path);
        return -1;
    }
    pthread_mutex_lock(&c->lock);
    int rc = add(c, hash, n); /* another process may have made it: index it now */
    evict(c, hash);
    pthread_mutex_unlock(&c->lock);
    (void)rc; /* out of memory for the index: the copy is still good */
    atomic_fetch_add(&c->m->cache_hits, 1);
    *data = buf;
    return 0;
}

/* Write path through a temporary in the same directory, renamed into place. */
static int write_copy(const sdfd_blobcache *c, const char *path, const void *data, size_t n,
                      char *err, size_t cap)
{
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s/.tmp-XXXXXX", c->dir);
    int fd = mkstemp(tmp), e = 0;
    if (fd < 0) {
        snprintf(err, cap, "cannot create a copy in %s: %s", c->dir, strerror(errno));
        return -1;
    }
    for (size_t done = 0; !e && done < n;) {
        ssize_t w = write(fd, (const char *)data + done, n - done);
        if (w < 0 && errno != EINTR)
            e = errno;
        else if (w > 0)
            done += (size_t)w;
    }
    if (close(fd) && !e)
        e = errno;
    if (!e && rename(tmp, path))
        e = errno;
    if (e) {
        unlink(tmp);
        snprintf(err, cap, "cannot write %s: %s", path, strerror(e));
        return -1;
    }
    return 0;
}

int sdfd_blobcache_put(sdfd_blobcache *c, const unsigned char hash[SDFD_BLOBCACHE_HASH_BYTES],
                       const void *data, size_t n, char *err, size_t cap)
{
    char path[4096];
    if (c->max_bytes && n > c->max_bytes)
        return 0; /* it would push out everything else and still not fit */
    pthread_mutex_lock(&c->lock);
    entry *known = find(c, hash);
    if (known)
        known->used = ++c->clock;
    pthread_mutex_unlock(&c->lock);
    if (known)
        return 0;
    path_of(c, hash, path, sizeof path);
    if (write_copy(c, path, data, n, err, cap))
        return -1;
    pthread_mutex_lock(&c->lock);
    int rc = add(c, hash, n);
    if (!rc)
        evict(c, hash);
    pthread_mutex_unlock(&c->lock);
    if (rc) {
        unlink(path);
        snprintf(err, cap, "out of memory indexing %s", c->dir);
        return -1;
    }
    atomic_fetch_add(&c->m->cache_fills, 1);
    return 0;
}

uint64_t sdfd_blobcache_bytes(sdfd_blobcache *c)
{
    pthread_mutex_lock(&c->lock);
    uint64_t total = c->total;
    pthread_mutex_unlock(&c->lock);
    return total;
}

void sdfd_blobcache_close(sdfd_blobcache *c)
{
    if (!c)
        return;
    pthread_mutex_destroy(&c->lock);
    free(c->e);
    free(c->dir);
    free(c);
}
