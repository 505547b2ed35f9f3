/* optable.c - the table of operations and the lookups over it (optable.h). One line per
 * operation; a route and method without a line does not exist, and an operation without
 * arguments in its line takes none, so a new route is strict until it says otherwise. */
#include "ops/optable.h"

#include <string.h>

#include "core/errors.h"
#include "ops/filterparams.h"
#include "proto.h"
#include "state/registry.h"

#define SLICE_ARGS "axis", "at", "normal", "origin", "bounds", "size", "mode", "step", "format"

static const sdfd_op ops[SDFD_OP_COUNT] = {
    {SDFD_OP_HEALTH, "health", "GET", "/healthz", 0, SDFD_AUTH_NONE,
     SDFD_OP_ALWAYS | SDFD_OP_UNLOGGED, {NULL}},
    {SDFD_OP_READY, "ready", "GET", "/readyz", 0, SDFD_AUTH_NONE,
     SDFD_OP_ALWAYS | SDFD_OP_UNLOGGED, {NULL}},
    {SDFD_OP_METRICS, "metrics", "GET", "/metrics", 0, SDFD_AUTH_NONE,
     SDFD_OP_ALWAYS | SDFD_OP_UNLOGGED, {NULL}},
    {SDFD_OP_OPENAPI, "openapi", "GET", "/openapi.json", 0, SDFD_AUTH_NONE, SDFD_OP_ALWAYS,
     {NULL}},
    {SDFD_OP_PAGE, "page", "GET", "/", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_STATIC, "static", "GET", "/static/{file}", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_MESH_LIST, "meshes", "GET", "/v1/meshes", SDF_PROTO_LIST_MESHES, SDFD_AUTH_NONE,
     0, {NULL}},
    {SDFD_OP_MESH_GET, "mesh", "GET", "/v1/meshes/{name}", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_MESH_PUT, "mesh_put", "PUT", "/v1/meshes/{name}", 0, SDFD_AUTH_WRITE,
     SDFD_OP_BODY | SDFD_OP_ASYNC, {"format"}},
    {SDFD_OP_MESH_DELETE, "mesh_delete", "DELETE", "/v1/meshes/{name}", 0, SDFD_AUTH_WRITE, 0,
     {NULL}},
    {SDFD_OP_QUERY, "query", "POST", "/v1/meshes/{name}/query", SDF_PROTO_QUERY,
     SDFD_AUTH_QUERY, SDFD_OP_BODY | SDFD_OP_FILTER, {"mode", "sign"}},
    {SDFD_OP_BAKE, "bake", "POST", "/v1/meshes/{name}/bake", 0, SDFD_AUTH_WRITE, SDFD_OP_BODY,
     {NULL}},
    {SDFD_OP_MESH_SLICE, "slice", "GET", "/v1/meshes/{name}/slice.png", 0, SDFD_AUTH_QUERY,
     SDFD_OP_FILTER | SDFD_OP_ASYNC, {SLICE_ARGS, "sign"}},
    {SDFD_OP_JOB_LIST, "jobs", "GET", "/v1/jobs", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_JOB_GET, "job", "GET", "/v1/jobs/{id}", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_JOB_CANCEL, "job_cancel", "DELETE", "/v1/jobs/{id}", 0, SDFD_AUTH_WRITE, 0,
     {NULL}},
    {SDFD_OP_VOLUME_LIST, "volumes", "GET", "/v1/volumes", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_VOLUME_GET, "volume", "GET", "/v1/volumes/{name}", 0, SDFD_AUTH_NONE, 0, {NULL}},
    {SDFD_OP_VOLUME_PUT, "volume_put", "PUT", "/v1/volumes/{name}", 0, SDFD_AUTH_WRITE,
     SDFD_OP_BODY | SDFD_OP_ASYNC, {NULL}},
    {SDFD_OP_VOLUME_DELETE, "volume_delete", "DELETE", "/v1/volumes/{name}", 0,
     SDFD_AUTH_WRITE, 0, {NULL}},
    /* a download is every node's answer: a query's rule */
    {SDFD_OP_VOLUME_DATA, "volume_data", "GET", "/v1/volumes/{name}/data", 0, SDFD_AUTH_QUERY,
     SDFD_OP_ASYNC, {"format"}},
    {SDFD_OP_VOLUME_QUERY, "volume_query", "POST", "/v1/volumes/{name}/query",
     SDF_PROTO_VOLUME_QUERY, SDFD_AUTH_QUERY, SDFD_OP_BODY, {"mode", "interpolation"}},
    {SDFD_OP_VOLUME_OPS, "volume_ops", "POST", "/v1/volumes/{name}/ops", 0, SDFD_AUTH_WRITE,
     SDFD_OP_BODY, {NULL}},
    {SDFD_OP_VOLUME_SLICE, "volume_slice", "GET", "/v1/volumes/{name}/slice.png", 0,
     SDFD_AUTH_QUERY, SDFD_OP_ASYNC, {SLICE_ARGS, "interpolation"}},
    /* a surface is every cell's answer: a query's rule; storing it, a write's */
    {SDFD_OP_VOLUME_MESH, "volume_mesh", "GET", "/v1/volumes/{name}/mesh", 0, SDFD_AUTH_QUERY,
     SDFD_OP_ASYNC, {"format", "iso", "cap", "method"}},
    {SDFD_OP_VOLUME_MESH_POST, "volume_mesh_post", "POST", "/v1/volumes/{name}/mesh", 0,
     SDFD_AUTH_WRITE, SDFD_OP_BODY | SDFD_OP_ASYNC, {NULL}},
    /* a binary connection's own: answered whenever it is read */
    {SDFD_OP_HELLO, "hello", NULL, NULL, SDF_PROTO_HELLO, SDFD_AUTH_NONE, SDFD_OP_ALWAYS, {NULL}},
    {SDFD_OP_AUTH, "auth", NULL, NULL, SDF_PROTO_AUTH, SDFD_AUTH_NONE, SDFD_OP_ALWAYS, {NULL}},
};

