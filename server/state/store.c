/* store.c - the files of --data-dir (see store.h): the lock, the layout, sidecars and data
 * files, quarantine, the start's scan and job records, on storefile.h's atomic writes and
 * checked reads. Every path is built from the directory given at open, so a store that
 * disappears (an unmounted volume) reads as unreadable, not as empty. */
#include "state/store.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/storefile.h"
#include "state/storelayout.h"

#define MAX_SIDECAR_BYTES (1 << 16)
#define MAX_DATA_BYTES ((size_t)1 << 34)
/* A file's path: the directory's (under 4096) and a name. */
#define FILE_PATH 4608
#define MARKER SDFD_STORE_MARKER
#define LOCK_FILE "sdfd-store.lock"

struct sdfd_store {
    char dir[3072];
    int lock_fd;              /* DIR/sdfd-store.lock, flock'ed for the process's life */
    atomic_ulong quarantined; /* makes quarantine names unique within the process */
};

static const char *const kind_dirs[] = SDFD_STORE_KIND_DIRS;
static const char *const data_dirs[] = SDFD_STORE_DATA_DIRS;

uint64_t sdfd_fnv1a64(const void *data, size_t n)
{
    const unsigned char *p = data;
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

static void path_of(const sdfd_store *s, char *out, size_t cap, const char *sub, const char *file)
{
    snprintf(out, cap, "%s/%s%s%s", s->dir, sub, file ? "/" : "", file ? file : "");
}

/* Write `file` in `dir` atomically (storefile.h). 0; SDFD_ENOSPACE when the file system is
 * full or the quota spent (507: the client may retry once space is freed, which sdfd cannot
 * do); SDFD_EUNAVAILABLE for any other failure; err says which file and why. */
static int write_atomic(const char *dir, const char *file, const void *data, size_t n,
                        char *err, size_t cap)
{
    static const char full[] = "the store is full: ";
    int e = sdfd_storefile_write_atomic(dir, file, data, n, err, cap);
    if (e != ENOSPC && e != EDQUOT)
        return e ? SDFD_EUNAVAILABLE : 0;
    if (cap > sizeof full) { /* prefix the message, cutting its end if need be */
        size_t keep = strnlen(err, cap - 1);
        if (keep > cap - sizeof full)
            keep = cap - sizeof full;
        memmove(err + sizeof full - 1, err, keep);
        memcpy(err, full, sizeof full - 1);
        err[sizeof full - 1 + keep] = '\0';
    }
    return SDFD_ENOSPACE;
}

/* Take DIR's lock for the life of the process (a flock, which the kernel drops with the
 * process, however it ends; NFS carries it as a lock on the whole file), and write who holds
 * it into the file for the message another sdfd gives. 0, or -1 with err set. */
static int lock_store(sdfd_store *s, char *err, size_t cap)
{
    char path[FILE_PATH];
    path_of(s, path, sizeof path, LOCK_FILE, NULL);
    s->lock_fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (s->lock_fd < 0) {
        snprintf(err, cap, "cannot open %s: %s", path, strerror(errno));
        return -1;
    }
    if (!flock(s->lock_fd, LOCK_EX | LOCK_NB)) {
        char host[128] = "";
        gethostname(host, sizeof host - 1);
        char text[200];
        int n = snprintf(text, sizeof text, "pid %d on %s\n", (int)getpid(), host);
        if (ftruncate(s->lock_fd, 0) || pwrite(s->lock_fd, text, (size_t)n, 0) != n)
            sdfd_log("warn", "store_lock", "cannot write %s: %s", path, strerror(errno));
        return 0;
    }
    int e = errno;
    char holder[128] = "";
    ssize_t got = e == EWOULDBLOCK ? pread(s->lock_fd, holder, sizeof holder - 1, 0) : -1;
    for (ssize_t i = 0; i < got; i++) /* one printable line, whatever the file holds */
        if (holder[i] < ' ' || holder[i] > '~')
            holder[i] = '\0';
    close(s->lock_fd);
    s->lock_fd = -1;
    if (e != EWOULDBLOCK)
        snprintf(err, cap, "cannot lock %s: %s", path, strerror(e));
    else
        snprintf(err, cap, "%s is in use by another sdfd (%s): a data directory serves one sdfd "
                 "at a time; replicas are to share their state through PostgreSQL (--catalog "
                 "URI), not a directory", s->dir, holder[0] ? holder : "holder unknown");
    return -1;
}

int sdfd_store_open(const char *dir, sdfd_store **out, char *err, size_t cap)
{
    *out = NULL;
    sdfd_store *s = calloc(1, sizeof *s);
    if (!s || strlen(dir) >= sizeof s->dir - 512) {
        snprintf(err, cap, "the --data-dir path is too long");
        free(s);
        return -1;
    }
    snprintf(s->dir, sizeof s->dir, "%s", dir);
    s->lock_fd = -1;
    static const char *const subs[] = {"",     "meshes",     "volumes",   "meshes/data",
                                       "volumes/data", "jobs", "quarantine"};
    for (size_t i = 0; i < sizeof subs / sizeof subs[0]; i++) {
        char p[4096];
        path_of(s, p, sizeof p, subs[i], NULL);
        if (mkdir(p, 0755) && errno != EEXIST) {
            snprintf(err, cap, "cannot create %s: %s", p, strerror(errno));
            sdfd_store_close(s);
            return -1;
        }
        if (i == 0 && lock_store(s, err, cap)) { /* before anything in DIR is touched */
            sdfd_store_close(s);
            return -1;
        }
    }
    if (sdfd_storelayout_settle(s->dir, err, cap)) {
        sdfd_store_close(s);
        return -1;
    }
    *out = s;
    return 0;
}

void sdfd_store_close(sdfd_store *s)
{
    if (s && s->lock_fd >= 0)
        close(s->lock_fd); /* the lock goes with it */
    free(s);
}

int sdfd_store_probe(sdfd_store *s)
{
    char p[4096];
    struct stat st;
    path_of(s, p, sizeof p, MARKER, NULL);
    if (stat(p, &st))
        return errno;
    for (int k = 0; k < 4; k++) {
        path_of(s, p, sizeof p, k < 2 ? kind_dirs[k] : data_dirs[k - 2], NULL);
        DIR *d = opendir(p);
        if (!d)
            return errno;
        closedir(d);
    }
    return 0;
}

/* ---- sidecars ---------------------------------------------------------------------------- */

static void sidecar_name(char *out, size_t cap, const char *name)
{
    snprintf(out, cap, "%s.json", name);
}

static char *sidecar_text(const sdfd_sidecar *m)
{
    char hash[17];
    snprintf(hash, sizeof hash, "%016" PRIx64, m->hash);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", m->name);
    cJSON_AddStringToObject(o, "file", m->file);
    cJSON_AddStringToObject(o, "format", m->format);
    cJSON_AddNumberToObject(o, "bytes", (double)m->bytes);
    cJSON_AddStringToObject(o, "fnv1a64", hash);
    cJSON *info = m->info ? cJSON_Parse(m->info) : NULL;
    cJSON_AddItemToObject(o, "info", info ? info : cJSON_CreateObject());
    char *text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return text;
}

/* Is `text` 1..max characters, each one of `set`? */
static int spelled_with(const char *text, size_t max, const char *set)
{
    size_t n = strlen(text);
    return n >= 1 && n <= max && strspn(text, set) == n;
}

/* Does the data file the sidecar names belong to its item: is it exactly the name sdfd gives
 * the item's data, NAME.<fnv1a64>.<format>? A sidecar that names any other file (another
 * item's, damaged or forged) must not lead a read, a delete or a quarantine to that file. */
static int own_data_file(const sdfd_sidecar *m, const char *file)
{
    char expect[sizeof m->file];
    int n = snprintf(expect, sizeof expect, "%s.%016" PRIx64 ".%s", m->name, m->hash, m->format);
    return n > 0 && (size_t)n < sizeof expect && !strcmp(expect, file);
}

/* Parse a sidecar's text into m; 0 or -1 with why set. */
static int parse_sidecar(const char *text, const char *name, sdfd_sidecar *m, char *why,
                         size_t cap)
{
    cJSON *o = cJSON_Parse(text);
    const cJSON *n = cJSON_GetObjectItemCaseSensitive(o, "name"),
                *f = cJSON_GetObjectItemCaseSensitive(o, "file"),
                *fmt = cJSON_GetObjectItemCaseSensitive(o, "format"),
                *b = cJSON_GetObjectItemCaseSensitive(o, "bytes"),
                *h = cJSON_GetObjectItemCaseSensitive(o, "fnv1a64"),
                *info = cJSON_GetObjectItemCaseSensitive(o, "info");
    int ok = cJSON_IsString(n) && !strcmp(n->valuestring, name) && cJSON_IsString(f) &&
             cJSON_IsString(fmt) &&
             spelled_with(fmt->valuestring, sizeof m->format - 1,
                          "abcdefghijklmnopqrstuvwxyz0123456789") &&
             cJSON_IsNumber(b) && b->valuedouble >= 0 &&
             b->valuedouble <= (double)MAX_DATA_BYTES && cJSON_IsString(h) &&
             spelled_with(h->valuestring, 16, "0123456789abcdef") &&
             strlen(h->valuestring) == 16 && cJSON_IsObject(info);
    if (!ok) {
        snprintf(why, cap, "the sidecar is not a JSON object with name, file, format, bytes, "
                 "fnv1a64 and info");
    } else {
        snprintf(m->name, sizeof m->name, "%s", name);
        snprintf(m->format, sizeof m->format, "%s", fmt->valuestring);
        m->hash = strtoull(h->valuestring, NULL, 16);
        m->bytes = (size_t)b->valuedouble;
        if (!(ok = own_data_file(m, f->valuestring)))
            snprintf(why, cap, "the sidecar names the data file '%.80s', not its own (%.120s."
                     "%s.%s)", f->valuestring, name, h->valuestring, m->format);
    }
    if (ok) {
        snprintf(m->file, sizeof m->file, "%s", f->valuestring);
        m->info = cJSON_PrintUnformatted(info);
    }
    cJSON_Delete(o);
    return ok ? 0 : -1;
}

static void stamp_of(const struct stat *st, sdfd_stamp *out)
{
    *out = (sdfd_stamp){(unsigned long long)st->st_dev, (unsigned long long)st->st_ino,
                        (unsigned long long)st->st_size,
                        (long long)st->st_mtim.tv_sec * 1000000000ll + st->st_mtim.tv_nsec};
}

/* ENOENT is "no such item" only while the store itself is there. Any other failure to open or
 * read a file (a permission, an I/O error) is the store's trouble, not damage to the item:
 * SDFD_EUNAVAILABLE, the file left where it is, and served once it can be read. */
static int missing_or_unreadable(sdfd_store *s, int e, const char *path, char *err, size_t cap)
{
    int probe = sdfd_store_probe(s);
    if (e == ENOENT && !probe)
        return SDF_ENOTFOUND;
    if (probe)
        snprintf(err, cap, "the store is unreadable: %s: %s", path, strerror(probe));
    else
        snprintf(err, cap, "cannot read %s: %s", path, strerror(e));
    return SDFD_EUNAVAILABLE;
}

int sdfd_store_stat(sdfd_store *s, sdfd_item_kind kind, const char *name, sdfd_stamp *stamp,
                    char *err, size_t cap)
{
    char file[SDFD_MAX_NAME + 8], path[FILE_PATH];
    sidecar_name(file, sizeof file, name);
    path_of(s, path, sizeof path, kind_dirs[kind], file);
    struct stat st;
    if (stat(path, &st))
        return missing_or_unreadable(s, errno, path, err, cap);
    stamp_of(&st, stamp);
    return 0;
}

int sdfd_store_read(sdfd_store *s, sdfd_item_kind kind, const char *name, sdfd_sidecar *meta,
                    void **data, sdfd_stamp *stamp, char *err, size_t cap)
{
    char file[SDFD_MAX_NAME + 8], path[FILE_PATH], dir[4096], *text;
    size_t n;
    struct stat st;
    memset(meta, 0, sizeof *meta);
    if (data)
        *data = NULL;
    sidecar_name(file, sizeof file, name);
    path_of(s, dir, sizeof dir, data_dirs[kind], NULL);
    path_of(s, path, sizeof path, kind_dirs[kind], file);
    int e = sdfd_storefile_read(path, MAX_SIDECAR_BYTES, SIZE_MAX, &text, &n, &st);
    if (e == ENOENT || (e && e != EFBIG && e != EISDIR))
        return missing_or_unreadable(s, e, path, err, cap);
    if (e) {
        snprintf(err, cap, "the sidecar %s is %s", file,
                 e == EISDIR ? "not a regular file" : "too large");
        return SDF_EFORMAT;
    }
    stamp_of(&st, stamp);
    int bad = parse_sidecar(text, name, meta, err, cap);
    free(text);
    if (bad)
        return SDF_EFORMAT;
    if (!data)
        return 0;
    char *bytes;
    snprintf(path, sizeof path, "%s/%s", dir, meta->file);
    e = sdfd_storefile_read(path, MAX_DATA_BYTES, meta->bytes, &bytes, &n, &st);
    if (e == ENOENT && !sdfd_store_probe(s))
        snprintf(err, cap, "its data file %s is missing", meta->file);
    else if (e == EFBIG)
        snprintf(err, cap, "its data file %s is not %zu bytes long, as the sidecar says (a "
                 "partial or foreign file)", meta->file, meta->bytes);
    else if (e == EISDIR)
        snprintf(err, cap, "its data file %s is not a regular file", meta->file);
    else if (e) {
        free(meta->info), meta->info = NULL;
        return missing_or_unreadable(s, e, path, err, cap);
    }
    if (!e && sdfd_fnv1a64(bytes, n) != meta->hash) {
        snprintf(err, cap, "its data file %s does not have the sidecar's FNV-1a hash", meta->file);
        e = EINVAL;
    }
    if (e) {
        free(bytes);
        free(meta->info), meta->info = NULL;
        return SDF_EFORMAT;
    }
    *data = bytes;
    return 0;
}

/* ---- writes and deletes ------------------------------------------------------------------ */

int sdfd_store_write(sdfd_store *s, sdfd_item_kind kind, sdfd_sidecar *meta, const void *data,
                     size_t n, int *existed, sdfd_stamp *stamp, char *err, size_t cap)
{
    char dir[4096], data_dir[4096], file[SDFD_MAX_NAME + 8];
    path_of(s, dir, sizeof dir, kind_dirs[kind], NULL);
    path_of(s, data_dir, sizeof data_dir, data_dirs[kind], NULL);
    sidecar_name(file, sizeof file, meta->name);
    meta->hash = sdfd_fnv1a64(data, n);
    meta->bytes = n;
    snprintf(meta->file, sizeof meta->file, "%s.%016" PRIx64 ".%s", meta->name, meta->hash,
             meta->format);
    sdfd_sidecar old;
    sdfd_stamp ignored;
    char why[256];
    int had = sdfd_store_read(s, kind, meta->name, &old, NULL, &ignored, why, sizeof why) == 0;
    free(old.info);
    *existed = had || sdfd_store_stat(s, kind, meta->name, &ignored, why, sizeof why) == 0;
    char path[FILE_PATH];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", data_dir, meta->file);
    int fresh = lstat(path, &st) != 0; /* the same bytes may be there already */
    int rc = write_atomic(data_dir, meta->file, data, n, err, cap);
    char *text = rc ? NULL : sidecar_text(meta);
    if (!rc && !text)
        rc = SDF_ENOMEM, snprintf(err, cap, "out of memory");
    if (!rc)
        rc = write_atomic(dir, file, text, strlen(text), err, cap);
    free(text);
    if (rc && fresh) /* no sidecar names it: give its space back now (a full store) */
        unlink(path);
    if (rc)
        return rc;
    if (had && strcmp(old.file, meta->file)) { /* the old version's data, now unreferenced */
        snprintf(path, sizeof path, "%s/%s", data_dir, old.file);
        unlink(path);
    }
    return sdfd_store_stat(s, kind, meta->name, stamp, err, cap);
}

int sdfd_store_remove(sdfd_store *s, sdfd_item_kind kind, const char *name, char *err,
                      size_t cap)
{
    char dir[4096], file[SDFD_MAX_NAME + 8], path[FILE_PATH];
    sdfd_sidecar meta;
    sdfd_stamp stamp;
    path_of(s, dir, sizeof dir, kind_dirs[kind], NULL);
    sidecar_name(file, sizeof file, name);
    int rc = sdfd_store_read(s, kind, name, &meta, NULL, &stamp, err, cap);
    free(meta.info);
    if (rc == SDF_ENOTFOUND || rc == SDFD_EUNAVAILABLE)
        return rc;
    snprintf(path, sizeof path, "%s/%s", dir, file);
    if (unlink(path)) {
        int e = errno;
        if (e == ENOENT)
            return SDF_ENOTFOUND;
        snprintf(err, cap, "cannot delete %s: %s", path, strerror(e));
        return SDFD_EUNAVAILABLE;
    }
    sdfd_storefile_sync_dir(dir); /* the delete is the sidecar's: durable before the data goes */
    if (!rc) {
        path_of(s, dir, sizeof dir, data_dirs[kind], NULL);
        snprintf(path, sizeof path, "%s/%s", dir, meta.file);
        unlink(path);
    }
    return 0;
}

/* The length of NAME when `file` is a data file's name, NAME.<16 hex>.<ext> with a valid NAME
 * and an ext of 1..7 lowercase letters or digits (a format's name); else 0. The last two
 * dots end NAME, so a data file has one owner, whatever the names. */
static size_t data_file_stem(const char *file)
{
    const char *ext = strrchr(file, '.');
    if (!ext || ext - file < 18 || ext[-17] != '.' ||
        !spelled_with(ext + 1, 7, "abcdefghijklmnopqrstuvwxyz0123456789") ||
        strspn(ext - 16, "0123456789abcdef") != 16)
        return 0;
    size_t stem = (size_t)(ext - 17 - file);
    return sdfd_valid_name(file, stem) ? stem : 0;
}

/* ---- quarantine -------------------------------------------------------------------------- */

/* Move DIR/sub/file into DIR/quarantine (with a note saying why). */
static void quarantine_file(sdfd_store *s, const char *sub, const char *file, const char *why)
{
    char from[FILE_PATH], to[FILE_PATH], name[300];
    unsigned long k = atomic_fetch_add(&s->quarantined, 1);
    snprintf(name, sizeof name, "%s-%lld-%d-%lu-%.200s", sub, (long long)time(NULL),
             (int)getpid(), k, file);
    for (char *c = name; *c; c++) /* meshes/data -> meshes-data */
        if (*c == '/')
            *c = '-';
    path_of(s, from, sizeof from, sub, file);
    snprintf(to, sizeof to, "%s/quarantine/%s", s->dir, name);
    if (rename(from, to)) {
        if (errno != ENOENT)
            sdfd_log("error", "store_quarantine", "cannot move %s aside: %s", from,
                     strerror(errno));
        return;
    }
    sdfd_log("warn", "store_quarantine", "%s/%s moved to quarantine/%s: %s", sub, file, name, why);
    char note[sizeof name + 8], dir[4096], err[128];
    snprintf(note, sizeof note, "%s.why", name);
    path_of(s, dir, sizeof dir, "quarantine", NULL);
    char text[1024];
    int len = snprintf(text, sizeof text, "%s\n", why);
    write_atomic(dir, note, text, (size_t)len < sizeof text ? (size_t)len : sizeof text - 1, err,
                 sizeof err);
}

/* Move the data files named as `name`'s (NAME.<hash>.<ext>) to quarantine. */
static void quarantine_data_of(sdfd_store *s, sdfd_item_kind kind, const char *name,
                               const char *why)
{
    char dir[4096];
    size_t len = strlen(name);
    path_of(s, dir, sizeof dir, data_dirs[kind], NULL);
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));)
        if (data_file_stem(e->d_name) == len && !strncmp(e->d_name, name, len))
            quarantine_file(s, data_dirs[kind], e->d_name, why);
    if (d)
        closedir(d);
}

