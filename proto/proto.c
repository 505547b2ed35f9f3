/* proto.c - the binary protocol codec (see proto.h and PROTOCOL.md). Little-endian access
 * goes through byte helpers, so the codec is correct on any host and never reads unaligned
 * words. Every decoder checks lengths before it reads. */
#include "proto.h"

#include <string.h>
#include <strings.h>

static const unsigned char magic[4] = {'S', 'D', 'F', 'P'};

static uint16_t get16(const unsigned char *p) { return (uint16_t)(p[0] | p[1] << 8); }

static uint32_t get32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get64(const unsigned char *p) { return get32(p) | (uint64_t)get32(p + 4) << 32; }

static void put16(unsigned char *p, uint16_t v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
}

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static void put64(unsigned char *p, uint64_t v)
{
    put32(p, (uint32_t)v);
    put32(p + 4, (uint32_t)(v >> 32));
}

static size_t pad4(size_t n) { return (n + 3) & ~(size_t)3; }

static int fail(const char **reason, int code, const char *why)
{
    if (reason)
        *reason = why;
    return code;
}

static const char *const mode_names[] = {"signed",   "distance", "gradient",
                                         "closest",  "filtered", "filtered-gradient"};

int sdf_proto_mode_from_name(const char *name, sdf_proto_mode *out)
{
    for (int m = 0; m <= SDF_MODE_LAST && name; m++) {
        if (!strcasecmp(name, mode_names[m])) { /* any case, as sdf.h's names */
            *out = (sdf_proto_mode)m;
            return 0;
        }
    }
    return SDF_EINVAL;
}

const char *sdf_proto_mode_name(sdf_proto_mode mode)
{
    return mode <= SDF_MODE_LAST ? mode_names[mode] : "?";
}

unsigned sdf_proto_words(sdf_proto_mode mode)
{
    static const unsigned words[] = {1, 1, 4, 5, 1, 4};
    return mode <= SDF_MODE_LAST ? words[mode] : 0;
}

int sdf_proto_mode_filtered(sdf_proto_mode mode)
{
    return mode == SDF_MODE_FILTERED || mode == SDF_MODE_FILTERED_GRADIENT;
}

/* ---- header ------------------------------------------------------------------------------ */

int sdf_proto_decode_header(const void *buf, size_t size, uint32_t max_payload,
                            sdf_proto_header *h, const char **reason)
{
    const unsigned char *p = buf;
    if (size < SDF_PROTO_HEADER_SIZE)
        return fail(reason, SDF_ETRUNC, "frame header is shorter than 16 bytes");
    if (memcmp(p, magic, 4))
        return fail(reason, SDF_EPROTO, "bad magic (expected \"SDFP\")");
    h->version = p[4];
    h->type = p[5];
    h->flags = get16(p + 6);
    h->request_id = get32(p + 8);
    h->length = get32(p + 12);
    if (h->version != SDF_PROTO_VERSION)
        return fail(reason, SDF_EPROTO, "unsupported protocol version (this server speaks 1)");
    if (h->length > max_payload)
        return fail(reason, SDF_ELIMIT, "frame payload is larger than max_payload");
    return 0;
}

void sdf_proto_encode_header(void *dst, uint8_t type, uint32_t request_id, uint32_t length)
{
    unsigned char *p = dst;
    memcpy(p, magic, 4);
    p[4] = SDF_PROTO_VERSION;
    p[5] = type;
    put16(p + 6, 0);
    put32(p + 8, request_id);
    put32(p + 12, length);
}

/* ---- QUERY ------------------------------------------------------------------------------- */

/* Bytes of the FILTER block, 0 for other modes. */
static size_t filter_size(const sdf_proto_query *q)
{
    if (!sdf_proto_mode_filtered(q->mode))
        return 0;
    return SDF_PROTO_FILTER_SIZE + pad4(q->filter.smooth.shape == SDF_VOLUME_MESH ? q->volume_name_len : 0);
}

