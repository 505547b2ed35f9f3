/* npz.c - .npz archives read from memory (npz.h). The central directory is the index (a
 * member's local header only says where its bytes start), as every zip reader does: numpy's
 * writer puts the sizes there, while its local headers may hold zip64 placeholders. */
#include "ops/npz.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "sdf/sdf.h"

#define SIG_LOCAL 0x04034b50u
#define SIG_CENTRAL 0x02014b50u
#define SIG_END 0x06054b50u
#define SIG_END64 0x06064b50u
#define SIG_LOCATOR64 0x07064b50u
#define END_SIZE 22
#define CENTRAL_SIZE 46
#define LOCAL_SIZE 30

static int fail(char *err, size_t cap, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = snprintf(err, cap, "npz: ");
    vsnprintf(err + (n > 0 && (size_t)n < cap ? n : 0), cap - (n > 0 && (size_t)n < cap ? n : 0),
              fmt, ap);
    va_end(ap);
    return rc;
}

static uint32_t u16(const unsigned char *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8; }
static uint32_t u32(const unsigned char *p) { return u16(p) | u16(p + 2) << 16; }
static uint64_t u64(const unsigned char *p) { return u32(p) | (uint64_t)u32(p + 4) << 32; }

int sdfd_npz_sniff(const void *data, size_t len)
{
    return len >= 4 && u32(data) == SIG_LOCAL;
}

/* Where the central directory is (offset, size, entries), from the end records. */
static int find_directory(const unsigned char *z, size_t len, uint64_t *offset, uint64_t *size,
                          uint64_t *entries, char *err, size_t cap)
{
    if (len < END_SIZE)
        return fail(err, cap, SDF_ETRUNC, "%zu bytes are too few for a zip archive", len);
    size_t at = len - END_SIZE, lowest = len - END_SIZE > 0xffff ? len - END_SIZE - 0xffff : 0;
    while (u32(z + at) != SIG_END || at + END_SIZE + u16(z + at + 20) != len) {
        if (at == lowest)
            return fail(err, cap, SDF_EFORMAT, "no end of central directory: not a zip archive, "
                        "or cut short");
        at--;
    }
    const unsigned char *e = z + at;
    if (u16(e + 4) || u16(e + 6))
        return fail(err, cap, SDF_EFORMAT, "archives split over several disks are not read");
    *entries = u16(e + 10), *size = u32(e + 12), *offset = u32(e + 16);
    if (*entries == 0xffff || *size == 0xffffffffu || *offset == 0xffffffffu) {
        if (at < 20 || u32(e - 20) != SIG_LOCATOR64)
            return fail(err, cap, SDF_EFORMAT, "zip64 end record missing");
        uint64_t at64 = u64(e - 12);
        if (len < 56 || at64 > len - 56 || u32(z + at64) != SIG_END64)
            return fail(err, cap, SDF_EFORMAT, "zip64 end record out of place");
        *entries = u64(z + at64 + 32), *size = u64(z + at64 + 40), *offset = u64(z + at64 + 48);
    }
    if (*offset > len || *size > len - *offset)
        return fail(err, cap, SDF_ETRUNC, "the central directory lies past the archive's end");
    return 0;
}

typedef struct entry {
    uint32_t flags, method, crc, name_len;
    uint64_t packed, unpacked, local;
    const char *name;
} entry;

/* The zip64 extra field's values for the 32-bit fields that hold 0xffffffff. */
static int zip64_sizes(const unsigned char *x, size_t n, entry *e, char *err, size_t cap)
{
    while (n >= 4) {
        size_t id = u16(x), sz = u16(x + 2);
        if (sz > n - 4)
            break;
        if (id == 1) {
            const unsigned char *v = x + 4, *end = x + 4 + sz;
            uint64_t *fields[3] = {&e->unpacked, &e->packed, &e->local};
            for (int i = 0; i < 3; i++)
                if (*fields[i] == 0xffffffffu) {
                    if (end - v < 8)
                        return fail(err, cap, SDF_EFORMAT, "short zip64 field");
                    *fields[i] = u64(v), v += 8;
                }
            return 0;
        }
        x += 4 + sz, n -= 4 + sz;
    }
    if (e->unpacked == 0xffffffffu || e->packed == 0xffffffffu || e->local == 0xffffffffu)
        return fail(err, cap, SDF_EFORMAT, "zip64 sizes missing");
    return 0;
}