/* A sidecar that parses names its item's own data file (parse_sidecar), which goes with it;
 * one that does not takes the data files named as its item's. Never another item's file. */
void sdfd_store_quarantine(sdfd_store *s, sdfd_item_kind kind, const char *name,
                           const char *why)
{
    char file[SDFD_MAX_NAME + 8], err[64];
    sdfd_sidecar meta;
    sdfd_stamp stamp;
    int rc = sdfd_store_read(s, kind, name, &meta, NULL, &stamp, err, sizeof err);
    free(meta.info);
    sidecar_name(file, sizeof file, name);
    quarantine_file(s, kind_dirs[kind], file, why);
    if (!rc)
        quarantine_file(s, data_dirs[kind], meta.file, why);
    else if (rc == SDF_EFORMAT)
        quarantine_data_of(s, kind, name, why);
}

/* ---- the start's scan -------------------------------------------------------------------- */

static int by_text(const void *a, const void *b) { return strcmp(a, b); }

static int old_enough(const char *path)
{
    struct stat st;
    return !lstat(path, &st) && time(NULL) - st.st_mtime > SDFD_STORE_GRACE_SECONDS;
}

/* A list of item names. */
typedef struct name_list {
    char (*rows)[SDFD_MAX_NAME + 1];
    size_t n;
} name_list;

