/* storelayout.c - the store's layout: its number in the marker, and the move of a layout-1
 * store's data files into KIND/data/ (storelayout.h). */
#include "state/storelayout.h"

#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/log.h"
#include "state/registry.h" /* sdfd_valid_name */
#include "state/storefile.h"

/* A path: a directory (under 4096) and a name. */
#define FILE_PATH 4608

static const char *const kind_dirs[] = SDFD_STORE_KIND_DIRS;
static const char *const data_dirs[] = SDFD_STORE_DATA_DIRS;

/* The layout the marker records: 0 when there is no marker (or it says none), -1 when it
 * cannot be read. */
static int marker_layout(const char *dir)
{
    char path[FILE_PATH], text[256];
    snprintf(path, sizeof path, "%s/%s", dir, SDFD_STORE_MARKER);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return errno == ENOENT ? 0 : -1;
    ssize_t n = read(fd, text, sizeof text - 1);
    close(fd);
    if (n < 0)
        return -1;
    text[n] = '\0';
    cJSON *o = cJSON_Parse(text);
    const cJSON *l = cJSON_GetObjectItemCaseSensitive(o, "layout");
    int layout = cJSON_IsNumber(l) && l->valuedouble >= 0 && l->valuedouble < 1000
                     ? (int)l->valuedouble
                     : 0;
    cJSON_Delete(o);
    return layout;
}

/* Is `file` a data file layout 1 wrote beside the sidecars, NAME.<16 hex>.<ext> with one of
 * the five extensions it wrote? No sidecar (NAME.json) is. */
static int layout1_data_name(const char *file)
{
    static const char *const exts[] = {"obj", "ply", "stl", "off", "exr"};
    const char *ext = strrchr(file, '.');
    if (!ext || ext - file < 18 || ext[-17] != '.' ||
        !sdfd_valid_name(file, (size_t)(ext - 17 - file)))
        return 0;
    for (const char *h = ext - 16; h < ext; h++)
        if (!strchr("0123456789abcdef", *h))
            return 0;
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++)
        if (!strcmp(ext + 1, exts[i]))
            return 1;
    return 0;
}

/* Move layout 1's data files into KIND/data/. Each rename is atomic, so a crash midway
 * leaves every file in one place or the other, and the next open moves the rest. 0, or -1
 * with err set. */
static int migrate_layout1(const char *store, char *err, size_t cap)
{
    for (int k = 0; k < 2; k++) {
        char dir[4096], data[4096], from[FILE_PATH], to[FILE_PATH];
        snprintf(dir, sizeof dir, "%s/%s", store, kind_dirs[k]);
        snprintf(data, sizeof data, "%s/%s", store, data_dirs[k]);
        DIR *d = opendir(dir);
        if (!d) {
            snprintf(err, cap, "cannot read %s: %s", dir, strerror(errno));
            return -1;
        }
        size_t moved = 0;
        struct stat st;
        for (struct dirent *e; (e = readdir(d));) {
            if (!layout1_data_name(e->d_name))
                continue;
            snprintf(from, sizeof from, "%s/%s", dir, e->d_name);
            snprintf(to, sizeof to, "%s/%s", data, e->d_name);
            if (!lstat(to, &st))
                continue; /* a second copy: the scan quarantines it */
            if (rename(from, to)) {
                if (errno == ENOENT)
                    continue; /* another replica opening the store moved it first */
                snprintf(err, cap, "cannot move %s to %s: %s", from, to, strerror(errno));
                closedir(d);
                return -1;
            }
            moved++;
        }
        closedir(d);
        if (moved && (sdfd_storefile_sync_dir(data) || sdfd_storefile_sync_dir(dir))) {
            snprintf(err, cap, "cannot sync %s: %s", dir, strerror(errno));
            return -1;
        }
        if (moved)
            sdfd_log("info", "store_migrate", "moved %zu data files from %s/ to %s/ (store "
                     "layout 1 to %d)", moved, kind_dirs[k], data_dirs[k], SDFD_STORE_LAYOUT);
    }
    return 0;
}

int sdfd_storelayout_settle(const char *dir, char *err, size_t cap)
{
    int layout = marker_layout(dir);
    if (layout > SDFD_STORE_LAYOUT) {
        snprintf(err, cap, "%s holds a store of layout %d, newer than this sdfd's (%d)", dir,
                 layout, SDFD_STORE_LAYOUT);
        return -1;
    }
    if (migrate_layout1(dir, err, cap)) /* also after a crash in a migration */
        return -1;
    if (layout == SDFD_STORE_LAYOUT)
        return 0;
    char text[64];
    int n = snprintf(text, sizeof text, "{\"store\":\"sdfd\",\"layout\":%d}\n",
                     SDFD_STORE_LAYOUT);
    return sdfd_storefile_write_atomic(dir, SDFD_STORE_MARKER, text, (size_t)n, err, cap) ? -1
                                                                                          : 0;
}
