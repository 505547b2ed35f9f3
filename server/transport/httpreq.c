/* httpreq.c - answering one HTTP request (httpreq.h): responses with the route's usual
 * headers, JSON errors in sdfd's codes, query bodies read in any form, and the wait for work
 * done off MHD's threads (the connection is suspended before the work is handed over, so the
 * worker's resume can never come first). */
#include "transport/httpreq.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/utf8.h"

typedef sdfd_http_request request;

/* ---- responses --------------------------------------------------------------------------- */

/* Queue response r (len bytes) with the type, the extra headers and the route's usual ones. */
enum MHD_Result sdfd_http_queue(request *req, int status, const char *type, struct MHD_Response *r,
                                size_t len, const sdfd_http_header *extra, int n_extra)
{
    if (status != MHD_HTTP_NO_CONTENT) /* no body, so no type (RFC 9110 section 8.3) */
        MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, type);
    for (int i = 0; i < n_extra; i++)
        MHD_add_response_header(r, extra[i].name, extra[i].value);
    if (status == MHD_HTTP_UNAUTHORIZED)
        MHD_add_response_header(r, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
    char allowed[64];
    if (status == MHD_HTTP_METHOD_NOT_ALLOWED && req->op)
        MHD_add_response_header(r, MHD_HTTP_HEADER_ALLOW,
                                sdfd_op_allowed(req->op, allowed, sizeof allowed));
    if (atomic_load(&req->srv->draining))
        MHD_add_response_header(r, MHD_HTTP_HEADER_CONNECTION, "close");
    enum MHD_Result ok = MHD_queue_response(req->conn, (unsigned)status, r);
    MHD_destroy_response(r);
    req->answered = 1;
    req->status = status;
    req->bytes_out = len;
    return ok;
}

enum MHD_Result sdfd_http_send(request *req, int status, const char *type, char *body, size_t len,
                               const sdfd_http_header *extra, int n_extra)
{
    struct MHD_Response *r = MHD_create_response_from_buffer(len, body, MHD_RESPMEM_MUST_FREE);
    if (!r) {
        free(body);
        return MHD_NO;
    }
    return sdfd_http_queue(req, status, type, r, len, extra, n_extra);
}

enum MHD_Result sdfd_http_buffer(request *req, int status, const char *type, char *body, size_t len,
                                 const char *count)
{
    sdfd_http_header h = {"X-SDF-Count", ""};
    if (count)
        snprintf(h.value, sizeof h.value, "%s", count);
    return sdfd_http_send(req, status, type, body, len, &h, count ? 1 : 0);
}

enum MHD_Result sdfd_http_json(request *req, int status, cJSON *json)
{
    char *text = cJSON_PrintUnformatted(json);
    cJSON_Delete(json);
    if (!text)
        return MHD_NO;
    return sdfd_http_buffer(req, status, "application/json", text, strlen(text), NULL);
}

/* The message and argument often quote the client's bytes: cleaned to UTF-8 (utf8.h). */
static enum MHD_Result error_body(request *req, int code, const char *argument,
                                  const char *message)
{
    char text[768], name[256];
    cJSON *root = cJSON_CreateObject(), *err = cJSON_AddObjectToObject(root, "error");
    cJSON_AddStringToObject(err, "code", sdfd_errname(code));
    sdfd_utf8_clean(text, sizeof text, message);
    cJSON_AddStringToObject(err, "message", text);
    if (argument && argument[0]) {
        sdfd_utf8_clean(name, sizeof name, argument);
        cJSON_AddStringToObject(err, "argument", name);
    }
    return sdfd_http_json(req, sdfd_http_status(code), root);
}