static int name_list_add(name_list *l, const char *name, size_t len)
{
    void *grown = realloc(l->rows, (l->n + 1) * sizeof *l->rows);
    if (!grown)
        return -1;
    l->rows = grown;
    snprintf(l->rows[l->n++], sizeof *l->rows, "%.*s", (int)len, name);
    return 0;
}

/* Delete `path` (a temporary or an orphan) once it is old enough. */
static void clean_up(const char *path, int temp)
{
    if (old_enough(path) && !unlink(path))
        sdfd_log("info", "store_cleanup", "deleted %s, left by an interrupted %s", path,
                 temp ? "write" : "write or delete");
}

/* KIND/: the sidecars, listed in `names`; strangers go to quarantine, old temporaries are
 * deleted. Dot files are never items: temporaries, and NFS's .nfsXXXX stand-ins for files
 * unlinked while open, which must stay where they are. */
static void scan_sidecars(sdfd_store *s, sdfd_item_kind kind, name_list *names)
{
    char dir[4096], path[FILE_PATH];
    path_of(s, dir, sizeof dir, kind_dirs[kind], NULL);
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));) {
        const char *f = e->d_name;
        size_t len = strlen(f);
        snprintf(path, sizeof path, "%s/%s", dir, f);
        if (!strncmp(f, ".tmp-", 5))
            clean_up(path, 1);
        if (f[0] == '.' || !strcmp(f, "data"))
            continue;
        int sidecar = len > 5 && !strcmp(f + len - 5, ".json");
        if (!sidecar || len - 5 > SDFD_STORE_MAX_NAME || !sdfd_valid_name(f, len - 5))
            quarantine_file(s, kind_dirs[kind], f,
                            sidecar ? "not a valid item name (1-200 of A-Z a-z 0-9 . _ -, not "
                                      "starting with '.')"
                                    : "not a file sdfd writes (NAME.json, or data/)");
        else if (name_list_add(names, f, len - 5))
            break;
    }
    if (d)
        closedir(d);
}

