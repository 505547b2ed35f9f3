/* test_proto.c - the binary protocol codec: every message type round-trips; every
 * truncated prefix of every payload (and of a header) is refused; bad magic, version,
 * lengths, modes, signs and names are refused with their codes; the PROTOCOL.md example
 * frame is byte-exact. Then mutations: valid payloads of every type with random bytes
 * changed, cut or extended, and random garbage, each decoded from a heap block of exactly
 * its size (so the sanitizer build sees any read past it); a decoder either refuses or
 * returns fields that lie inside the payload and within the caps. */
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "proto.h"

static unsigned char frame[1 << 16];

static void test_header(void)
{
    sdf_proto_header h;
    const char *why = NULL;
    sdf_proto_encode_header(frame, SDF_PROTO_QUERY, 0xdeadbeef, 1234);
    CHECK(sdf_proto_decode_header(frame, 16, 1 << 20, &h, &why) == 0 && h.type == SDF_PROTO_QUERY &&
              h.request_id == 0xdeadbeef && h.length == 1234 && h.version == 1,
          "header round trip");
    for (size_t n = 0; n < 16; n++)
        CHECK(sdf_proto_decode_header(frame, n, 1 << 20, &h, &why) == SDF_ETRUNC, "prefix %zu", n);
    CHECK(sdf_proto_decode_header(frame, 16, 1000, &h, &why) == SDF_ELIMIT && why, "cap");
    frame[4] = 2;
    CHECK(sdf_proto_decode_header(frame, 16, 1 << 20, &h, &why) == SDF_EPROTO, "version 2");
    frame[4] = 1;
    frame[0] = 'X';
    CHECK(sdf_proto_decode_header(frame, 16, 1 << 20, &h, &why) == SDF_EPROTO, "magic");
}

static void test_query(void)
{
    float pts[6] = {1, 2, 3, -4, 5.5f, 1e-30f};
    sdf_proto_query q = {.mode = SDF_MODE_CLOSEST, .sign = SDF_SIGN_WINDING, .name = "elephant",
                         .name_len = 8, .count = 2, .points = pts}, back;
    size_t n = sdf_proto_encode_query(frame, sizeof frame, 42, &q);
    CHECK(n == 16 + 8 + 8 + 24, "query frame size %zu", n);
    sdf_proto_header h;
    const char *why;
    CHECK(sdf_proto_decode_header(frame, n, 1 << 20, &h, &why) == 0 && h.length == n - 16, "header");
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 100, &back, &why) == 0, "decode: %s", why);
    CHECK(back.mode == q.mode && back.sign == q.sign && back.count == 2 && back.name_len == 8 &&
              !memcmp(back.name, "elephant", 8) && !memcmp(back.points, pts, sizeof pts),
          "query round trip");
    CHECK(((const unsigned char *)back.points - (frame + 16)) % 4 == 0, "points are 4-aligned");
    for (size_t len = 0; len < h.length; len++)
        CHECK(sdf_proto_decode_query(frame + 16, len, 100, &back, &why) != 0, "prefix %zu", len);
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 1, &back, &why) == SDF_ELIMIT, "max points");
    frame[16] = 9;
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 100, &back, &why) == SDF_EINVAL, "mode 9");
    frame[16] = SDF_MODE_FILTERED; /* a filtered mode needs the 40-byte FILTER block */
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 100, &back, &why) == SDF_EPROTO,
          "filtered query without its FILTER block");
    frame[16] = SDF_MODE_CLOSEST;
    frame[17] = 5;
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 100, &back, &why) == SDF_EINVAL, "sign 5");
    frame[17] = 0;
    frame[18] = 0;
    CHECK(sdf_proto_decode_query(frame + 16, h.length, 100, &back, &why) == SDF_EPROTO, "empty name");
    q.name_len = 0;
    CHECK(sdf_proto_encode_query(frame, sizeof frame, 1, &q) == 0, "empty name encoded");
    q.name_len = 8;
    CHECK(sdf_proto_encode_query(frame, 40, 1, &q) == 0, "overflowing buffer written");
    /* Count that disagrees with the length, including one that would overflow 12 * count. */
    n = sdf_proto_encode_query(frame, sizeof frame, 42, &q);
    frame[16 + 4] = 0xff, frame[16 + 5] = 0xff, frame[16 + 6] = 0xff, frame[16 + 7] = 0x7f;
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, UINT32_MAX, &back, &why) == SDF_EPROTO, "count");

    /* The example from PROTOCOL.md, byte for byte. */
    static const unsigned char example[] = {
        0x53, 0x44, 0x46, 0x50, 0x01, 0x03, 0x00, 0x00, 0x07, 0x00, 0x00, 0x00, 0x18, 0x00, 0x00,
        0x00, 0x00, 0x00, 0x04, 0x00, 0x01, 0x00, 0x00, 0x00, 0x64, 0x65, 0x6d, 0x6f, 0, 0, 0,
        0, 0, 0, 0, 0, 0, 0, 0, 0};
    float origin[3] = {0, 0, 0};
    sdf_proto_query ex = {.mode = SDF_MODE_SIGNED, .sign = SDF_SIGN_AUTO, .name = "demo",
                          .name_len = 4, .count = 1, .points = origin};
    n = sdf_proto_encode_query(frame, sizeof frame, 7, &ex);
    CHECK(n == sizeof example && !memcmp(frame, example, n), "PROTOCOL.md example differs");
}