enum MHD_Result sdfd_http_error(request *req, int code, const char *fmt, ...)
{
    char message[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    return error_body(req, code, NULL, message);
}

enum MHD_Result sdfd_http_refuse(request *req, int code, const char *argument, const char *fmt,
                                 ...)
{
    char message[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    return error_body(req, code, argument, message);
}

/* The filled req->reply in the reply form, with the point count in X-SDF-Count. */
enum MHD_Result sdfd_http_results(request *req)
{
    size_t len;
    char *body = sdfd_reply_render(&req->reply, req->reply_form, &len);
    if (!body)
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory formatting %zu results",
                               req->points);
    char count[32];
    snprintf(count, sizeof count, "%zu", req->points);
    return sdfd_http_buffer(req, 200, sdfd_form_type(req->reply_form), body, len, count);
}

/* ---- URL arguments ----------------------------------------------------------------------- */

static enum MHD_Result collect(void *cls, enum MHD_ValueKind kind, const char *key,
                               const char *value)
{
    (void)kind;
    sdfd_url_args_add(cls, key, value);
    return MHD_YES;
}

int sdfd_http_check_args(request *req, enum MHD_Result *refused)
{
    req->args = (sdfd_url_args){.n = 0};
    MHD_get_connection_values(req->conn, MHD_GET_ARGUMENT_KIND, collect, &req->args);
    char err[300];
    const char *argument;
    if (!sdfd_url_args_check(&req->args, req->op, err, sizeof err, &argument))
        return 0;
    *refused = sdfd_http_refuse(req, SDF_EINVAL, argument, "%s", err);
    return -1;
}

/* ---- query bodies ------------------------------------------------------------------------ */

const char *sdfd_http_param(const char *value, size_t n, char *buf, size_t cap)
{
    if (!value)
        return NULL;
    snprintf(buf, cap, "%.*s", (int)(n < cap ? n : cap - 1), value);
    return buf;
}

int sdfd_http_reply_form(request *req, sdfd_form request_form)
{
    const char *accept = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                     MHD_HTTP_HEADER_ACCEPT);
    int f = sdfd_form_from_type(accept);
    return f >= 0 ? f : (int)request_form;
}

/* The URL's `key` into *v when the body has none; given in both, it is refused. */
static int url_param(request *req, const char *key, const char **v, size_t *n,
                     enum MHD_Result *refused)
{
    const char *u = sdfd_url_value(&req->args, key);
    if (!u)
        return 0;
    if (*v) {
        *refused = sdfd_http_refuse(req, SDF_EINVAL, key, "'%s' is given twice: in the JSON "
                                    "body and in the URL", key);
        return -1;
    }
    *v = u, *n = strlen(u);
    return 0;
}

/* A body's parameters and the URL's together (the URL's names were checked at admission). */
static int merge_params(request *req, sdfd_query_params *p, enum MHD_Result *refused)
{
    int volume = req->op->id == SDFD_OP_VOLUME_QUERY;
    const char *stray = volume ? (p->sign ? "sign" : p->filter ? "filter" : NULL)
                               : (p->interpolation ? "interpolation" : NULL);
    if (stray) {
        *refused = sdfd_http_error(req, SDF_EINVAL, "a %s query takes no \"%s\" (it takes %s)",
                                   volume ? "volume" : "mesh", stray,
                                   volume ? "\"mode\" and \"interpolation\""
                                          : "\"mode\", \"sign\" and \"filter\"");
        return -1;
    }
    const char *filter_arg = sdfd_url_first_filter_arg(&req->args);
    if (p->filter && filter_arg) {
        *refused = sdfd_http_refuse(req, SDF_EINVAL, filter_arg, "the filter is given twice: a "
                                    "\"filter\" in the JSON body and '%s' in the URL",
                                    filter_arg);
        return -1;
    }
    if (url_param(req, "mode", &p->mode, &p->mode_len, refused) ||
        url_param(req, "sign", &p->sign, &p->sign_len, refused) ||
        url_param(req, "interpolation", &p->interpolation, &p->interpolation_len, refused))
        return -1;
    return 0;
}

/* Parse a query body of any form into req->points_buf. Returns 0, or -1 with the error
 * queued and its MHD result in *refused. */