/* Is the data file `file` (NAME.<hash>.<ext>, NAME `stem` bytes long) an orphan: NAME has no
 * sidecar, or one that reads and names another file? A sidecar that cannot be read now (a
 * permission, an I/O error) or is damaged keeps the file: the former may be mended, the
 * latter is quarantined with it. */
static int orphan(sdfd_store *s, sdfd_item_kind kind, const char *file, size_t stem)
{
    char name[SDFD_MAX_NAME + 1], why[64];
    sdfd_sidecar meta;
    sdfd_stamp stamp;
    snprintf(name, sizeof name, "%.*s", (int)stem, file);
    int rc = sdfd_store_read(s, kind, name, &meta, NULL, &stamp, why, sizeof why);
    free(meta.info);
    return rc == SDF_ENOTFOUND || (!rc && strcmp(meta.file, file));
}

/* KIND/data/: strangers go to quarantine; old temporaries, and old orphans (left by a
 * crash), are deleted. */
static void scan_data(sdfd_store *s, sdfd_item_kind kind)
{
    char dir[4096], path[FILE_PATH];
    path_of(s, dir, sizeof dir, data_dirs[kind], NULL);
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));) {
        const char *f = e->d_name;
        size_t stem = data_file_stem(f);
        snprintf(path, sizeof path, "%s/%s", dir, f);
        if (f[0] == '.') {
            if (!strncmp(f, ".tmp-", 5))
                clean_up(path, 1);
        } else if (!stem) {
            quarantine_file(s, data_dirs[kind], f, "not a file sdfd writes (NAME.<hash>.<ext>)");
        } else if (orphan(s, kind, f, stem)) {
            clean_up(path, 0);
        }
    }
    if (d)
        closedir(d);
}

