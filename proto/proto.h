/* proto.h - codec for sdfd's binary protocol (PROTOCOL.md): frame headers and the payloads
 * of each message type. No I/O and no allocation: decoders check every length against the
 * bytes given and the caller's caps and return pointers into the caller's buffer; encoders
 * write into caller buffers and say how much they wrote. Shared by the server, the tests
 * and C clients. Errors are SDF_E* codes (sdf.h), or SDF_EPROTO below, with a static reason
 * string. */
#ifndef SDF_PROTO_H
#define SDF_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

/* A frame that breaks the protocol: the codec's own code beside the library's SDF_E* codes,
 * in the range sdf.h leaves to the layers above it (sdfd's table names it EPROTO, 400). */
#define SDF_EPROTO (-13)

#define SDF_PROTO_VERSION 1
#define SDF_PROTO_HEADER_SIZE 16
#define SDF_PROTO_MAX_NAME 255

enum sdf_proto_type {
    SDF_PROTO_HELLO = 0x01,
    SDF_PROTO_LIST_MESHES = 0x02,
    SDF_PROTO_QUERY = 0x03,
    SDF_PROTO_VOLUME_QUERY = 0x04,
    SDF_PROTO_AUTH = 0x05,        /* payload: the server's --token; answered by AUTH_OK */
    SDF_PROTO_ERROR = 0x7F,
    SDF_PROTO_HELLO_OK = 0x81,
    SDF_PROTO_MESHES = 0x82,
    SDF_PROTO_RESULT = 0x83,
    SDF_PROTO_AUTH_OK = 0x85,     /* empty payload */
};

/* Query modes; the values are the wire codes. */
typedef enum sdf_proto_mode {
    SDF_MODE_SIGNED = 0,
    SDF_MODE_DISTANCE = 1,
    SDF_MODE_GRADIENT = 2,
    SDF_MODE_CLOSEST = 3,
    SDF_MODE_FILTERED = 4,          /* the convolution-filtered field g (docs/filtered.md) */
    SDF_MODE_FILTERED_GRADIENT = 5, /* g and its gradient */
} sdf_proto_mode;
#define SDF_MODE_LAST SDF_MODE_FILTERED_GRADIENT

/* "signed", "distance", "gradient", "closest", "filtered", "filtered-gradient" <-> mode. */
int sdf_proto_mode_from_name(const char *name, sdf_proto_mode *out);
const char *sdf_proto_mode_name(sdf_proto_mode mode);
/* 32-bit words per point in a result: 1, 1, 4, 5, 1, 4; 0 for an unknown mode. */
unsigned sdf_proto_words(sdf_proto_mode mode);
/* Does the mode take the filter's parameters (a FILTER block in a QUERY)? */
int sdf_proto_mode_filtered(sdf_proto_mode mode);

typedef struct sdf_proto_header {
    uint8_t version, type;
    uint16_t flags;
    uint32_t request_id;
    uint32_t length; /* payload bytes */
} sdf_proto_header;

/* Decode the 16-byte header at `buf` (`size` bytes available). SDF_ETRUNC if fewer than 16;
 * SDF_EPROTO for a wrong magic or version; SDF_ELIMIT if length > max_payload. */
int sdf_proto_decode_header(const void *buf, size_t size, uint32_t max_payload,
                            sdf_proto_header *h, const char **reason);
void sdf_proto_encode_header(void *dst, uint8_t type, uint32_t request_id, uint32_t length);

/* QUERY. `points` holds 12 * count bytes of little-endian float32 xyz (4-byte aligned
 * relative to the payload start). Filtered modes carry the filter's parameters in a
 * SDF_PROTO_FILTER_SIZE-byte block after the name (decoded values are not validated here:
 * the library refuses bad ones with a message). */
typedef struct sdf_proto_query {
    sdf_proto_mode mode;
    sdf_sign_method sign;
    const char *name;
    size_t name_len;
    uint32_t count;
    const void *points;
    sdf_filter_options filter;   /* filtered modes only; filter.smooth.mesh is never set */
    const char *volume_name;     /* filtered modes with a mesh smoothing volume: its name */
    size_t volume_name_len;      /* 1..255 then, else 0 */
} sdf_proto_query;

/* The FILTER block's size without the smoothing mesh's name (PROTOCOL.md). */
#define SDF_PROTO_FILTER_SIZE 120

/* Payload size of a QUERY, or 0 if a name is empty or too long. */
size_t sdf_proto_query_size(const sdf_proto_query *q);
int sdf_proto_decode_query(const void *payload, size_t size, uint32_t max_points,
                           sdf_proto_query *q, const char **reason);
