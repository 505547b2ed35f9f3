/* npy.c - NumPy .npy header codec (format versions 1.0, 2.0 and 3.0), no I/O.
 *
 * A .npy file is the magic "\x93NUMPY", a version, a little-endian header length (2 bytes
 * in 1.0, 4 in 2.0/3.0), then a Python dict literal such as
 *   {'descr': '<f4', 'fortran_order': False, 'shape': (1000, 3), }
 * padded with spaces to a multiple of 64 bytes and ended by '\n', then the raw data.
 * We accept what sdfd needs: little-endian float32/float64 (and, when asked, integers) in C
 * order, up to 4 dimensions, with exactly the bytes the shape calls for. Every length is checked before use. */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/diag.h"

#define MAGIC "\x93NUMPY"
#define MAGIC_LEN 6

/* Find `'key':` in the dict text and return the position just after the colon. */
static const char *find_key(const char *dict, size_t len, const char *key)
{
    char pattern[32];
    int n = snprintf(pattern, sizeof pattern, "'%s'", key);
    for (size_t i = 0; i + (size_t)n <= len; i++) {
        if (memcmp(dict + i, pattern, (size_t)n))
            continue;
        const char *p = dict + i + n, *end = dict + len;
        while (p < end && *p == ' ')
            p++;
        return p < end && *p == ':' ? p + 1 : NULL;
    }
    return NULL;
}

static const char *skip_spaces(const char *p, const char *end)
{
    while (p < end && *p == ' ')
        p++;
    return p;
}

/* The descr: '<f4' or '<f8', and with `integers` also little-endian (or, for one byte,
 * byte-order-free '|') signed and unsigned integers of 1, 2, 4 or 8 bytes. */
static int parse_descr(const char *dict, size_t len, int integers, sdf_npy_info *info,
                       sdf_diag *diag)
{
    const char *end = dict + len, *p = find_key(dict, len, "descr");
    if (!p)
        return sdf__diag_set(diag, SDF_EPARSE, 0, 10, "npy header has no 'descr'");
    p = skip_spaces(p, end);
    if (end - p >= 5 && (p[0] == '\'' || p[0] == '"') && p[4] == p[0]) {
        char order = p[1], kind = p[2], size = p[3];
        size_t bytes = size == '1' ? 1 : size == '2' ? 2 : size == '4' ? 4 : size == '8' ? 8 : 0;
        int little = order == '<' || (order == '|' && bytes == 1);
        if (order == '<' && kind == 'f' && (bytes == 4 || bytes == 8)) {
            info->kind = 'f', info->itemsize = bytes;
            info->dtype = bytes == 4 ? SDF_NPY_F32 : SDF_NPY_F64;
            return 0;
        }
        if (integers && little && bytes && (kind == 'i' || kind == 'u')) {
            info->kind = kind, info->itemsize = bytes;
            return 0;
        }
    }
    return sdf__diag_set(diag, SDF_EFORMAT, 0, (long long)(p - dict) + 10,
                         integers ? "npy dtype must be little-endian float32, float64 or an "
                                    "integer type ('<f4', '<f8', '<i8', '<u4', ...)"
                                  : "npy dtype must be little-endian float32 ('<f4') or "
                                    "float64 ('<f8')");
}

static int parse_order(const char *dict, size_t len, sdf_diag *diag)
{
    const char *end = dict + len, *p = find_key(dict, len, "fortran_order");
    if (!p)
        return sdf__diag_set(diag, SDF_EPARSE, 0, 10, "npy header has no 'fortran_order'");
    p = skip_spaces(p, end);
    if (end - p >= 5 && !memcmp(p, "False", 5))
        return 0;
    return sdf__diag_set(diag, SDF_EFORMAT, 0, (long long)(p - dict) + 10,
                         "npy arrays must be in C order (fortran_order False)");
}

static int parse_shape(const char *dict, size_t len, sdf_npy_info *info, sdf_diag *diag)
{
    const char *end = dict + len, *p = find_key(dict, len, "shape");
    if (!p)
        return sdf__diag_set(diag, SDF_EPARSE, 0, 10, "npy header has no 'shape'");
    p = skip_spaces(p, end);
    if (p >= end || *p != '(')
        return sdf__diag_set(diag, SDF_EPARSE, 0, (long long)(p - dict) + 10,
                             "npy shape is not a tuple");
    p++;
    info->ndim = 0;
    for (;;) {
        p = skip_spaces(p, end);
        if (p < end && *p == ')')
            return 0;
        if (p >= end || !isdigit((unsigned char)*p))
            break;
        if (info->ndim == SDF_NPY_MAX_DIMS)
            return sdf__diag_set(diag, SDF_ELIMIT, 0, (long long)(p - dict) + 10,
                                 "npy arrays of more than %d dimensions are not supported",
                                 SDF_NPY_MAX_DIMS);
        unsigned long long v = 0;
        while (p < end && isdigit((unsigned char)*p)) {
            if (v > (SIZE_MAX - 9) / 10)
                return sdf__diag_set(diag, SDF_ELIMIT, 0, (long long)(p - dict) + 10,
                                     "npy dimension too large");
            v = v * 10 + (unsigned)(*p++ - '0');
        }
        info->shape[info->ndim++] = (size_t)v;
        p = skip_spaces(p, end);
        if (p < end && *p == ',')
            p++;
    }
    return sdf__diag_set(diag, SDF_EPARSE, 0, (long long)(p - dict) + 10, "malformed npy shape");
}