/* "bin:" and each operation's name, for the operations a frame asks for. */
static const char *const bin_labels[SDFD_OP_COUNT] = {
    [SDFD_OP_MESH_LIST] = "bin:meshes", [SDFD_OP_QUERY] = "bin:query",
    [SDFD_OP_VOLUME_QUERY] = "bin:volume_query", [SDFD_OP_HELLO] = "bin:hello",
    [SDFD_OP_AUTH] = "bin:auth"};

const sdfd_op *sdfd_op_get(sdfd_op_id id)
{
    return &ops[id];
}

/* Whether `url` is `path` with its parameter (if any) filled in: 1 with the parameter's
 * text in *p and its length in *n. */
static int path_matches(const char *path, const char *url, const char **p, size_t *n)
{
    const char *open = strchr(path, '{');
    *p = url, *n = 0;
    if (!open)
        return !strcmp(path, url);
    size_t prefix = (size_t)(open - path);
    const char *suffix = strchr(open, '}') + 1;
    if (strncmp(url, path, prefix))
        return 0;
    const char *param = url + prefix, *slash = strchr(param, '/');
    size_t len = slash ? (size_t)(slash - param) : strlen(param);
    if (strcmp(param + len, suffix))
        return 0;
    *p = param, *n = len;
    return 1;
}

int sdfd_op_match(const char *method, const char *url, const sdfd_op **op, char *param,
                  size_t cap)
{
    const char *m = !strcmp(method, "HEAD") ? "GET" : method;
    const sdfd_op *path_only = NULL;
    param[0] = '\0';
    for (size_t i = 0; i < SDFD_OP_COUNT; i++) {
        const char *p;
        size_t n;
        if (!ops[i].path || !path_matches(ops[i].path, url, &p, &n))
            continue;
        if (strchr(ops[i].path, '{') && (!sdfd_valid_name(p, n) || n >= cap))
            return SDF_EINVAL;
        if (strcmp(ops[i].method, m)) {
            path_only = path_only ? path_only : &ops[i];
            continue;
        }
        memcpy(param, p, n);
        param[n] = '\0';
        *op = &ops[i];
        return 0;
    }
    *op = path_only;
    return path_only ? SDFD_EMETHOD : SDF_ENOTFOUND;
}

const sdfd_op *sdfd_op_of_frame(uint8_t type)
{
    for (size_t i = 0; type && i < SDFD_OP_COUNT; i++)
        if (ops[i].frame == type)
            return &ops[i];
    return NULL;
}