/* Filtered queries carry their parameters, bit for bit. */
static void test_filtered_query(void)
{
    float pts[3] = {0.5f, -1, 2};
    sdf_proto_query q = {.mode = SDF_MODE_FILTERED_GRADIENT, .sign = SDF_SIGN_NONE, .name = "m",
                         .name_len = 1, .count = 1, .points = pts,
                         .filter = {.kernel = SDF_KERNEL_BUMP, .cap = 0.125, .a = 3e5, .b = 0.1,
                                    .samples = 96, .unsigned_integrand = 1, .allow_wide_bump = 1,
                                    .sample_gradient = 1, .seed = 0x0123456789abcdefu,
                                    .min_samples = 12,
                                    .medial = 0.375}},
                    back;
    size_t n = sdf_proto_encode_query(frame, sizeof frame, 5, &q);
    CHECK(n == 16 + 8 + 4 + SDF_PROTO_FILTER_SIZE + 12, "filtered query frame size %zu", n);
    const char *why;
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == 0, "decode: %s", why);
    const sdf_filter_options *f = &back.filter;
    CHECK(f->kernel == SDF_KERNEL_BUMP && f->cap == 0.125 && f->a == 3e5 && f->b == 0.1 &&
              f->samples == 96 && f->unsigned_integrand && f->allow_wide_bump && !f->grid &&
              f->sample_gradient &&
              f->seed == 0x0123456789abcdefu && f->min_samples == 12 && f->medial == 0.375 &&
              !memcmp(back.points, pts, sizeof pts),
          "filter round trip");
    for (size_t len = 0; len < n - 16; len++)
        CHECK(sdf_proto_decode_query(frame + 16, len, 10, &back, &why) != 0, "prefix %zu", len);
    /* Reserved bits and bytes must be 0: a later version's meaning is never ignored. */
    unsigned char *block = frame + 16 + 8 + 4;
    const struct { size_t at; unsigned char bit; const char *says; } reserved[] = {
        {1, 0x10, "flags"}, {1, 0x80, "flags"}, {108, 1, "reserved"}, {111, 0x40, "reserved"},
        {3, 1, "name length"}};
    for (size_t r = 0; r < sizeof reserved / sizeof reserved[0]; r++) {
        block[reserved[r].at] ^= reserved[r].bit;
        CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == SDF_EINVAL &&
                  strstr(why, reserved[r].says),
              "reserved byte %zu bit %#x accepted", reserved[r].at, reserved[r].bit);
        block[reserved[r].at] ^= reserved[r].bit;
    }
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == 0, "restored: %s", why);
    CHECK(sdf_proto_words(SDF_MODE_FILTERED) == 1 && sdf_proto_words(SDF_MODE_FILTERED_GRADIENT) == 4,
          "filtered words");

    /* Smoothing volumes: a sphere, a box, and a mesh by name (padded after the block). */
    q.filter.smooth = (sdf_smoothing_volume){.shape = SDF_VOLUME_SPHERE, .center = {1, 2, 3},
                                             .radius = 0.5, .depth = 0.25, .scale = 2};
    n = sdf_proto_encode_query(frame, sizeof frame, 6, &q);
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == 0 &&
              back.filter.smooth.shape == SDF_VOLUME_SPHERE && back.filter.smooth.center[2] == 3 &&
              back.filter.smooth.radius == 0.5 && back.filter.smooth.depth == 0.25 &&
              back.filter.smooth.scale == 2 && !back.volume_name,
          "sphere volume round trip");
    q.filter.smooth = (sdf_smoothing_volume){.shape = SDF_VOLUME_BOX, .lo = {-1, -2, -3},
                                             .hi = {4, 5, 6}};
    n = sdf_proto_encode_query(frame, sizeof frame, 6, &q);
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == 0 &&
              back.filter.smooth.lo[1] == -2 && back.filter.smooth.hi[2] == 6,
          "box volume round trip");
    q.filter.smooth = (sdf_smoothing_volume){.shape = SDF_VOLUME_MESH};
    q.volume_name = "knife", q.volume_name_len = 5;
    n = sdf_proto_encode_query(frame, sizeof frame, 6, &q);
    CHECK(n == 16 + 8 + 4 + SDF_PROTO_FILTER_SIZE + 8 + 12, "mesh volume frame size %zu", n);
    CHECK(sdf_proto_decode_query(frame + 16, n - 16, 10, &back, &why) == 0 &&
              back.volume_name_len == 5 && !memcmp(back.volume_name, "knife", 5) &&
              !memcmp(back.points, pts, sizeof pts),
          "mesh volume round trip: %s", why);
    for (size_t len = 0; len < n - 16; len++)
        CHECK(sdf_proto_decode_query(frame + 16, len, 10, &back, &why) != 0, "prefix %zu", len);
    q.volume_name_len = 0;
    CHECK(sdf_proto_encode_query(frame, sizeof frame, 6, &q) == 0, "mesh volume without a name");
}

