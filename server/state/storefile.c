/* storefile.c - atomic writes, checked whole-file reads and directory syncs (storefile.h). */
#include "state/storefile.h"

#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* A path: a directory (under 4096) and a name. */
#define FILE_PATH 4608

int sdfd_storefile_sync_dir(const char *dir)
{
    int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = fsync(fd);
    int e = errno;
    close(fd);
    errno = e;
    return rc;
}

/* 0, or an errno value. */
static int write_all(int fd, const void *data, size_t n)
{
    const char *p = data;
    while (n) {
        ssize_t w = write(fd, p, n > (1u << 30) ? (1u << 30) : n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return w < 0 ? errno : EIO;
        p += w, n -= (size_t)w;
    }
    return 0;
}

int sdfd_storefile_write_atomic(const char *dir, const char *file, const void *data, size_t n,
                                char *err, size_t cap)
{
    char tmp[FILE_PATH], final[FILE_PATH];
    snprintf(tmp, sizeof tmp, "%s/.tmp-XXXXXX", dir);
    snprintf(final, sizeof final, "%s/%s", dir, file);
    int fd = mkstemp(tmp);
    if (fd < 0) {
        int e = errno;
        snprintf(err, cap, "cannot create a file in %s: %s", dir, strerror(e));
        return e;
    }
    int e = fchmod(fd, 0644) ? errno : 0;
    if (!e)
        e = write_all(fd, data, n);
    if (!e && fsync(fd))
        e = errno;
    if (close(fd) && !e) /* NFS may report a failed write only here */
        e = errno;
    if (!e && rename(tmp, final))
        e = errno;
    if (!e && sdfd_storefile_sync_dir(dir))
        e = errno;
    if (e) {
        unlink(tmp);
        snprintf(err, cap, "cannot write %s: %s", final, strerror(e));
    }
    return e;
}

int sdfd_storefile_read(const char *path, size_t max, size_t expect, char **out, size_t *n,
                        struct stat *st)
{
    *out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return errno;
    int e = 0;
    if (fstat(fd, st))
        e = errno;
    else if (!S_ISREG(st->st_mode))
        e = EISDIR;
    else if ((size_t)st->st_size > max || (expect != SIZE_MAX && (size_t)st->st_size != expect))
        e = EFBIG;
    char *buf = e ? NULL : malloc((size_t)st->st_size + 1);
    if (!e && !buf)
        e = ENOMEM;
    size_t got = 0;
    while (!e && got < (size_t)st->st_size) {
        ssize_t r = read(fd, buf + got, (size_t)st->st_size - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            e = r < 0 ? errno : EFBIG;
        else
            got += (size_t)r;
    }
    close(fd);
    if (e) {
        free(buf);
        return e;
    }
    buf[got] = '\0';
    *out = buf, *n = got;
    return 0;
}