/* The central directory entry at *p (advanced past it). */
static int read_entry(const unsigned char *z, const unsigned char **p, const unsigned char *end,
                      entry *e, char *err, size_t cap)
{
    const unsigned char *c = *p;
    if (end - c < CENTRAL_SIZE || u32(c) != SIG_CENTRAL)
        return fail(err, cap, SDF_EFORMAT, "damaged central directory");
    size_t name = u16(c + 28), extra = u16(c + 30), comment = u16(c + 32);
    if ((size_t)(end - c) - CENTRAL_SIZE < name + extra + comment)
        return fail(err, cap, SDF_ETRUNC, "central directory entry cut short");
    *e = (entry){.flags = u16(c + 8), .method = u16(c + 10), .crc = u32(c + 16),
                 .packed = u32(c + 20), .unpacked = u32(c + 24), .local = u32(c + 42),
                 .name = (const char *)c + CENTRAL_SIZE, .name_len = (uint32_t)name};
    *p = c + CENTRAL_SIZE + name + extra + comment;
    (void)z;
    return zip64_sizes(c + CENTRAL_SIZE + name, extra, e, err, cap);
}

/* The member's bytes as stored, after its local header. */
static int member_bytes(const unsigned char *z, size_t len, const entry *e,
                        const unsigned char **data, char *err, size_t cap)
{
    if (e->local > len || len - e->local < LOCAL_SIZE || u32(z + e->local) != SIG_LOCAL)
        return fail(err, cap, SDF_EFORMAT, "member '%.*s' has no local header",
                    (int)e->name_len, e->name);
    uint64_t start = e->local + LOCAL_SIZE + u16(z + e->local + 26) + u16(z + e->local + 28);
    if (start > len || e->packed > len - start)
        return fail(err, cap, SDF_ETRUNC, "member '%.*s' runs past the archive's end",
                    (int)e->name_len, e->name);
    *data = z + start;
    return 0;
}

static int inflate_member(const unsigned char *in, const entry *e, unsigned char *out,
                          char *err, size_t cap)
{
    z_stream s = {0};
    if (inflateInit2(&s, -MAX_WBITS) != Z_OK)
        return fail(err, cap, SDF_ENOMEM, "out of memory for zlib");
    int rc = Z_OK;
    uint64_t in_left = e->packed, out_left = e->unpacked;
    s.next_in = (unsigned char *)in, s.next_out = out;
    while (rc == Z_OK) { /* zlib's counts are 32-bit: feed members over 4 GiB in parts */
        if (!s.avail_in && in_left) {
            s.avail_in = in_left > UINT32_MAX ? UINT32_MAX : (uInt)in_left;
            in_left -= s.avail_in;
        }
        if (!s.avail_out && out_left) {
            s.avail_out = out_left > UINT32_MAX ? UINT32_MAX : (uInt)out_left;
            out_left -= s.avail_out;
        }
        rc = inflate(&s, Z_FINISH);
        if (rc == Z_BUF_ERROR && (s.avail_in || in_left) && (s.avail_out || out_left))
            rc = Z_OK;
    }
    uint64_t made = e->unpacked - out_left - s.avail_out;
    inflateEnd(&s);
    if (rc != Z_STREAM_END || made != e->unpacked)
        return fail(err, cap, SDF_EFORMAT, "member '%.*s' does not inflate to its %llu bytes",
                    (int)e->name_len, e->name, (unsigned long long)e->unpacked);
    return 0;
}

static int is_wanted(const char *name, const char *const *wanted)
{
    for (size_t i = 0; wanted && wanted[i]; i++)
        if (!strcmp(name, wanted[i]))
            return 1;
    return !wanted;
}