static void test_result(void)
{
    float data[10] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
    size_t n = sdf_proto_encode_result_head(frame, 3, SDF_MODE_CLOSEST, 2);
    memcpy(frame + n, data, sizeof data);
    sdf_proto_header h;
    sdf_proto_result r;
    const char *why;
    CHECK(sdf_proto_decode_header(frame, n + 40, 1 << 20, &h, &why) == 0 && h.length == 8 + 40, "len");
    CHECK(sdf_proto_decode_result(frame + 16, h.length, &r, &why) == 0 && r.words == 5 &&
              r.count == 2 && !memcmp(r.data, data, 40),
          "result round trip");
    for (size_t len = 0; len < h.length; len++)
        CHECK(sdf_proto_decode_result(frame + 16, len, &r, &why) != 0, "prefix %zu", len);
    /* every mode's result decodes, the filtered ones included; one past the last does not */
    for (int m = 0; m <= SDF_MODE_LAST + 1; m++) {
        unsigned words = m <= SDF_MODE_LAST ? sdf_proto_words((sdf_proto_mode)m) : 1;
        n = sdf_proto_encode_result_head(frame, 4, (sdf_proto_mode)m, 1);
        frame[16 + 1] = (unsigned char)words;
        memcpy(frame + n, data, 4 * words);
        int rc = sdf_proto_decode_result(frame + 16, 8 + 4 * words, &r, &why);
        CHECK(m <= SDF_MODE_LAST ? rc == 0 && (int)r.mode == m && r.words == words && r.count == 1
                                 : rc == SDF_EPROTO,
              "mode %d result: %d", m, rc);
    }
}

