/* optable.h - the one table of sdfd's operations: for each, its HTTP method and path, the
 * binary frame that asks for it, who may call it, the URL arguments it takes and its label
 * in /metrics and the logs. The HTTP routes, the binary frames, the URL-argument check, the
 * Allow header, the metrics' labels and `sdfd --describe-routes` all read this table, so a
 * route is described once; docs/openapi.yaml describes the same routes for clients, and a
 * test fails on any difference between the two.
 *
 * The table is constant data: thread-safe, nothing to create or free. */
#ifndef SDFD_OPTABLE_H
#define SDFD_OPTABLE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

typedef enum sdfd_op_id {
    SDFD_OP_HEALTH, SDFD_OP_READY, SDFD_OP_METRICS, SDFD_OP_OPENAPI, SDFD_OP_PAGE,
    SDFD_OP_STATIC,
    SDFD_OP_MESH_LIST, SDFD_OP_MESH_GET, SDFD_OP_MESH_PUT, SDFD_OP_MESH_DELETE, SDFD_OP_QUERY,
    SDFD_OP_BAKE, SDFD_OP_MESH_SLICE,
    SDFD_OP_JOB_LIST, SDFD_OP_JOB_GET, SDFD_OP_JOB_CANCEL,
    SDFD_OP_VOLUME_LIST, SDFD_OP_VOLUME_GET, SDFD_OP_VOLUME_PUT, SDFD_OP_VOLUME_DELETE,
    SDFD_OP_VOLUME_DATA, SDFD_OP_VOLUME_QUERY, SDFD_OP_VOLUME_OPS, SDFD_OP_VOLUME_SLICE,
    SDFD_OP_VOLUME_MESH, SDFD_OP_VOLUME_MESH_POST,
    SDFD_OP_HELLO, SDFD_OP_AUTH,
    SDFD_OP_COUNT
} sdfd_op_id;

/* Who may call an operation when sdfd has a --token. */
typedef enum sdfd_auth {
    SDFD_AUTH_NONE,  /* anyone */
    SDFD_AUTH_WRITE, /* only with the token: it changes what is stored, or runs a job */
    SDFD_AUTH_QUERY  /* with the token when --auth-queries is set: it answers with the field */
} sdfd_auth;

enum {
    SDFD_OP_ALWAYS = 1,   /* answered while sdfd loads or drains (probes, metrics) */
    SDFD_OP_BODY = 2,     /* takes a request body (Content-Length required) */
    SDFD_OP_FILTER = 4,   /* takes the filter's URL arguments too (filterparams.h) */
    SDFD_OP_UNLOGGED = 8, /* no request log line (probes and scrapes would drown the log) */
    SDFD_OP_ASYNC = 16,   /* may finish on a worker thread (call.h) */
};

#define SDFD_OP_MAX_ARGS 12

typedef struct sdfd_op {
    sdfd_op_id id;
    const char *name;   /* "query": the binary log's route, and --describe-routes' */
    const char *method; /* "GET", "PUT", "POST", "DELETE"; NULL: binary only */
    const char *path;   /* "/v1/meshes/{name}/query": at most one {parameter}; the label */
    uint8_t frame;      /* the binary frame type asking for it (proto.h), 0: none */
    sdfd_auth auth;
    unsigned flags;     /* SDFD_OP_* */
    const char *args[SDFD_OP_MAX_ARGS]; /* the URL arguments it takes, NULL after the last */
} sdfd_op;

/* The operation `id` (< SDFD_OP_COUNT). */
const sdfd_op *sdfd_op_get(sdfd_op_id id);

/* The operation an HTTP request asks for. HEAD asks for GET's. Returns 0 with *op set and
 * the path's parameter copied into param (cap bytes, "" when the path has none);
 * SDF_ENOTFOUND when no path matches; SDF_EINVAL when the parameter is not a valid name
 * (sdfd_valid_name); SDFD_EMETHOD when the path is known but not with this method (*op is
 * then one of the path's, for its Allow header). */
int sdfd_op_match(const char *method, const char *url, const sdfd_op **op, char *param,
                  size_t cap);

/* The operation a binary frame type asks for, or NULL when none does. */
const sdfd_op *sdfd_op_of_frame(uint8_t type);

/* A frame type's name as the log and --describe-routes spell it ("QUERY"), or "UNKNOWN". */
const char *sdfd_op_frame_name(uint8_t type);

/* The methods the path of `op` takes, as an Allow header lists them ("GET, HEAD, PUT"). */
const char *sdfd_op_allowed(const sdfd_op *op, char *buf, size_t cap);

/* Whether `op` takes the URL argument `name` (its own or, with SDFD_OP_FILTER, a filter's). */
int sdfd_op_takes(const sdfd_op *op, const char *name);

/* The i-th URL argument `op` takes (its own, then the filter's), or NULL after the last. */
const char *sdfd_op_arg(const sdfd_op *op, size_t i);

/* Metric labels: every operation has one for HTTP (its path) and, when a frame asks for it,
 * one for the binary protocol ("bin:" and its name); requests that match nothing count as
 * "other" and "bin:other". Labels are indexed 0..SDFD_OP_LABELS-1 (several indices may
 * share a label text: GET and PUT of one path); NULL for an index without a label. */
#define SDFD_OP_LABELS (2 * SDFD_OP_COUNT + 2)
#define SDFD_OP_LABEL_OTHER (2 * SDFD_OP_COUNT)
#define SDFD_OP_LABEL_BIN_OTHER (2 * SDFD_OP_COUNT + 1)
const char *sdfd_op_label(size_t index);
/* The label index of `op` (NULL: unmatched) over HTTP (binary 0) or the binary protocol. */
size_t sdfd_op_label_index(const sdfd_op *op, int binary);

/* The table as JSON ({"routes": [...]}, docs/api.md "The route table") on `out`. */
void sdfd_op_describe(FILE *out);

#endif