static int parse(const void *data, size_t size, int integers, sdf_npy_info *info,
                 sdf_diag *diag)
{
    sdf__diag_clear(diag);
    if (!info || (!data && size))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "invalid argument");
    memset(info, 0, sizeof *info);
    const unsigned char *u = data;
    if (size < MAGIC_LEN + 2 || memcmp(u, MAGIC, MAGIC_LEN))
        return sdf__diag_set(diag, size < MAGIC_LEN + 2 ? SDF_ETRUNC : SDF_EFORMAT, 0, 0,
                             "not a .npy file (magic \\x93NUMPY expected)");
    unsigned major = u[6];
    size_t len_bytes = major == 1 ? 2 : 4;
    if (major < 1 || major > 3)
        return sdf__diag_set(diag, SDF_EFORMAT, 0, 6, "unsupported npy version %u", major);
    if (size < 8 + len_bytes)
        return sdf__diag_set(diag, SDF_ETRUNC, 0, 8, "npy header length is cut off");
    size_t header_len = (size_t)u[8] | (size_t)u[9] << 8;
    if (len_bytes == 4)
        header_len |= (size_t)u[10] << 16 | (size_t)u[11] << 24;
    size_t offset = 8 + len_bytes;
    if (header_len > size - offset)
        return sdf__diag_set(diag, SDF_ETRUNC, 0, (long long)offset,
                             "npy header declares %zu bytes but only %zu follow", header_len,
                             size - offset);
    const char *dict = (const char *)u + offset;
    int rc = parse_descr(dict, header_len, integers, info, diag);
    if (!rc)
        rc = parse_order(dict, header_len, diag);
    if (!rc)
        rc = parse_shape(dict, header_len, info, diag);
    if (rc)
        return rc;
    info->data_offset = offset + header_len;
    size_t avail = size - info->data_offset, elems = 1;
    for (int i = 0; i < info->ndim; i++) {
        if (info->shape[i] && elems > avail / info->shape[i])
            return sdf__diag_set(diag, SDF_ETRUNC, 0, (long long)info->data_offset,
                                 "npy shape needs more data than the %zu bytes present", avail);
        elems *= info->shape[i];
    }
    if (elems > avail / info->itemsize)
        return sdf__diag_set(diag, SDF_ETRUNC, 0, (long long)info->data_offset,
                             "npy shape needs %zu elements but only %zu bytes follow", elems,
                             avail);
    info->data_bytes = elems * info->itemsize;
    if (info->data_bytes != avail)
        return sdf__diag_set(diag, SDF_EPARSE, 0, (long long)(info->data_offset + info->data_bytes),
                             "%zu bytes follow the npy data", avail - info->data_bytes);
    return 0;
}

int sdf_npy_parse(const void *data, size_t size, sdf_npy_info *info, sdf_diag *diag)
{
    return parse(data, size, 0, info, diag);
}

int sdf_npy_parse_numeric(const void *data, size_t size, sdf_npy_info *info, sdf_diag *diag)
{
    return parse(data, size, 1, info, diag);
}

long sdf_npy_write_header(char *dst, size_t cap, int ndim, const size_t *shape)
{
    return sdf_npy_write_header_descr(dst, cap, "'<f4'", ndim, shape);
}

long sdf_npy_write_header_descr(char *dst, size_t cap, const char *descr, int ndim,
                                const size_t *shape)
{
    if (ndim < 1 || ndim > SDF_NPY_MAX_DIMS || !shape || !dst || !descr || strlen(descr) > 192)
        return SDF_EINVAL;
    char dict[320], dims[96] = "";
    size_t used = 0;
    for (int i = 0; i < ndim; i++)
        used += (size_t)snprintf(dims + used, sizeof dims - used, "%zu,%s", shape[i],
                                 i + 1 < ndim ? " " : "");
    if (ndim > 1)
        dims[used - 1] = '\0'; /* "(3, 4)" but "(3,)" */
    int n = snprintf(dict, sizeof dict, "{'descr': %s, 'fortran_order': False, 'shape': (%s), }",
                     descr, dims);
    size_t total = 10 + (size_t)n + 1;
    total = (total + 63) / 64 * 64;
    if (total > cap)
        return SDF_ELIMIT;
    memcpy(dst, MAGIC, MAGIC_LEN);
    dst[6] = 1;
    dst[7] = 0;
    size_t header_len = total - 10;
    dst[8] = (char)(header_len & 0xff);
    dst[9] = (char)(header_len >> 8);
    memcpy(dst + 10, dict, (size_t)n);
    memset(dst + 10 + n, ' ', total - 10 - (size_t)n - 1);
    dst[total - 1] = '\n';
    return (long)total;
}