static void test_error_and_hello(void)
{
    size_t n = sdf_proto_encode_error(frame, sizeof frame, 9, 404, "ENOTFOUND", "no mesh 'x'");
    sdf_proto_header h;
    sdf_proto_error e;
    const char *why;
    CHECK(sdf_proto_decode_header(frame, n, 1 << 20, &h, &why) == 0 && h.type == SDF_PROTO_ERROR, "hdr");
    CHECK(sdf_proto_decode_error(frame + 16, h.length, &e, &why) == 0 && e.status == 404 &&
              e.code_len == 9 && !memcmp(e.code, "ENOTFOUND", 9) && e.message_len == 11,
          "error round trip");
    for (size_t len = 0; len < h.length; len++)
        CHECK(sdf_proto_decode_error(frame + 16, len, &e, &why) != 0, "error prefix %zu", len);
    n = sdf_proto_encode_error(frame, 40, 9, 422, "EINVAL", "a long message that cannot fit in forty bytes");
    CHECK(n == 40, "truncated error message: %zu", n);
    CHECK(sdf_proto_encode_error(frame, 30, 9, 404, "ENOTFOUND", "") == 0, "no room for the code");

    sdf_proto_hello hello = {1, 5000, 400, "sdfd 0.1", 8}, back;
    n = sdf_proto_encode_hello_ok(frame, sizeof frame, 1, &hello);
    CHECK(sdf_proto_decode_hello_ok(frame + 16, n - 16, &back, &why) == 0 && back.max_points == 400 &&
              back.max_payload == 5000 && back.server_len == 8,
          "hello round trip");
    for (size_t len = 0; len < n - 16; len++)
        CHECK(sdf_proto_decode_hello_ok(frame + 16, len, &back, &why) != 0, "hello prefix %zu", len);

    sdf_proto_mesh_entry meshes[2] = {{"demo", 4, 12288, 1, 1}, {"cow", 3, 5804, 1, 2}}, m;
    n = sdf_proto_encode_meshes(frame, sizeof frame, 5, meshes, 2);
    CHECK(n == sdf_proto_meshes_size(meshes, 2), "meshes size");
    uint32_t count;
    size_t off = 0;
    CHECK(sdf_proto_meshes_count(frame + 16, n - 16, &count) == 0 && count == 2, "count");
    CHECK(sdf_proto_meshes_next(frame + 16, n - 16, &off, &m, &why) == 0 && m.name_len == 4 &&
              m.triangles == 12288,
          "first mesh");
    CHECK(sdf_proto_meshes_next(frame + 16, n - 16, &off, &m, &why) == 0 && m.auto_sign == 2 &&
              off == n - 16,
          "second mesh");
    CHECK(sdf_proto_meshes_next(frame + 16, n - 16, &off, &m, &why) != 0, "read past the end");
    off = 0;
    CHECK(sdf_proto_meshes_next(frame + 16, n - 20, &off, &m, &why) == 0 &&
              sdf_proto_meshes_next(frame + 16, n - 20, &off, &m, &why) == SDF_EPROTO,
          "truncated second entry");
}

static void test_volume_query(void)
{
    float pts[9] = {1, 2, 3, -4, 5.5f, 1e-30f, 0, 0, 7};
    sdf_proto_volume_query q = {.gradient = 1, .interpolation = SDF_VOLUME_NEAREST, .name = "knot",
                                .name_len = 4, .count = 3, .points = pts}, back;
    size_t n = sdf_proto_encode_volume_query(frame, sizeof frame, 9, &q);
    CHECK(n == 16 + 8 + 4 + 36, "volume query frame size %zu", n);
    sdf_proto_header h;
    const char *why;
    CHECK(sdf_proto_decode_header(frame, n, 1 << 20, &h, &why) == 0 &&
              h.type == SDF_PROTO_VOLUME_QUERY && h.request_id == 9, "volume query header");
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 100, &back, &why) == 0, "decode: %s", why);
    CHECK(back.gradient == 1 && back.interpolation == SDF_VOLUME_NEAREST && back.count == 3 &&
              back.name_len == 4 && !memcmp(back.name, "knot", 4) &&
              !memcmp(back.points, pts, sizeof pts),
          "volume query round trip");
    for (size_t len = 0; len < h.length; len++)
        CHECK(sdf_proto_decode_volume_query(frame + 16, len, 100, &back, &why) != 0, "prefix %zu", len);
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 2, &back, &why) == SDF_ELIMIT,
          "max points");
    frame[16] = 2;
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 100, &back, &why) == SDF_EINVAL, "mode 2");
    frame[16] = 0;
    frame[17] = 4;
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 100, &back, &why) == SDF_EINVAL &&
              strstr(why, "3 default"),
          "interpolation 4");
    frame[17] = 255;
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 100, &back, &why) == SDF_EINVAL,
          "interpolation 255");
    frame[17] = 0;
    frame[18] = 0;
    CHECK(sdf_proto_decode_volume_query(frame + 16, h.length, 100, &back, &why) == SDF_EPROTO,
          "empty name");
    q.name_len = 256;
    CHECK(sdf_proto_encode_volume_query(frame, sizeof frame, 1, &q) == 0, "name too long");
}

