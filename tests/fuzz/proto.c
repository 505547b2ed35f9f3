/* proto.c - fuzzes the binary protocol's decoders (proto/proto.h): the input is one frame,
 * header and payload, decoded as the server and the clients decode it, by its type (every
 * message type: QUERY, VOLUME_QUERY, RESULT, ERROR, HELLO_OK, MESHES; the others carry
 * opaque bytes). Everything a decoder hands back must lie inside the payload, and a decoded
 * VOLUME_QUERY's codes encode back to the bytes they came from. */
#include "fuzz.h"
#include "proto.h"

#define MAX_POINTS 4096
#define MAX_PAYLOAD (12 * MAX_POINTS + 4096)

/* [p, p + n) lies in the payload (n = 0 anywhere is fine). */
static void inside(const uint8_t *payload, size_t size, const void *p, size_t n)
{
    if (!n)
        return;
    const uint8_t *b = p;
    FUZZ_CHECK(b >= payload && n <= size && (size_t)(b - payload) <= size - n);
    fuzz_touch(b, n);
}

static void decode(uint8_t type, const uint8_t *payload, size_t size)
{
    const char *reason = NULL;
    switch (type) {
    case SDF_PROTO_QUERY: {
        sdf_proto_query q;
        if (sdf_proto_decode_query(payload, size, MAX_POINTS, &q, &reason))
            break;
        FUZZ_CHECK(q.count <= MAX_POINTS && q.name_len >= 1 && q.name_len <= 255);
        FUZZ_CHECK(sdf_proto_words(q.mode) > 0);
        inside(payload, size, q.name, q.name_len);
        inside(payload, size, q.points, 12 * (size_t)q.count);
        FUZZ_CHECK(((const uint8_t *)q.points - payload) % 4 == 0);
        inside(payload, size, q.volume_name, q.volume_name_len);
        FUZZ_CHECK(sdf_proto_query_size(&q) == size);
        break;
    }
    case SDF_PROTO_VOLUME_QUERY: {
        sdf_proto_volume_query q;
        if (sdf_proto_decode_volume_query(payload, size, MAX_POINTS, &q, &reason))
            break;
        FUZZ_CHECK(q.count <= MAX_POINTS);
        inside(payload, size, q.name, q.name_len);
        inside(payload, size, q.points, 12 * (size_t)q.count);
        FUZZ_CHECK(sdf_proto_volume_query_size(&q) == size);
        /* what was decoded encodes back to the same what and interpolation bytes (the
         * interpolation table is one to one; its four values: PROTOCOL.md) */
        uint8_t prefix[SDF_PROTO_HEADER_SIZE + 8 + SDF_PROTO_MAX_NAME + 1];
        q.count = 0;
        FUZZ_CHECK(sdf_proto_encode_volume_query(prefix, sizeof prefix, 0, &q) > 0);
        FUZZ_CHECK(prefix[SDF_PROTO_HEADER_SIZE] == payload[0] &&
                   prefix[SDF_PROTO_HEADER_SIZE + 1] == payload[1] && payload[1] <= 3);
        break;
    }
    case SDF_PROTO_RESULT: {
        sdf_proto_result r;
        if (!sdf_proto_decode_result(payload, size, &r, &reason))
            inside(payload, size, r.data, 4 * (size_t)r.words * r.count);
        break;
    }
    case SDF_PROTO_ERROR: {
        sdf_proto_error e;
        if (!sdf_proto_decode_error(payload, size, &e, &reason)) {
            inside(payload, size, e.code, e.code_len);
            inside(payload, size, e.message, e.message_len);
        }
        break;
    }
    case SDF_PROTO_HELLO_OK: {
        sdf_proto_hello h;
        if (!sdf_proto_decode_hello_ok(payload, size, &h, &reason))
            inside(payload, size, h.server, h.server_len);
        break;
    }
    case SDF_PROTO_MESHES: {
        uint32_t count;
        if (sdf_proto_meshes_count(payload, size, &count))
            break;
        size_t offset = 0;
        sdf_proto_mesh_entry e;
        for (uint32_t i = 0; i < count; i++) {
            size_t before = offset;
            if (sdf_proto_meshes_next(payload, size, &offset, &e, &reason))
                break;
            FUZZ_CHECK(offset > before);
            inside(payload, size, e.name, e.name_len);
        }
        break;
    }
    default: /* HELLO, LIST_MESHES, AUTH, AUTH_OK, unknown types: bytes or nothing */
        return;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdf_proto_header h;
    const char *reason = NULL;
    if (sdf_proto_decode_header(data, size, MAX_PAYLOAD, &h, &reason))
        return 0;
    FUZZ_CHECK(h.length <= MAX_PAYLOAD && h.version == SDF_PROTO_VERSION);
    size_t have = size - SDF_PROTO_HEADER_SIZE;
    size_t n = h.length < have ? h.length : have; /* a short frame: decode what came */
    uint8_t *payload = malloc(n ? n : 1); /* aligned, as a receive buffer */
    if (!payload)
        return 0;
    memcpy(payload, data + SDF_PROTO_HEADER_SIZE, n);
    decode(h.type, payload, n);
    free(payload);
    return 0;
}