const char *sdfd_op_allowed(const sdfd_op *op, char *buf, size_t cap)
{
    static const char *const order[] = {"GET", "PUT", "POST", "DELETE"};
    size_t at = 0;
    buf[0] = '\0';
    for (size_t k = 0; k < sizeof order / sizeof order[0]; k++)
        for (size_t i = 0; op->path && i < SDFD_OP_COUNT && at < cap; i++) {
            if (!ops[i].path || strcmp(ops[i].path, op->path) || strcmp(ops[i].method, order[k]))
                continue;
            /* HEAD wherever GET: MHD drops the body */
            at += (size_t)snprintf(buf + at, cap - at, "%s%s%s", at ? ", " : "", order[k],
                                   k == 0 ? ", HEAD" : "");
        }
    return buf;
}

const char *sdfd_op_arg(const sdfd_op *op, size_t i)
{
    size_t own = 0;
    while (own < SDFD_OP_MAX_ARGS && op->args[own])
        own++;
    if (i < own)
        return op->args[i];
    return op->flags & SDFD_OP_FILTER ? sdfd_filter_url_name(i - own) : NULL;
}

int sdfd_op_takes(const sdfd_op *op, const char *name)
{
    for (size_t i = 0; i < SDFD_OP_MAX_ARGS && op->args[i]; i++)
        if (!strcmp(op->args[i], name))
            return 1;
    return (op->flags & SDFD_OP_FILTER) && sdfd_filter_is_url_name(name);
}

const char *sdfd_op_label(size_t index)
{
    if (index < SDFD_OP_COUNT)
        return ops[index].path;
    if (index < 2 * SDFD_OP_COUNT)
        return bin_labels[index - SDFD_OP_COUNT];
    return index == SDFD_OP_LABEL_OTHER ? "other"
           : index == SDFD_OP_LABEL_BIN_OTHER ? "bin:other"
                                              : NULL;
}

size_t sdfd_op_label_index(const sdfd_op *op, int binary)
{
    if (!op || (binary ? !bin_labels[op->id] : !op->path))
        return binary ? SDFD_OP_LABEL_BIN_OTHER : SDFD_OP_LABEL_OTHER;
    return binary ? SDFD_OP_COUNT + op->id : op->id;
}

const char *sdfd_op_frame_name(uint8_t type)
{
    return type == SDF_PROTO_QUERY          ? "QUERY"
           : type == SDF_PROTO_VOLUME_QUERY ? "VOLUME_QUERY"
           : type == SDF_PROTO_HELLO        ? "HELLO"
           : type == SDF_PROTO_LIST_MESHES  ? "LIST_MESHES"
           : type == SDF_PROTO_AUTH         ? "AUTH"
                                            : "UNKNOWN";
}

void sdfd_op_describe(FILE *out)
{
    static const char *const auth[] = {"none", "write", "query"};
    fprintf(out, "{\"routes\": [");
    for (size_t i = 0; i < SDFD_OP_COUNT; i++) {
        const sdfd_op *op = &ops[i];
        fprintf(out, "%s\n  {\"operation\": \"%s\", \"method\": ", i ? "," : "", op->name);
        if (op->method)
            fprintf(out, "\"%s\", \"path\": \"%s\", \"label\": \"%s\", ", op->method,
                    op->path, op->path);
        else
            fprintf(out, "null, \"path\": null, \"label\": null, ");
        fprintf(out, "\"auth\": \"%s\", \"body\": %s, \"args\": [", auth[op->auth],
                op->flags & SDFD_OP_BODY ? "true" : "false");
        for (size_t a = 0; sdfd_op_arg(op, a); a++)
            fprintf(out, "%s\"%s\"", a ? ", " : "", sdfd_op_arg(op, a));
        fprintf(out, "], \"frame\": ");
        if (op->frame)
            fprintf(out, "\"%s\"", sdfd_op_frame_name(op->frame));
        else
            fprintf(out, "null");
        if (bin_labels[i])
            fprintf(out, ", \"bin_label\": \"%s\"}", bin_labels[i]);
        else
            fprintf(out, ", \"bin_label\": null}");
    }
    fprintf(out, "\n]}\n");
}