size_t sdfd_store_scan(sdfd_store *s, sdfd_item_kind kind, char (**names)[SDFD_MAX_NAME + 1])
{
    name_list found = {0};
    scan_sidecars(s, kind, &found);
    scan_data(s, kind);
    if (found.rows)
        qsort(found.rows, found.n, sizeof *found.rows, by_text);
    *names = found.rows;
    return found.n;
}

/* The stems of DIR's "*.json" files (sidecars, job records) that `accept` takes, each shorter
 * than `width`, as rows of `width` bytes in *out (NULL when there are none). */
static size_t json_stems(const char *dir, size_t width, int (*accept)(const char *, size_t),
                         char **out)
{
    size_t n = 0;
    char *rows = NULL;
    DIR *d = opendir(dir);
    for (struct dirent *e; d && (e = readdir(d));) {
        size_t len = strlen(e->d_name);
        if (len <= 5 || strcmp(e->d_name + len - 5, ".json") || len - 5 >= width ||
            !accept(e->d_name, len - 5))
            continue;
        void *grown = realloc(rows, (n + 1) * width);
        if (!grown)
            break;
        rows = grown;
        snprintf(rows + n++ * width, width, "%.*s", (int)(len - 5), e->d_name);
    }
    if (d)
        closedir(d);
    *out = rows;
    return n;
}