/* Write a whole QUERY frame (header + payload, points copied from q->points); returns its
 * size, or 0 if it does not fit in `cap` or the name is empty / too long. */
size_t sdf_proto_encode_query(void *dst, size_t cap, uint32_t request_id, const sdf_proto_query *q);

/* VOLUME_QUERY: evaluate a baked volume (docs/volumes.md). Answered by a RESULT in the
 * signed layout (W = 1: the value) or, with `gradient`, the gradient layout (W = 4). */
typedef struct sdf_proto_volume_query {
    int gradient;                    /* 0: value; 1: value and gradient */
    sdf_volume_filter interpolation; /* on the wire: TRILINEAR 0, NEAREST 1, HERMITE 2,
                                        DEFAULT 3 (the volume's order decides, sdf.h) */
    const char *name;
    size_t name_len;
    uint32_t count;
    const void *points;
} sdf_proto_volume_query;

/* Payload size of a VOLUME_QUERY (8 + pad4(name_length) + 12 N), or 0 for a bad name. */
size_t sdf_proto_volume_query_size(const sdf_proto_volume_query *q);
int sdf_proto_decode_volume_query(const void *payload, size_t size, uint32_t max_points,
                                  sdf_proto_volume_query *q, const char **reason);
/* The whole frame's size, or 0 if it does not fit in `cap`, the name is empty / too long or
 * the interpolation is not one of the four. */
size_t sdf_proto_encode_volume_query(void *dst, size_t cap, uint32_t request_id,
                                     const sdf_proto_volume_query *q);

/* RESULT: 12 bytes of header fields then 4 * words * count bytes of data. */
typedef struct sdf_proto_result {
    sdf_proto_mode mode;
    unsigned words;
    uint32_t count;
    const void *data;
} sdf_proto_result;

#define SDF_PROTO_RESULT_PREFIX 8
/* Write the header and the 8-byte result prefix for `count` points of `mode` into dst
 * (SDF_PROTO_HEADER_SIZE + SDF_PROTO_RESULT_PREFIX bytes); the caller appends the data. */
size_t sdf_proto_encode_result_head(void *dst, uint32_t request_id, sdf_proto_mode mode,
                                    uint32_t count);
int sdf_proto_decode_result(const void *payload, size_t size, sdf_proto_result *r,
                            const char **reason);

/* ERROR: status, code name, message. Encoding truncates the message to fit `cap`. */
typedef struct sdf_proto_error {
    uint16_t status;
    const char *code;
    size_t code_len;
    const char *message;
    size_t message_len;
} sdf_proto_error;

/* The status and code name are the sender's (sdfd's error table: server/core/errors.h); returns 0
 * when `cap` cannot hold the frame with the code name. */
size_t sdf_proto_encode_error(void *dst, size_t cap, uint32_t request_id, uint16_t status,
                              const char *code, const char *message);
int sdf_proto_decode_error(const void *payload, size_t size, sdf_proto_error *e,
                           const char **reason);

/* HELLO_OK */
typedef struct sdf_proto_hello {
    uint16_t version;
    uint32_t max_payload, max_points;
    const char *server;
    size_t server_len;
} sdf_proto_hello;

size_t sdf_proto_encode_hello_ok(void *dst, size_t cap, uint32_t request_id,
                                 const sdf_proto_hello *h);
int sdf_proto_decode_hello_ok(const void *payload, size_t size, sdf_proto_hello *h,
                              const char **reason);

/* MESHES: built entry by entry into a caller buffer. */
typedef struct sdf_proto_mesh_entry {
    const char *name;
    size_t name_len;
    uint64_t triangles;
    uint8_t closed;
    uint8_t auto_sign;
} sdf_proto_mesh_entry;

/* Frame size for these entries; encode writes header + payload, returning the size or 0. */
size_t sdf_proto_meshes_size(const sdf_proto_mesh_entry *entries, size_t count);
size_t sdf_proto_encode_meshes(void *dst, size_t cap, uint32_t request_id,
                               const sdf_proto_mesh_entry *entries, size_t count);
/* Iterate: *offset starts at 0 (after reading the count with sdf_proto_meshes_count). */
int sdf_proto_meshes_count(const void *payload, size_t size, uint32_t *count);
int sdf_proto_meshes_next(const void *payload, size_t size, size_t *offset,
                          sdf_proto_mesh_entry *e, const char **reason);

#endif