int sdfd_http_read_points(request *req, sdfd_form *form, sdfd_query_params *params, size_t *count,
                          enum MHD_Result *refused)
{
    const char *type = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                   MHD_HTTP_HEADER_CONTENT_TYPE);
    int f = sdfd_form_from_type(type);
    if (f < 0) {
        *refused = sdfd_http_error(req, SDF_EFORMAT,
                                   "Content-Type must be application/json, "
                                   "application/octet-stream or application/x-npy");
        return -1;
    }
    *form = (sdfd_form)f;
    *params = (sdfd_query_params){0};
    char err[256];
    int rc = sdfd_parse_points(*form, req->body, req->len, req->srv->cfg.max_points, params,
                               &req->points_buf, count, &req->points_owned, err, sizeof err);
    if (rc) {
        *refused = sdfd_http_error(req, rc, "%s", err);
        return -1;
    }
    return merge_params(req, params, refused);
}

/* ---- work done elsewhere ------------------------------------------------------------------ */

void sdfd_http_wait(request *req, sdfd_http_respond respond)
{
    req->waiting = 1;
    req->respond = respond;
    MHD_suspend_connection(req->conn);
}

void sdfd_http_unwait(request *req)
{
    req->waiting = 0;
    MHD_resume_connection(req->conn);
}

void sdfd_http_resume(request *req)
{
    atomic_store(&req->finished, 1);
    MHD_resume_connection(req->conn);
}

/* ---- results ----------------------------------------------------------------------------- */

/* A streamed result: a volume's node words as stored (after an npy header for npy), sent
 * straight from the volume, which the response holds a reference to, instead of a copy the
 * size of the volume. */
typedef struct volume_stream {
    sdfd_stored_volume *stored;
    char header[512];
    size_t header_len;
} volume_stream;

static ssize_t read_volume_stream(void *cls, uint64_t pos, char *buf, size_t max)
{
    volume_stream *s = cls;
    size_t total = s->header_len + sdf_volume_data_bytes(s->stored->volume), n = 0;
    if (pos >= total)
        return MHD_CONTENT_READER_END_OF_STREAM;
    while (n < max && pos < total) {
        size_t at = (size_t)pos, chunk;
        const char *from;
        if (at < s->header_len)
            from = s->header + at, chunk = s->header_len - at;
        else
            from = (const char *)sdf_volume_data(s->stored->volume) + (at - s->header_len),
            chunk = total - at;
        if (chunk > max - n)
            chunk = max - n;
        memcpy(buf + n, from, chunk);
        n += chunk, pos += chunk;
    }
    return (ssize_t)n;
}

static void free_volume_stream(void *cls)
{
    volume_stream *s = cls;
    sdfd_volume_release(s->stored);
    free(s);
}

static enum MHD_Result stream_volume(request *req, sdfd_result *r)
{
    volume_stream *s = calloc(1, sizeof *s);
    if (!s)
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory");
    const sdf_volume *v = r->stream->volume;
    if (r->file == SDF_VOLUME_NPY) {
        long len = sdf_volume_npy_header(v, s->header, sizeof s->header);
        if (len < 0) {
            free(s);
            return sdfd_http_error(req, (int)len, "cannot write the npy header");
        }
        s->header_len = (size_t)len;
    }
    s->stored = r->stream; /* the stream's own reference: it may outlive the request */
    r->stream = NULL;
    size_t total = s->header_len + sdf_volume_data_bytes(v);
    struct MHD_Response *resp = MHD_create_response_from_callback(
        total, 1 << 16, read_volume_stream, s, free_volume_stream);
    if (!resp) {
        free_volume_stream(s);
        return MHD_NO;
    }
    return sdfd_http_queue(req, r->status, r->type, resp, total, r->fields, r->n_fields);
}

enum MHD_Result sdfd_http_result(request *req, sdfd_result *r)
{
    if (r->code)
        return sdfd_http_refuse(req, r->code, r->argument, "%s", r->message);
    if (r->stream)
        return stream_volume(req, r);
    char *body = r->bytes;
    size_t len = r->len;
    const char *type = r->type ? r->type : "application/json";
    if (r->json) {
        body = cJSON_PrintUnformatted(r->json);
        if (!body)
            return MHD_NO;
        len = strlen(body);
    }
    r->bytes = NULL; /* MHD frees it */
    return sdfd_http_send(req, r->status, type, body, len, r->fields, r->n_fields);
}