size_t sdf_proto_query_size(const sdf_proto_query *q)
{
    if (q->name_len == 0 || q->name_len > SDF_PROTO_MAX_NAME)
        return 0;
    if (sdf_proto_mode_filtered(q->mode) && q->filter.smooth.shape == SDF_VOLUME_MESH &&
        (q->volume_name_len == 0 || q->volume_name_len > SDF_PROTO_MAX_NAME))
        return 0;
    return 8 + pad4(q->name_len) + filter_size(q) + 12 * (size_t)q->count;
}

/* The FILTER block (PROTOCOL.md): kernel, flags, reserved, samples, cap, a, b, seed. */
enum { FILTER_GRID = 1, FILTER_UNSIGNED = 2, FILTER_WIDE_BUMP = 4, FILTER_SAMPLE_GRADIENT = 8 };

static double get_f64(const unsigned char *p)
{
    uint64_t bits = get64(p);
    double v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

static void put_f64(unsigned char *p, double v)
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    put64(p, bits);
}

/* Decode the fixed part of a FILTER block (the volume name, if any, follows it). Bits and
 * bytes the protocol reserves must be 0, so that a later version's meaning for them is never
 * silently ignored: SDF_EINVAL with *reason, else 0. */
static int decode_filter(const unsigned char *p, sdf_proto_query *q, const char **reason)
{
    if (p[1] & ~(FILTER_GRID | FILTER_UNSIGNED | FILTER_WIDE_BUMP | FILTER_SAMPLE_GRADIENT))
        return fail(reason, SDF_EINVAL, "FILTER flags: only bits 0-3 are defined; the rest must "
                                        "be 0");
    if (get32(p + 108) != 0)
        return fail(reason, SDF_EINVAL, "FILTER bytes 108-111 are reserved and must be 0");
    if (p[2] != SDF_VOLUME_MESH && p[3] != 0)
        return fail(reason, SDF_EINVAL, "FILTER volume mesh name length must be 0 unless the "
                                        "smoothing volume is a mesh (3)");
    sdf_filter_options *f = &q->filter;
    *f = (sdf_filter_options){0};
    f->kernel = (sdf_kernel)p[0];
    f->grid = (p[1] & FILTER_GRID) != 0;
    f->unsigned_integrand = (p[1] & FILTER_UNSIGNED) != 0;
    f->allow_wide_bump = (p[1] & FILTER_WIDE_BUMP) != 0;
    f->sample_gradient = (p[1] & FILTER_SAMPLE_GRADIENT) != 0;
    f->smooth.shape = (sdf_volume_shape)p[2];
    q->volume_name_len = f->smooth.shape == SDF_VOLUME_MESH ? p[3] : 0;
    uint32_t samples = get32(p + 4);
    f->samples = samples > SDF_FILTER_MAX_SAMPLES ? -1 : (int)samples; /* -1: refused later */
    f->cap = get_f64(p + 8);
    f->a = get_f64(p + 16);
    f->b = get_f64(p + 24);
    f->seed = get64(p + 32);
    f->smooth.depth = get_f64(p + 40);
    f->smooth.scale = get_f64(p + 48);
    double x[6];
    for (int i = 0; i < 6; i++)
        x[i] = get_f64(p + 56 + 8 * i);
    uint32_t min_samples = get32(p + 104);
    f->min_samples = min_samples > SDF_FILTER_MAX_SAMPLES ? -1 : (int)min_samples;
    f->medial = get_f64(p + 112);
    if (f->smooth.shape == SDF_VOLUME_SPHERE) {
        memcpy(f->smooth.center, x, sizeof f->smooth.center);
        f->smooth.radius = x[3];
    } else if (f->smooth.shape == SDF_VOLUME_BOX) {
        memcpy(f->smooth.lo, x, sizeof f->smooth.lo);
        memcpy(f->smooth.hi, x + 3, sizeof f->smooth.hi);
    }
    return 0;
}