/* The interpolation byte: 0 and 1 as protocol version 1 first named them, then 2 hermite and
 * 3 default, both ways; a filter the protocol has no byte for is not encoded. */
static void test_volume_interpolations(void)
{
    static const struct {
        unsigned char byte;
        sdf_volume_filter filter;
    } wire[] = {{0, SDF_VOLUME_TRILINEAR}, {1, SDF_VOLUME_NEAREST}, {2, SDF_VOLUME_HERMITE},
                {3, SDF_VOLUME_DEFAULT}};
    float pts[3] = {0.5f, -1, 2};
    for (size_t i = 0; i < sizeof wire / sizeof wire[0]; i++) {
        sdf_proto_volume_query q = {.interpolation = wire[i].filter, .name = "v", .name_len = 1,
                                    .count = 1, .points = pts}, back;
        size_t n = sdf_proto_encode_volume_query(frame, sizeof frame, 3, &q);
        const char *why;
        CHECK(n == 16 + 8 + 4 + 12 && frame[17] == wire[i].byte, "filter %d is byte %u",
              (int)wire[i].filter, frame[17]);
        CHECK(sdf_proto_decode_volume_query(frame + 16, n - 16, 1, &back, &why) == 0 &&
                  back.interpolation == wire[i].filter,
              "byte %u decodes to %d", wire[i].byte, (int)back.interpolation);
    }
    sdf_proto_volume_query q = {.interpolation = (sdf_volume_filter)(SDF_VOLUME_HERMITE + 1),
                                .name = "v", .name_len = 1, .count = 1, .points = pts};
    CHECK(sdf_proto_encode_volume_query(frame, sizeof frame, 3, &q) == 0,
          "an unknown filter is encoded");
}

/* ---- mutations ---------------------------------------------------------------------- */

static uint64_t mutation_state = 0x243f6a8885a308d3u;

static uint32_t next_random(void)
{
    mutation_state = mutation_state * 6364136223846793005u + 1442695040888963407u;
    return (uint32_t)(mutation_state >> 33);
}

/* Is [p, p + n) inside [base, base + size)? */
static int inside(const void *base, size_t size, const void *p, size_t n)
{
    const unsigned char *b = base, *q = p;
    return q >= b && q <= b + size && n <= (size_t)(b + size - q);
}

enum { MUTATE_QUERY, MUTATE_FILTERED, MUTATE_VOLUME, MUTATE_RESULT, MUTATE_ERROR, MUTATE_HELLO,
       MUTATE_MESHES, MUTATE_KINDS };

/* A valid payload of each kind (without its header) into out; its size. */
static size_t valid_payload(int kind, unsigned char *out)
{
    static const float pts[15] = {1, 2, 3, -4, 5.5f, 1e-30f, 0, 0, 7, 8, 9, 10, -1, -2, -3};
    size_t n = 0;
    if (kind == MUTATE_QUERY || kind == MUTATE_FILTERED) {
        sdf_proto_query q = {.mode = SDF_MODE_CLOSEST, .sign = SDF_SIGN_WINDING, .name = "mesh",
                             .name_len = 4, .count = 5, .points = pts};
        if (kind == MUTATE_FILTERED) {
            q.mode = SDF_MODE_FILTERED;
            q.filter = (sdf_filter_options){.samples = 64, .smooth.shape = SDF_VOLUME_MESH};
            q.volume_name = "volume", q.volume_name_len = 6;
        }
        n = sdf_proto_encode_query(frame, sizeof frame, 1, &q);
    } else if (kind == MUTATE_VOLUME) {
        sdf_proto_volume_query q = {.gradient = 1, .name = "vol", .name_len = 3, .count = 5,
                                    .points = pts};
        n = sdf_proto_encode_volume_query(frame, sizeof frame, 1, &q);
    } else if (kind == MUTATE_RESULT) {
        n = sdf_proto_encode_result_head(frame, 1, SDF_MODE_GRADIENT, 3);
        memcpy(frame + n, pts, 4 * 4 * 3);
        n += 4 * 4 * 3;
    } else if (kind == MUTATE_ERROR) {
        n = sdf_proto_encode_error(frame, sizeof frame, 1, 404, "ENOTFOUND", "no mesh named x");
    } else if (kind == MUTATE_HELLO) {
        sdf_proto_hello h = {.version = 1, .max_payload = 1 << 20, .max_points = 400,
                             .server = "sdfd", .server_len = 4};
        n = sdf_proto_encode_hello_ok(frame, sizeof frame, 1, &h);
    } else {
        sdf_proto_mesh_entry m[3] = {{"demo", 4, 12288, 1, 1}, {"cow", 3, 5804, 1, 2},
                                     {"k", 1, 7, 0, 0}};
        n = sdf_proto_encode_meshes(frame, sizeof frame, 1, m, 3);
    }
    CHECK(n > SDF_PROTO_HEADER_SIZE, "valid payload of kind %d", kind);
    memcpy(out, frame + SDF_PROTO_HEADER_SIZE, n - SDF_PROTO_HEADER_SIZE);
    return n - SDF_PROTO_HEADER_SIZE;
}

