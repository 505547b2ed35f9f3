/* npz.h - NumPy .npz archives read from memory: a zip file whose members are .npy files
 * (numpy.savez stores them, numpy.savez_compressed deflates them).
 *
 * Only what those two write is read: members stored (method 0) or deflated (method 8, through
 * zlib), found through the central directory, with zip64 sizes where numpy writes them. The
 * archive is checked before anything is allocated: every offset and size lies inside it, a
 * member's inflated size is declared and at most `max_bytes` in total, and the inflated bytes
 * must match that size and the member's CRC-32. Encrypted, split or multi-disk archives are
 * refused. Nothing is global; any thread. */
#ifndef SDFD_NPZ_H
#define SDFD_NPZ_H

#include <stddef.h>

#define SDFD_NPZ_MAX_MEMBERS 64
#define SDFD_NPZ_MAX_NAME 64

typedef struct sdfd_npz_member {
    char name[SDFD_NPZ_MAX_NAME + 1]; /* without the ".npy" numpy adds */
    const unsigned char *data;        /* the .npy bytes: in the archive, or in `owned` */
    size_t size;
    unsigned char *owned; /* inflated bytes (malloc'd), or NULL */
} sdfd_npz_member;

typedef struct sdfd_npz {
    sdfd_npz_member members[SDFD_NPZ_MAX_MEMBERS];
    size_t count;
} sdfd_npz;

/* Does `data` start like a zip file ("PK\3\4")? */
int sdfd_npz_sniff(const void *data, size_t len);

/* Read the archive's members named in `wanted` (NULL-terminated, ".npy" left off; NULL: all),
 * pointing into `data` (which must outlive *out) or into inflated copies; the others are
 * listed with no data and never inflated. 0, or an SDF_E* code with err set (SDF_EFORMAT: not an npz sdfd can
 * read; SDF_ETRUNC: cut short; SDF_ELIMIT: over max_bytes or SDFD_NPZ_MAX_MEMBERS;
 * SDF_ENOMEM). *out is always safe to free. */
int sdfd_npz_read(const void *data, size_t len, const char *const *wanted, size_t max_bytes,
                  sdfd_npz *out, char *err, size_t cap);

/* The member named `name` (".npy" left off), or NULL. */
const sdfd_npz_member *sdfd_npz_find(const sdfd_npz *z, const char *name);

void sdfd_npz_free(sdfd_npz *z);

#endif