static void encode_filter(unsigned char *p, const sdf_proto_query *q)
{
    const sdf_filter_options *f = &q->filter;
    int mesh = f->smooth.shape == SDF_VOLUME_MESH;
    memset(p, 0, SDF_PROTO_FILTER_SIZE);
    p[0] = (unsigned char)f->kernel;
    p[1] = (unsigned char)((f->grid ? FILTER_GRID : 0) |
                           (f->unsigned_integrand ? FILTER_UNSIGNED : 0) |
                           (f->allow_wide_bump ? FILTER_WIDE_BUMP : 0) |
                           (f->sample_gradient ? FILTER_SAMPLE_GRADIENT : 0));
    p[2] = (unsigned char)f->smooth.shape;
    p[3] = (unsigned char)(mesh ? q->volume_name_len : 0);
    put32(p + 4, f->samples < 0 ? 0 : (uint32_t)f->samples);
    put_f64(p + 8, f->cap);
    put_f64(p + 16, f->a);
    put_f64(p + 24, f->b);
    put64(p + 32, f->seed);
    put_f64(p + 40, f->smooth.depth);
    put_f64(p + 48, f->smooth.scale);
    double x[6] = {0, 0, 0, 0, 0, 0};
    if (f->smooth.shape == SDF_VOLUME_SPHERE) {
        memcpy(x, f->smooth.center, sizeof f->smooth.center);
        x[3] = f->smooth.radius;
    } else if (f->smooth.shape == SDF_VOLUME_BOX) {
        memcpy(x, f->smooth.lo, sizeof f->smooth.lo);
        memcpy(x + 3, f->smooth.hi, sizeof f->smooth.hi);
    }
    for (int i = 0; i < 6; i++)
        put_f64(p + 56 + 8 * i, x[i]);
    put32(p + 104, f->min_samples < 0 ? 0 : (uint32_t)f->min_samples);
    put32(p + 108, 0);
    put_f64(p + 112, f->medial);
    if (mesh) {
        memset(p + SDF_PROTO_FILTER_SIZE, 0, pad4(q->volume_name_len));
        memcpy(p + SDF_PROTO_FILTER_SIZE, q->volume_name, q->volume_name_len);
    }
}

int sdf_proto_decode_query(const void *payload, size_t size, uint32_t max_points,
                           sdf_proto_query *q, const char **reason)
{
    const unsigned char *p = payload;
    if (size < 8)
        return fail(reason, SDF_EPROTO, "QUERY payload is shorter than its 8-byte prefix");
    q->mode = (sdf_proto_mode)p[0];
    q->sign = (sdf_sign_method)p[1];
    q->name_len = get16(p + 2);
    q->count = get32(p + 4);
    if (p[0] > SDF_MODE_LAST)
        return fail(reason, SDF_EINVAL, "unknown mode (0 signed, 1 distance, 2 gradient, "
                                        "3 closest, 4 filtered, 5 filtered-gradient)");
    if (p[1] > SDF_SIGN_NONE)
        return fail(reason, SDF_EINVAL,
                    "unknown sign (0 auto, 1 pseudonormal, 2 winding, 3 raycast, 4 none)");
    if (q->name_len == 0 || q->name_len > SDF_PROTO_MAX_NAME)
        return fail(reason, SDF_EPROTO, "mesh name length must be 1..255");
    if (q->count > max_points)
        return fail(reason, SDF_ELIMIT, "more points than max_points");
    q->name = (const char *)p + 8;
    size_t at = 8 + pad4(q->name_len);
    q->filter = (sdf_filter_options){0};
    q->volume_name = NULL;
    q->volume_name_len = 0;
    if (sdf_proto_mode_filtered(q->mode)) {
        if (size < at + SDF_PROTO_FILTER_SIZE)
            return fail(reason, SDF_EPROTO, "QUERY payload is too short for its FILTER block");
        int rc = decode_filter(p + at, q, reason);
        if (rc)
            return rc;
        if (q->filter.smooth.shape == SDF_VOLUME_MESH) {
            if (q->volume_name_len == 0)
                return fail(reason, SDF_EPROTO, "smoothing mesh name length must be 1..255");
            q->volume_name = (const char *)p + at + SDF_PROTO_FILTER_SIZE;
        }
    }
    if (size != sdf_proto_query_size(q))
        return fail(reason, SDF_EPROTO,
                    "QUERY payload length is not 8 + pad4(name_length) [+ the FILTER block of a "
                    "filtered mode] + 12 * count");
    at += filter_size(q);
    q->points = p + at;
    return 0;
}

/* The header and the 8-byte prefix that QUERY and VOLUME_QUERY share: two code bytes, the
 * name's length, the point count, then the name padded to 4. Returns the payload start. */