static int add_member(const unsigned char *z, size_t len, const entry *e,
                      const char *const *wanted, size_t *budget, sdfd_npz_member *m, char *err,
                      size_t cap)
{
    if (e->flags & 1)
        return fail(err, cap, SDF_EFORMAT, "encrypted members are not read");
    if (e->method != 0 && e->method != 8)
        return fail(err, cap, SDF_EFORMAT, "member '%.*s' is compressed by method %u (only "
                    "stored and deflated members are read)", (int)e->name_len, e->name,
                    e->method);
    size_t n = e->name_len >= 4 && !memcmp(e->name + e->name_len - 4, ".npy", 4)
                   ? e->name_len - 4 : e->name_len;
    if (n > SDFD_NPZ_MAX_NAME)
        return fail(err, cap, SDF_ELIMIT, "a member's name is over %d bytes", SDFD_NPZ_MAX_NAME);
    memcpy(m->name, e->name, n), m->name[n] = '\0';
    if (!is_wanted(m->name, wanted))
        return 0; /* listed, never read */
    const unsigned char *stored = NULL;
    int rc = member_bytes(z, len, e, &stored, err, cap);
    if (rc)
        return rc;
    if (e->unpacked > *budget || (e->method == 0 && e->packed != e->unpacked))
        return fail(err, cap, e->unpacked > *budget ? SDF_ELIMIT : SDF_EFORMAT,
                    "member '%s' declares %llu bytes: %s", m->name,
                    (unsigned long long)e->unpacked,
                    e->unpacked > *budget ? "more than the server reads" : "not its stored size");
    *budget -= e->unpacked;
    m->data = stored, m->size = e->unpacked;
    if (e->method == 8) {
        if (!(m->owned = malloc(e->unpacked ? e->unpacked : 1)))
            return fail(err, cap, SDF_ENOMEM, "out of memory for member '%s'", m->name);
        if ((rc = inflate_member(stored, e, m->owned, err, cap)))
            return rc;
        m->data = m->owned;
    }
    uLong crc = crc32_z(0L, Z_NULL, 0);
    if (crc32_z(crc, m->data, m->size) != e->crc)
        return fail(err, cap, SDF_EFORMAT, "member '%s' fails its CRC-32", m->name);
    return 0;
}

int sdfd_npz_read(const void *data, size_t len, const char *const *wanted, size_t max_bytes,
                  sdfd_npz *out, char *err, size_t cap)
{
    memset(out, 0, sizeof *out);
    const unsigned char *z = data;
    uint64_t offset = 0, size = 0, entries = 0;
    int rc = find_directory(z, len, &offset, &size, &entries, err, cap);
    if (!rc && entries > SDFD_NPZ_MAX_MEMBERS)
        rc = fail(err, cap, SDF_ELIMIT, "%llu members, more than %d",
                  (unsigned long long)entries, SDFD_NPZ_MAX_MEMBERS);
    const unsigned char *p = z + (rc ? 0 : offset), *end = p + (rc ? 0 : size);
    size_t budget = max_bytes;
    for (uint64_t i = 0; !rc && i < entries; i++) {
        entry e = {0};
        if (!(rc = read_entry(z, &p, end, &e, err, cap)))
            rc = add_member(z, len, &e, wanted, &budget, &out->members[out->count++], err, cap);
    }
    for (size_t i = 0; !rc && i < out->count; i++)
        for (size_t k = 0; k < i; k++)
            if (!strcmp(out->members[i].name, out->members[k].name))
                rc = fail(err, cap, SDF_EFORMAT, "member '%s' appears twice",
                          out->members[i].name);
    return rc;
}

const sdfd_npz_member *sdfd_npz_find(const sdfd_npz *z, const char *name)
{
    for (size_t i = 0; i < z->count; i++)
        if (!strcmp(z->members[i].name, name) && z->members[i].data)
            return &z->members[i];
    return NULL;
}

void sdfd_npz_free(sdfd_npz *z)
{
    for (size_t i = 0; i < z->count; i++)
        free(z->members[i].owned);
    memset(z, 0, sizeof *z);
}
