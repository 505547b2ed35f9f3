/* backfile.c - the file store behind backing.h's calls (backfile.h): each is one of
 * store.h's, the version a sidecar's stamp. */
#include "state/backfile.h"

#include <stdio.h>
#include <string.h>

#include "core/errors.h"

static int start(void *self, char *err, size_t cap)
{
    (void)self, (void)err, (void)cap; /* opened, and brought to layout 2, by sdfd_store_open */
    return 0;
}

static int probe(void *self, char *msg, size_t cap)
{
    int e = sdfd_store_probe(self);
    if (e)
        snprintf(msg, cap, "--data-dir cannot be read: %s", strerror(e));
    return e;
}

static int write_item(void *self, sdfd_item_kind kind, sdfd_sidecar *meta, const void *data,
                      size_t n, int *existed, sdfd_seen *seen, char *err, size_t cap)
{
    *seen = (sdfd_seen){0};
    return sdfd_store_write(self, kind, meta, data, n, existed, &seen->stamp, err, cap);
}

static int remove_item(void *self, sdfd_item_kind kind, const char *name, char *err,
                       size_t cap)
{
    return sdfd_store_remove(self, kind, name, err, cap);
}

static int stat_item(void *self, sdfd_item_kind kind, const char *name, sdfd_seen *seen,
                     char *err, size_t cap)
{
    *seen = (sdfd_seen){0};
    return sdfd_store_stat(self, kind, name, &seen->stamp, err, cap);
}

/* A rewrite is a rename: another inode, or another size or time. */
static int changed(const sdfd_seen *now, const sdfd_seen *loaded)
{
    const sdfd_stamp *a = &now->stamp, *b = &loaded->stamp;
    return a->dev != b->dev || a->ino != b->ino || a->size != b->size ||
           a->mtime_ns != b->mtime_ns;
}

static int read_item(void *self, sdfd_item_kind kind, const char *name, sdfd_sidecar *meta,
                     void **data, sdfd_seen *seen, char *err, size_t cap)
{
    *seen = (sdfd_seen){0};
    return sdfd_store_read(self, kind, name, meta, data, &seen->stamp, err, cap);
}

static void quarantine(void *self, sdfd_item_kind kind, const char *name, const char *why)
{
    sdfd_store_quarantine(self, kind, name, why);
}

static size_t names(void *self, sdfd_item_kind kind, int start,
                    char (**out)[SDFD_MAX_NAME + 1])
{
    return start ? sdfd_store_scan(self, kind, out) : sdfd_store_names(self, kind, out);
}

static void watch(void *self, sdfd_backing_changed fn, void *arg)
{
    (void)self, (void)fn, (void)arg; /* stamps show other processes' changes */
}

static void close_store(void *self) { sdfd_store_close(self); }

static const sdfd_backing_ops ops = {
    .flag = "--data-dir",
    .max_name = SDFD_STORE_MAX_NAME,
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
    .close = close_store,
};

void sdfd_backfile_init(sdfd_store *store, sdfd_backing *out)
{
    *out = (sdfd_backing){.ops = &ops, .self = store, .store = store};
}