static unsigned char *put_query_prefix(void *dst, uint8_t type, uint32_t request_id,
                                       size_t payload, uint8_t code0, uint8_t code1,
                                       const char *name, size_t name_len, uint32_t count)
{
    unsigned char *p = dst;
    sdf_proto_encode_header(p, type, request_id, (uint32_t)payload);
    p += SDF_PROTO_HEADER_SIZE;
    p[0] = code0;
    p[1] = code1;
    put16(p + 2, (uint16_t)name_len);
    put32(p + 4, count);
    memset(p + 8, 0, pad4(name_len));
    memcpy(p + 8, name, name_len);
    return p;
}

size_t sdf_proto_encode_query(void *dst, size_t cap, uint32_t request_id, const sdf_proto_query *q)
{
    size_t payload = sdf_proto_query_size(q);
    if (!payload || payload > UINT32_MAX || SDF_PROTO_HEADER_SIZE + payload > cap)
        return 0;
    unsigned char *p = put_query_prefix(dst, SDF_PROTO_QUERY, request_id, payload,
                                        (uint8_t)q->mode, (uint8_t)q->sign, q->name, q->name_len,
                                        q->count);
    size_t at = 8 + pad4(q->name_len);
    if (sdf_proto_mode_filtered(q->mode))
        encode_filter(p + at, q);
    at += filter_size(q);
    memcpy(p + at, q->points, 12 * (size_t)q->count);
    return SDF_PROTO_HEADER_SIZE + payload;
}

/* ---- VOLUME_QUERY ------------------------------------------------------------------------ */

/* The interpolation byte's values, in wire order (PROTOCOL.md): 0 and 1 came first and keep
 * their meaning, so the byte is not sdf_volume_filter's own numbering. */
static const sdf_volume_filter wire_filters[] = {SDF_VOLUME_TRILINEAR, SDF_VOLUME_NEAREST,
                                                 SDF_VOLUME_HERMITE, SDF_VOLUME_DEFAULT};
#define WIRE_FILTERS (sizeof wire_filters / sizeof wire_filters[0])

/* The wire byte of an interpolation, or -1 for a value the protocol has no byte for. */
static int wire_filter(sdf_volume_filter f)
{
    for (size_t i = 0; i < WIRE_FILTERS; i++)
        if (wire_filters[i] == f)
            return (int)i;
    return -1;
}

size_t sdf_proto_volume_query_size(const sdf_proto_volume_query *q)
{
    if (q->name_len == 0 || q->name_len > SDF_PROTO_MAX_NAME)
        return 0;
    return 8 + pad4(q->name_len) + 12 * (size_t)q->count;
}

int sdf_proto_decode_volume_query(const void *payload, size_t size, uint32_t max_points,
                                  sdf_proto_volume_query *q, const char **reason)
{
    const unsigned char *p = payload;
    if (size < 8)
        return fail(reason, SDF_EPROTO, "VOLUME_QUERY payload is shorter than its 8-byte prefix");
    if (p[0] > 1)
        return fail(reason, SDF_EINVAL, "unknown volume mode (0 value, 1 value and gradient)");
    if (p[1] >= WIRE_FILTERS)
        return fail(reason, SDF_EINVAL,
                    "unknown interpolation (0 trilinear, 1 nearest, 2 hermite, 3 default)");
    q->gradient = p[0];
    q->interpolation = wire_filters[p[1]];
    q->name_len = get16(p + 2);
    q->count = get32(p + 4);
    if (q->name_len == 0 || q->name_len > SDF_PROTO_MAX_NAME)
        return fail(reason, SDF_EPROTO, "volume name length must be 1..255");
    if (q->count > max_points)
        return fail(reason, SDF_ELIMIT, "more points than max_points");
    if (size != sdf_proto_volume_query_size(q))
        return fail(reason, SDF_EPROTO,
                    "VOLUME_QUERY payload length is not 8 + pad4(name_length) + 12 * count");
    q->name = (const char *)p + 8;
    q->points = p + 8 + pad4(q->name_len);
    return 0;
}