static int item_stem(const char *stem, size_t len)
{
    return len <= SDFD_STORE_MAX_NAME && sdfd_valid_name(stem, len);
}

size_t sdfd_store_names(sdfd_store *s, sdfd_item_kind kind, char (**names)[SDFD_MAX_NAME + 1])
{
    char dir[4096], *rows;
    path_of(s, dir, sizeof dir, kind_dirs[kind], NULL);
    size_t n = json_stems(dir, sizeof **names, item_stem, &rows);
    if (rows)
        qsort(rows, n, sizeof **names, by_text);
    *names = (char(*)[SDFD_MAX_NAME + 1])rows;
    return n;
}

/* ---- job records ------------------------------------------------------------------------- */

int sdfd_store_write_job(sdfd_store *s, const char *id, const char *json)
{
    char dir[4096], file[96], err[256];
    path_of(s, dir, sizeof dir, "jobs", NULL);
    snprintf(file, sizeof file, "%.64s.json", id);
    int rc = write_atomic(dir, file, json, strlen(json), err, sizeof err);
    if (rc)
        sdfd_log("error", "store_job", "%s", err);
    return rc;
}

char *sdfd_store_read_job(sdfd_store *s, const char *id)
{
    char file[96], path[FILE_PATH], *text;
    size_t n;
    struct stat st;
    snprintf(file, sizeof file, "%.64s.json", id);
    path_of(s, path, sizeof path, "jobs", file);
    return sdfd_storefile_read(path, MAX_SIDECAR_BYTES, SIZE_MAX, &text, &n, &st) ? NULL : text;
}