/* Decode `size` bytes at p as `kind`; when accepted, every field must lie in the payload
 * and within the caps. Returns 1 if accepted. */
static int decode_and_check(int kind, const unsigned char *p, size_t size)
{
    const char *why = NULL;
    const uint32_t max_points = 8;
    int ok = 0;
    if (kind == MUTATE_QUERY || kind == MUTATE_FILTERED) {
        sdf_proto_query q;
        if (sdf_proto_decode_query(p, size, max_points, &q, &why) == 0) {
            ok = 1;
            CHECK(q.count <= max_points && q.mode <= SDF_MODE_LAST &&
                      q.sign >= SDF_SIGN_AUTO && q.sign <= SDF_SIGN_NONE &&
                      q.name_len >= 1 && q.name_len <= SDF_PROTO_MAX_NAME &&
                      inside(p, size, q.name, q.name_len) &&
                      inside(p, size, q.points, 12 * (size_t)q.count) &&
                      (!q.volume_name || (q.volume_name_len <= SDF_PROTO_MAX_NAME &&
                                          inside(p, size, q.volume_name, q.volume_name_len))),
                  "accepted query out of bounds (%zu bytes)", size);
        } else {
            CHECK(why != NULL, "a refused query says why");
        }
    } else if (kind == MUTATE_VOLUME) {
        sdf_proto_volume_query q;
        if (sdf_proto_decode_volume_query(p, size, max_points, &q, &why) == 0) {
            ok = 1;
            CHECK(q.count <= max_points && (q.gradient == 0 || q.gradient == 1) &&
                      q.name_len >= 1 && q.name_len <= SDF_PROTO_MAX_NAME &&
                      inside(p, size, q.name, q.name_len) &&
                      inside(p, size, q.points, 12 * (size_t)q.count),
                  "accepted volume query out of bounds (%zu bytes)", size);
        } else {
            CHECK(why != NULL, "a refused volume query says why");
        }
    } else if (kind == MUTATE_RESULT) {
        sdf_proto_result r;
        if (sdf_proto_decode_result(p, size, &r, &why) == 0) {
            ok = 1;
            CHECK(r.words == sdf_proto_words(r.mode) && r.words > 0 &&
                      inside(p, size, r.data, 4 * (size_t)r.words * r.count),
                  "accepted result out of bounds (%zu bytes)", size);
        }
    } else if (kind == MUTATE_ERROR) {
        sdf_proto_error e;
        if (sdf_proto_decode_error(p, size, &e, &why) == 0) {
            ok = 1;
            CHECK(inside(p, size, e.code, e.code_len) &&
                      inside(p, size, e.message, e.message_len),
                  "accepted error out of bounds (%zu bytes)", size);
        }
    } else if (kind == MUTATE_HELLO) {
        sdf_proto_hello h;
        if (sdf_proto_decode_hello_ok(p, size, &h, &why) == 0) {
            ok = 1;
            CHECK(inside(p, size, h.server, h.server_len), "accepted hello out of bounds");
        }
    } else {
        uint32_t count;
        if (sdf_proto_meshes_count(p, size, &count) == 0) {
            ok = 1;
            size_t offset = 0, last = 0;
            sdf_proto_mesh_entry m;
            /* Entries are at least a few bytes each: never more of them than bytes. */
            for (uint32_t k = 0; k < count && k <= size; k++) {
                if (sdf_proto_meshes_next(p, size, &offset, &m, &why) != 0)
                    break;
                CHECK(offset > last && offset <= size && inside(p, size, m.name, m.name_len),
                      "accepted mesh entry %u out of bounds", k);
                last = offset;
            }
        }
    }
    return ok;
}