size_t sdf_proto_encode_volume_query(void *dst, size_t cap, uint32_t request_id,
                                     const sdf_proto_volume_query *q)
{
    size_t payload = sdf_proto_volume_query_size(q);
    int interpolation = wire_filter(q->interpolation);
    if (!payload || payload > UINT32_MAX || SDF_PROTO_HEADER_SIZE + payload > cap ||
        interpolation < 0)
        return 0;
    unsigned char *p = put_query_prefix(dst, SDF_PROTO_VOLUME_QUERY, request_id, payload,
                                        q->gradient ? 1 : 0, (uint8_t)interpolation, q->name,
                                        q->name_len, q->count);
    memcpy(p + 8 + pad4(q->name_len), q->points, 12 * (size_t)q->count);
    return SDF_PROTO_HEADER_SIZE + payload;
}

/* ---- RESULT ------------------------------------------------------------------------------ */

size_t sdf_proto_encode_result_head(void *dst, uint32_t request_id, sdf_proto_mode mode,
                                    uint32_t count)
{
    unsigned char *p = dst;
    unsigned words = sdf_proto_words(mode);
    uint64_t payload = SDF_PROTO_RESULT_PREFIX + 4ull * words * count;
    sdf_proto_encode_header(p, SDF_PROTO_RESULT, request_id, (uint32_t)payload);
    p += SDF_PROTO_HEADER_SIZE;
    p[0] = (unsigned char)mode;
    p[1] = (unsigned char)words;
    put16(p + 2, 0);
    put32(p + 4, count);
    return SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX;
}

int sdf_proto_decode_result(const void *payload, size_t size, sdf_proto_result *r,
                            const char **reason)
{
    const unsigned char *p = payload;
    if (size < SDF_PROTO_RESULT_PREFIX)
        return fail(reason, SDF_EPROTO, "RESULT payload is shorter than its 8-byte prefix");
    r->mode = (sdf_proto_mode)p[0];
    r->words = p[1];
    r->count = get32(p + 4);
    if (p[0] > SDF_MODE_LAST || r->words != sdf_proto_words(r->mode))
        return fail(reason, SDF_EPROTO, "RESULT mode and words per point disagree");
    if ((size - SDF_PROTO_RESULT_PREFIX) / 4 / r->words != r->count ||
        (size - SDF_PROTO_RESULT_PREFIX) % (4 * r->words))
        return fail(reason, SDF_EPROTO, "RESULT payload length does not match its count");
    r->data = p + SDF_PROTO_RESULT_PREFIX;
    return 0;
}

/* ---- ERROR ------------------------------------------------------------------------------- */

size_t sdf_proto_encode_error(void *dst, size_t cap, uint32_t request_id, uint16_t status,
                              const char *code, const char *message)
{
    size_t code_len = strlen(code), msg_len = message ? strlen(message) : 0;
    size_t fixed = SDF_PROTO_HEADER_SIZE + 2 + 2 + code_len + 2;
    if (code_len > UINT16_MAX || cap < fixed)
        return 0;
    if (msg_len > cap - fixed)
        msg_len = cap - fixed;
    if (msg_len > UINT16_MAX)
        msg_len = UINT16_MAX;
    unsigned char *p = dst;
    sdf_proto_encode_header(p, SDF_PROTO_ERROR, request_id,
                            (uint32_t)(fixed + msg_len - SDF_PROTO_HEADER_SIZE));
    p += SDF_PROTO_HEADER_SIZE;
    put16(p, status);
    put16(p + 2, (uint16_t)code_len);
    memcpy(p + 4, code, code_len);
    put16(p + 4 + code_len, (uint16_t)msg_len);
    if (msg_len)
        memcpy(p + 6 + code_len, message, msg_len);
    return fixed + msg_len;
}

/* Read a u16-length-prefixed string at *off. */
static int get_string(const unsigned char *p, size_t size, size_t *off, const char **s,
                      size_t *len)
{
    if (size - *off < 2)
        return -1;
    *len = get16(p + *off);
    if (size - *off - 2 < *len)
        return -1;
    *s = (const char *)p + *off + 2;
    *off += 2 + *len;
    return 0;
}