void sdfd_store_remove_job(sdfd_store *s, const char *id)
{
    char file[96], path[FILE_PATH];
    snprintf(file, sizeof file, "%.64s.json", id);
    path_of(s, path, sizeof path, "jobs", file);
    unlink(path);
}

int sdfd_store_lock_job(sdfd_store *s, const char *id)
{
    char file[96], path[FILE_PATH];
    snprintf(file, sizeof file, "%.64s.lock", id);
    path_of(s, path, sizeof path, "jobs", file);
    int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    struct flock l = {.l_type = F_WRLCK, .l_whence = SEEK_SET};
    if (fd >= 0 && fcntl(fd, F_SETLK, &l)) {
        close(fd);
        return -1;
    }
    return fd;
}

void sdfd_store_unlock_job(sdfd_store *s, const char *id, int fd)
{
    char file[96], path[FILE_PATH];
    snprintf(file, sizeof file, "%.64s.lock", id);
    path_of(s, path, sizeof path, "jobs", file);
    unlink(path); /* before the lock goes, so no one takes a lock on a file about to vanish */
    if (fd >= 0)
        close(fd);
}

static int job_stem(const char *stem, size_t len)
{
    (void)len;
    return stem[0] != '.';
}

size_t sdfd_store_job_ids(sdfd_store *s, char (**ids)[64])
{
    char dir[4096], *rows;
    path_of(s, dir, sizeof dir, "jobs", NULL);
    size_t n = json_stems(dir, sizeof **ids, job_stem, &rows);
    *ids = (char(*)[64])rows;
    return n;
}