/* Random changes to valid payloads and random garbage, each in a block of its exact size. */
static void test_mutations(void)
{
    unsigned char valid[1024], work[1100];
    size_t accepted[MUTATE_KINDS] = {0}, tried[MUTATE_KINDS] = {0};
    for (int kind = 0; kind < MUTATE_KINDS; kind++) {
        size_t n = valid_payload(kind, valid);
        CHECK(decode_and_check(kind, valid, n), "the unmutated payload of kind %d", kind);
        for (int round = 0; round < 20000; round++) {
            size_t size = n;
            memcpy(work, valid, n);
            int how = (int)(next_random() % 4);
            if (how == 3) { /* garbage of a random length */
                size = next_random() % 300;
                for (size_t i = 0; i < size; i++)
                    work[i] = (unsigned char)next_random();
            } else {
                int changes = 1 + (int)(next_random() % 4);
                for (int c = 0; c < changes; c++) {
                    uint32_t v = next_random();
                    /* lengths and counts live at the start: bias changes towards it */
                    size_t at = next_random() % (v & 1 ? (n < 32 ? n : 32) : n);
                    work[at] = v & 2 ? (unsigned char)(v >> 8) : v & 4 ? 0xff : 0;
                }
                if (how == 1) /* cut */
                    size = next_random() % (n + 1);
                else if (how == 2) /* extended by random bytes */
                    for (size_t grow = 1 + next_random() % 64; grow > 0; grow--)
                        work[size++] = (unsigned char)next_random();
            }
            unsigned char *block = malloc(size ? size : 1);
            CHECK(block != NULL, "memory");
            memcpy(block, work, size);
            accepted[kind] += (size_t)decode_and_check(kind, block, size);
            tried[kind]++;
            free(block);
        }
        /* Some mutations keep a payload valid (a changed coordinate), most do not: both
         * paths ran. */
        CHECK(accepted[kind] > 0 && accepted[kind] < tried[kind],
              "kind %d: %zu of %zu mutations accepted", kind, accepted[kind], tried[kind]);
    }
    for (int round = 0; round < 20000; round++) { /* headers: 16 random bytes */
        unsigned char *h = malloc(SDF_PROTO_HEADER_SIZE);
        CHECK(h != NULL, "memory");
        for (int i = 0; i < SDF_PROTO_HEADER_SIZE; i++)
            h[i] = (unsigned char)next_random();
        if (round % 2) { /* half with the right magic and version, so lengths get judged */
            uint32_t id = next_random(), length = next_random();
            length >>= next_random() % 32;
            sdf_proto_encode_header(h, h[5], id, length);
        }
        sdf_proto_header hd;
        const char *why = NULL;
        if (sdf_proto_decode_header(h, SDF_PROTO_HEADER_SIZE, 1 << 20, &hd, &why) == 0)
            CHECK(hd.version == SDF_PROTO_VERSION && hd.length <= (1u << 20), "header caps");
        free(h);
    }
}

static void test_mode_names(void)
{
    sdf_proto_mode m;
    CHECK(sdf_proto_mode_from_name("gradient", &m) == 0 && m == SDF_MODE_GRADIENT &&
              sdf_proto_words(m) == 4 && sdf_proto_mode_from_name("fast", &m) == SDF_EINVAL,
          "mode names");
}

static const check_case cases[] = {
    {"mutations", test_mutations},
    {"header", test_header},
    {"query", test_query},
    {"filtered_query", test_filtered_query},
    {"volume_query", test_volume_query},
    {"volume_interpolations", test_volume_interpolations},
    {"result", test_result},
    {"error_and_hello", test_error_and_hello},
    {"mode_names", test_mode_names},
};

int main(int argc, char **argv)
{
    return check_main("proto", cases, CHECK_COUNT_OF(cases), argc, argv);
}