int sdf_proto_decode_error(const void *payload, size_t size, sdf_proto_error *e,
                           const char **reason)
{
    const unsigned char *p = payload;
    size_t off = 2;
    if (size < 2)
        return fail(reason, SDF_EPROTO, "ERROR payload is shorter than its status");
    e->status = get16(p);
    if (get_string(p, size, &off, &e->code, &e->code_len) ||
        get_string(p, size, &off, &e->message, &e->message_len) || off != size)
        return fail(reason, SDF_EPROTO, "ERROR payload strings do not fit its length");
    return 0;
}

/* ---- HELLO_OK ---------------------------------------------------------------------------- */

size_t sdf_proto_encode_hello_ok(void *dst, size_t cap, uint32_t request_id,
                                 const sdf_proto_hello *h)
{
    size_t payload = 12 + 2 + h->server_len;
    if (h->server_len > UINT16_MAX || SDF_PROTO_HEADER_SIZE + payload > cap)
        return 0;
    unsigned char *p = dst;
    sdf_proto_encode_header(p, SDF_PROTO_HELLO_OK, request_id, (uint32_t)payload);
    p += SDF_PROTO_HEADER_SIZE;
    put16(p, h->version);
    put16(p + 2, 0);
    put32(p + 4, h->max_payload);
    put32(p + 8, h->max_points);
    put16(p + 12, (uint16_t)h->server_len);
    memcpy(p + 14, h->server, h->server_len);
    return SDF_PROTO_HEADER_SIZE + payload;
}

int sdf_proto_decode_hello_ok(const void *payload, size_t size, sdf_proto_hello *h,
                              const char **reason)
{
    const unsigned char *p = payload;
    size_t off = 12;
    if (size < 12)
        return fail(reason, SDF_EPROTO, "HELLO_OK payload is too short");
    h->version = get16(p);
    h->max_payload = get32(p + 4);
    h->max_points = get32(p + 8);
    if (get_string(p, size, &off, &h->server, &h->server_len) || off != size)
        return fail(reason, SDF_EPROTO, "HELLO_OK server string does not fit its length");
    return 0;
}

/* ---- MESHES ------------------------------------------------------------------------------ */

size_t sdf_proto_meshes_size(const sdf_proto_mesh_entry *entries, size_t count)
{
    size_t size = SDF_PROTO_HEADER_SIZE + 4;
    for (size_t i = 0; i < count; i++)
        size += 2 + entries[i].name_len + 8 + 2;
    return size;
}

size_t sdf_proto_encode_meshes(void *dst, size_t cap, uint32_t request_id,
                               const sdf_proto_mesh_entry *entries, size_t count)
{
    size_t size = sdf_proto_meshes_size(entries, count);
    if (size > cap || size > UINT32_MAX || count > UINT32_MAX)
        return 0;
    unsigned char *p = dst;
    sdf_proto_encode_header(p, SDF_PROTO_MESHES, request_id,
                            (uint32_t)(size - SDF_PROTO_HEADER_SIZE));
    p += SDF_PROTO_HEADER_SIZE;
    put32(p, (uint32_t)count);
    p += 4;
    for (size_t i = 0; i < count; i++) {
        const sdf_proto_mesh_entry *e = &entries[i];
        if (e->name_len > UINT16_MAX)
            return 0;
        put16(p, (uint16_t)e->name_len);
        memcpy(p + 2, e->name, e->name_len);
        p += 2 + e->name_len;
        put64(p, e->triangles);
        p[8] = e->closed;
        p[9] = e->auto_sign;
        p += 10;
    }
    return size;
}

int sdf_proto_meshes_count(const void *payload, size_t size, uint32_t *count)
{
    if (size < 4)
        return SDF_EPROTO;
    *count = get32(payload);
    return 0;
}

int sdf_proto_meshes_next(const void *payload, size_t size, size_t *offset,
                          sdf_proto_mesh_entry *e, const char **reason)
{
    const unsigned char *p = payload;
    size_t off = *offset ? *offset : 4;
    if (get_string(p, size, &off, &e->name, &e->name_len) || size - off < 10)
        return fail(reason, SDF_EPROTO, "MESHES entry runs past the payload");
    e->triangles = get64(p + off);
    e->closed = p[off + 8];
    e->auto_sign = p[off + 9];
    *offset = off + 10;
    return 0;
}
