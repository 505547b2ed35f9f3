/* storefile.h - the file primitives the store (store.h) is built from: a write that readers
 * see whole or not at all, a whole-file read with its size checked before anything is
 * allocated, and a directory's fsync. Plain POSIX on paths; they know nothing of items, so
 * the store's rules (which file, which error to answer) stay in store.c. */
#ifndef SDFD_STOREFILE_H
#define SDFD_STOREFILE_H

#include <stddef.h>
#include <sys/stat.h>

/* Write dir/file so that a reader sees the old or the new bytes, never a part: a temporary
 * `.tmp-XXXXXX` in dir, written, fsynced, renamed over the final name, and dir fsynced. 0, or
 * the errno value of the step that failed (the temporary is removed), with err saying which
 * file could not be written and why. */
int sdfd_storefile_write_atomic(const char *dir, const char *file, const void *data, size_t n,
                                char *err, size_t cap);

/* Read a whole regular file of at most `max` bytes (and exactly `expect`, unless SIZE_MAX)
 * into *out (malloc'd, NUL-terminated; *n bytes) and its stat into *st. 0, or an errno value:
 * EFBIG (the size is not the one expected, or over max), EISDIR (not a regular file), or
 * the system's (ENOENT, EACCES, EIO ...). */
int sdfd_storefile_read(const char *path, size_t max, size_t expect, char **out, size_t *n,
                        struct stat *st);

/* fsync the directory, so that the names created, renamed or removed in it are durable.
 * 0, or -1 with errno set. */
int sdfd_storefile_sync_dir(const char *dir);

#endif
