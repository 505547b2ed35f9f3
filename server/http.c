/* http.c - the HTTP API on libmicrohttpd (routes in docs/api.md).
 *
 * MHD's threads only do I/O: they receive bodies, parse them, format replies. Geometry runs
 * elsewhere: a query becomes a batcher job and a mesh upload a loader thread, and the
 * connection is suspended (MHD_suspend_connection) until that work resumes it. The
 * connection is suspended before the work is handed over, so the resume can never come
 * first.
 *
 * Each request walks the same steps: `admit` (route, method, auth, Content-Length, all
 * checked from the headers before any body byte is read), `receive` (append the body, never
 * past its declared length), `dispatch` (start the work, or answer at once), and after a
 * resume, `reply_*`. The completion callback logs, counts and frees. */
#include "http.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <microhttpd.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bakeparams.h"
#include "body.h"
#include "filterparams.h"
#include "log.h"

struct sdfd_http {
    sdfd_server *srv;
    struct MHD_Daemon *daemon;
    int listen_fd;
};

/* Work a request waits for: a batcher job, or a thread of its own running `run` (uploads,
 * volume queries and file encodings: not geometry for the batcher, but too slow for MHD's
 * I/O threads). */
typedef enum work { WORK_NONE, WORK_QUERY, WORK_THREAD } work;

typedef struct request request;
typedef void (*thread_work)(request *req);

/* A response header beyond the type and count. */
typedef struct header {
    const char *name;
    char value[300];
} header;

struct request {
    sdfd_http *http;
    struct MHD_Connection *conn;
    const char *method;
    sdfd_route route;
    char route_text[96];
    char name[SDFD_MAX_NAME + 1]; /* mesh or volume name, or job id, from the URL */
    double start;
    int answered;                 /* a response is queued */
    int status;
    size_t points, bytes_out;
    /* body */
    char *body;
    size_t len, declared;
    /* background work; `finished` is set by the worker before it resumes the connection */
    work work;
    atomic_int finished;
    sdfd_job job;
    float *points_buf;
    int points_owned;
    sdfd_form reply_form;
    sdfd_reply reply;
    char format[16];              /* ?format= of an upload, copied on the MHD thread */
    sdf_mesh *uploaded;
    sdf_mesh *volume; /* a filtered query's smoothing mesh, held until the request ends */
    int work_rc, replaced;        /* a thread's result: 0 or SDF_E* (message in diag) */
    sdf_diag diag;
    /* WORK_THREAD: `run` leaves a status (0 or SDF_E*, message in diag) and a body */
    thread_work run;
    enum MHD_Result (*respond)(request *req); /* back on the MHD thread: queue the response */
    sdfd_stored_volume *stored;   /* a volume query's or download's volume */
    sdf_volume_filter interpolation;
    sdf_volume_file file_type;
    char *out_body;
    size_t out_len;
};

/* ---- responses --------------------------------------------------------------------------- */

static const char *allowed_methods(sdfd_route route)
{
    switch (route) {
    case SDFD_ROUTE_MESH:
    case SDFD_ROUTE_VOLUME:
        return "GET, PUT, DELETE";
    case SDFD_ROUTE_QUERY:
    case SDFD_ROUTE_BAKE:
    case SDFD_ROUTE_VOLUME_QUERY:
        return "POST";
    case SDFD_ROUTE_JOB:
        return "GET, DELETE";
    default:
        return "GET, HEAD";
    }
}

/* Queue response r (len bytes) with the type, the extra headers and the route's usual ones. */
static enum MHD_Result queue_response(request *req, int status, const char *type,
                                      struct MHD_Response *r, size_t len, const header *extra,
                                      int n_extra)
{
    MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, type);
    for (int i = 0; i < n_extra; i++)
        MHD_add_response_header(r, extra[i].name, extra[i].value);
    if (status == MHD_HTTP_UNAUTHORIZED)
        MHD_add_response_header(r, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
    if (status == MHD_HTTP_METHOD_NOT_ALLOWED)
        MHD_add_response_header(r, MHD_HTTP_HEADER_ALLOW, allowed_methods(req->route));
    if (atomic_load(&req->http->srv->draining))
        MHD_add_response_header(r, MHD_HTTP_HEADER_CONNECTION, "close");
    enum MHD_Result ok = MHD_queue_response(req->conn, (unsigned)status, r);
    MHD_destroy_response(r);
    req->answered = 1;
    req->status = status;
    req->bytes_out = len;
    return ok;
}

static enum MHD_Result send_with_headers(request *req, int status, const char *type, char *body,
                                         size_t len, const header *extra, int n_extra)
{
    struct MHD_Response *r = MHD_create_response_from_buffer(len, body, MHD_RESPMEM_MUST_FREE);
    if (!r) {
        free(body);
        return MHD_NO;
    }
    return queue_response(req, status, type, r, len, extra, n_extra);
}

static enum MHD_Result send_buffer(request *req, int status, const char *type, char *body,
                                   size_t len, const char *count)
{
    header h = {"X-SDF-Count", ""};
    if (count)
        snprintf(h.value, sizeof h.value, "%s", count);
    return send_with_headers(req, status, type, body, len, &h, count ? 1 : 0);
}

static enum MHD_Result send_json(request *req, int status, cJSON *json)
{
    char *text = cJSON_PrintUnformatted(json);
    cJSON_Delete(json);
    if (!text)
        return MHD_NO;
    return send_buffer(req, status, "application/json", text, strlen(text), NULL);
}

/* {"error": {"code": "ENOTFOUND", "message": "..."}} with the code's HTTP status. */
static enum MHD_Result send_error(request *req, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static enum MHD_Result send_error(request *req, int code, const char *fmt, ...)
{
    char message[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    cJSON *root = cJSON_CreateObject(), *err = cJSON_AddObjectToObject(root, "error");
    cJSON_AddStringToObject(err, "code", sdf_errname(code));
    cJSON_AddStringToObject(err, "message", message);
    return send_json(req, sdf_http_status(code), root);
}

static cJSON *report_json(const char *name, const sdf_mesh *mesh)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", name);
    cJSON_AddStringToObject(o, "format", sdf_format_name(r.format));
    cJSON_AddNumberToObject(o, "vertices", (double)r.vertices);
    cJSON_AddNumberToObject(o, "input_vertices", (double)r.input_vertices);
    cJSON_AddNumberToObject(o, "triangles", (double)r.triangles);
    cJSON *bbox = cJSON_AddObjectToObject(o, "bbox");
    cJSON_AddItemToObject(bbox, "min", cJSON_CreateFloatArray(r.bbox_min, 3));
    cJSON_AddItemToObject(bbox, "max", cJSON_CreateFloatArray(r.bbox_max, 3));
    cJSON_AddNumberToObject(o, "diagonal", r.diagonal);
    cJSON_AddBoolToObject(o, "closed", r.closed);
    cJSON_AddBoolToObject(o, "edge_manifold", r.edge_manifold);
    cJSON_AddBoolToObject(o, "self_intersecting", r.self_intersecting);
    cJSON_AddBoolToObject(o, "flipped", r.flipped);
    cJSON_AddNumberToObject(o, "degenerate_triangles", (double)r.degenerate_triangles);
    cJSON_AddNumberToObject(o, "boundary_edges", (double)r.boundary_edges);
    cJSON_AddNumberToObject(o, "nonmanifold_edges", (double)r.nonmanifold_edges);
    cJSON_AddNumberToObject(o, "misoriented_edges", (double)r.misoriented_edges);
    cJSON_AddNumberToObject(o, "volume", r.volume);
    cJSON_AddStringToObject(o, "sign", sdf_sign_name(r.auto_sign));
    cJSON_AddNumberToObject(o, "index_bytes", (double)r.index_bytes);
    cJSON_AddNumberToObject(o, "build_seconds", r.build_seconds);
    return o;
}

/* ---- admission: everything decided from the request line and headers ------------------- */

static int parse_route(request *req, const char *url)
{
    static const struct { const char *path; sdfd_route route; } fixed[] = {
        {"/healthz", SDFD_ROUTE_HEALTH}, {"/readyz", SDFD_ROUTE_READY},
        {"/metrics", SDFD_ROUTE_METRICS}, {"/v1/meshes", SDFD_ROUTE_MESHES},
        {"/v1/jobs", SDFD_ROUTE_JOBS}, {"/v1/volumes", SDFD_ROUTE_VOLUMES}};
    /* collection/{name}[suffix] */
    static const struct { const char *collection, *suffix; sdfd_route route; } named[] = {
        {"/v1/meshes/", "", SDFD_ROUTE_MESH}, {"/v1/meshes/", "/query", SDFD_ROUTE_QUERY},
        {"/v1/meshes/", "/bake", SDFD_ROUTE_BAKE}, {"/v1/jobs/", "", SDFD_ROUTE_JOB},
        {"/v1/volumes/", "", SDFD_ROUTE_VOLUME}, {"/v1/volumes/", "/data", SDFD_ROUTE_VOLUME_DATA},
        {"/v1/volumes/", "/query", SDFD_ROUTE_VOLUME_QUERY}};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        if (!strcmp(url, fixed[i].path)) {
            req->route = fixed[i].route;
            snprintf(req->route_text, sizeof req->route_text, "%s", url);
            return 0;
        }
    }
    for (size_t i = 0; i < sizeof named / sizeof named[0]; i++) {
        size_t c = strlen(named[i].collection);
        if (strncmp(url, named[i].collection, c))
            continue;
        const char *name = url + c, *slash = strchr(name, '/');
        size_t n = slash ? (size_t)(slash - name) : strlen(name);
        if (strcmp(slash ? slash : "", named[i].suffix))
            continue;
        if (!sdfd_valid_name(name, n))
            return -2;
        memcpy(req->name, name, n);
        req->name[n] = '\0';
        req->route = named[i].route;
        snprintf(req->route_text, sizeof req->route_text, "%s", sdfd_route_name(req->route));
        return 0;
    }
    return -1;
}

static int method_allowed(const request *req)
{
    const char *list = allowed_methods(req->route), *m = req->method;
    size_t n = strlen(m);
    for (const char *p = strstr(list, m); p; p = strstr(p + 1, m))
        if ((p == list || p[-1] == ' ') && (p[n] == ',' || p[n] == '\0'))
            return 1;
    return 0;
}

static int authorized(const request *req)
{
    const sdfd_config *cfg = &req->http->srv->cfg;
    int needs = !strcmp(req->method, "PUT") || !strcmp(req->method, "DELETE") ||
                req->route == SDFD_ROUTE_BAKE ||
                (cfg->auth_queries &&
                 (req->route == SDFD_ROUTE_QUERY || req->route == SDFD_ROUTE_VOLUME_QUERY));
    if (!cfg->token || !needs)
        return 1;
    const char *h = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                MHD_HTTP_HEADER_AUTHORIZATION);
    return h && !strncmp(h, "Bearer ", 7) && !strcmp(h + 7, cfg->token);
}

/* Decide from the headers alone; returns MHD_YES with a response queued if refused. */
static enum MHD_Result admit(request *req, const char *url)
{
    sdfd_server *srv = req->http->srv;
    int route = parse_route(req, url);
    if (route == -1)
        return send_error(req, SDF_ENOTFOUND, "no route %s", url);
    if (route == -2)
        return send_error(req, SDF_EINVAL, "names are 1-255 characters of A-Z a-z 0-9 . _ - "
                                           "and do not start with '.'");
    if (!method_allowed(req))
        return send_error(req, SDF_EMETHOD, "%s is not allowed on %s", req->method, req->route_text);
    if (!authorized(req))
        return send_error(req, SDF_EUNAUTHORIZED, "this request needs 'Authorization: Bearer <token>'");
    if (atomic_load(&srv->draining) && req->route != SDFD_ROUTE_HEALTH &&
        req->route != SDFD_ROUTE_READY && req->route != SDFD_ROUTE_METRICS)
        return send_error(req, SDF_EUNAVAILABLE, "the server is shutting down");
    int has_body = !strcmp(req->method, "POST") || !strcmp(req->method, "PUT");
    if (!has_body)
        return MHD_YES;
    const char *cl = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_CONTENT_LENGTH);
    char *end;
    unsigned long long declared = cl ? strtoull(cl, &end, 10) : 0;
    if (!cl || !*cl || *end)
        return send_error(req, SDF_ELENGTH, "send the body with a Content-Length header");
    if (declared > srv->cfg.max_body_bytes)
        return send_error(req, SDF_ELIMIT, "the body is %llu bytes, over the limit of %zu",
                          declared, srv->cfg.max_body_bytes);
    /* The whole body in one allocation, sized by a checked length, NUL-terminated. */
    req->declared = (size_t)declared;
    req->body = malloc(req->declared + 1);
    if (!req->body)
        return send_error(req, SDF_ENOMEM, "out of memory for a %zu-byte body", req->declared);
    req->body[0] = '\0';
    return MHD_YES;
}

/* ---- work: queries ----------------------------------------------------------------------- */

static void query_done(sdfd_job *job)
{
    request *req = job->user;
    atomic_store(&req->finished, 1);
    MHD_resume_connection(req->conn);
}

/* A parameter from the body (JSON) or else the URL query string. */
static const char *param(request *req, const char *body_value, size_t n, const char *key,
                         char *buf, size_t cap)
{
    if (body_value) {
        snprintf(buf, cap, "%.*s", (int)(n < cap ? n : cap - 1), body_value);
        return buf;
    }
    return MHD_lookup_connection_value(req->conn, MHD_GET_ARGUMENT_KIND, key);
}

/* URL argument `name` of a connection (for sdfd_filter_from_strings). */
static const char *url_argument(void *conn, const char *name)
{
    return MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, name);
}

static int reply_form(request *req, sdfd_form request_form)
{
    const char *accept = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                     MHD_HTTP_HEADER_ACCEPT);
    int f = sdfd_form_from_type(accept);
    return f >= 0 ? f : (int)request_form;
}

/* Parse a query body of any form into req->points_buf. Returns 0, or -1 with the error
 * queued and its MHD result in *refused. */
static int read_points(request *req, sdfd_form *form, sdfd_query_params *params, size_t *count,
                       enum MHD_Result *refused)
{
    const char *type = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                   MHD_HTTP_HEADER_CONTENT_TYPE);
    int f = sdfd_form_from_type(type);
    if (f < 0) {
        *refused = send_error(req, SDF_EFORMAT, "Content-Type must be application/json, "
                                                "application/octet-stream or application/x-npy");
        return -1;
    }
    *form = (sdfd_form)f;
    *params = (sdfd_query_params){0};
    char err[256];
    int rc = sdfd_parse_points(*form, req->body, req->len, req->http->srv->cfg.max_points, params,
                               &req->points_buf, count, &req->points_owned, err, sizeof err);
    if (rc) {
        *refused = send_error(req, rc, "%s", err);
        return -1;
    }
    return 0;
}

static enum MHD_Result start_query(request *req)
{
    sdfd_server *srv = req->http->srv;
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (read_points(req, &form, &params, &count, &refused))
        return refused;
    char err[256], mode_buf[32], sign_buf[32];
    int rc;
    const char *mode = param(req, params.mode, params.mode_len, "mode", mode_buf, sizeof mode_buf);
    const char *sign = param(req, params.sign, params.sign_len, "sign", sign_buf, sizeof sign_buf);
    sdf_proto_mode m = SDF_MODE_SIGNED;
    sdf_sign_method s = SDF_SIGN_AUTO;
    if (mode && sdf_proto_mode_from_name(mode, &m))
        return send_error(req, SDF_EINVAL,
                          "unknown mode '%s' (signed, distance, gradient, closest, filtered, "
                          "filtered-gradient)", mode);
    if (sign && sdf_sign_from_name(sign, &s))
        return send_error(req, SDF_EINVAL,
                          "unknown sign '%s' (auto, pseudonormal, winding, raycast, none)", sign);
    sdf_filter_options filter = {0};
    char volume_name[SDFD_VOLUME_NAME_MAX + 1] = "";
    if (sdf_proto_mode_filtered(m)) {
        rc = params.filter ? sdfd_filter_from_json(params.filter, params.filter_len, &filter,
                                                   volume_name, err, sizeof err)
                           : sdfd_filter_from_strings(url_argument, req->conn, &filter,
                                                      volume_name, err, sizeof err);
        if (rc)
            return send_error(req, rc, "%s", err);
        if (volume_name[0]) {
            req->volume = sdfd_registry_get(srv->registry, volume_name, strlen(volume_name));
            if (!req->volume)
                return send_error(req, SDF_ENOTFOUND, "no smoothing mesh named '%s'", volume_name);
            filter.smooth.mesh = req->volume;
        }
    }
    sdf_mesh *mesh = sdfd_registry_get(srv->registry, req->name, strlen(req->name));
    if (!mesh)
        return send_error(req, SDF_ENOTFOUND, "no mesh named '%s'", req->name);
    if (sdf_proto_mode_filtered(m) &&
        (rc = sdfd_filter_validate(mesh, &filter, count,
                                   SDFD_FILTER_QUERIES_PER_POINT_LIMIT * srv->cfg.max_points, err,
                                   sizeof err))) {
        sdf_mesh_release(mesh);
        return send_error(req, rc, "%s", err);
    }
    req->points = count;
    req->reply_form = (sdfd_form)reply_form(req, form);
    if (sdfd_reply_init(&req->reply, req->reply_form, m, count)) {
        sdf_mesh_release(mesh);
        return send_error(req, SDF_ENOMEM, "out of memory for %zu results", count);
    }
    req->job = (sdfd_job){.mesh = mesh, .mode = m, .sign = s, .filter = filter,
                          .points = req->points_buf,
                          .count = count, .words = req->reply.words, .done = query_done,
                          .user = req};
    req->work = WORK_QUERY;
    MHD_suspend_connection(req->conn); /* before submitting: the resume cannot come first */
    size_t bad = 0;
    rc = sdfd_batcher_submit(srv->batcher, &req->job, &bad);
    if (rc) {
        req->work = WORK_NONE;
        MHD_resume_connection(req->conn);
        if (rc == SDF_ENONFINITE)
            return send_error(req, rc, "point %zu has a NaN or infinite coordinate", bad);
        if (rc == SDF_EBUSY)
            return send_error(req, rc, "more than %zu points are waiting; retry later",
                              srv->cfg.max_queued_points);
        return send_error(req, rc, "%s", sdf_strerror(rc));
    }
    sdfd_metrics_points(srv->metrics, count);
    return MHD_YES;
}

/* The filled req->reply in the reply form, with the point count in X-SDF-Count. */
static enum MHD_Result send_results(request *req)
{
    size_t len;
    char *body = sdfd_reply_render(&req->reply, req->reply_form, &len);
    if (!body)
        return send_error(req, SDF_ENOMEM, "out of memory formatting %zu results", req->points);
    char count[32];
    snprintf(count, sizeof count, "%zu", req->points);
    return send_buffer(req, 200, sdfd_form_type(req->reply_form), body, len, count);
}

static enum MHD_Result reply_query(request *req)
{
    if (req->job.status)
        return send_error(req, req->job.status, "query failed: %s", sdf_strerror(req->job.status));
    return send_results(req);
}

/* ---- work: uploads ----------------------------------------------------------------------- */

/* ---- work on a thread of its own ---------------------------------------------------------- */

static void *thread_main(void *arg)
{
    request *req = arg;
    req->run(req);
    atomic_store(&req->finished, 1);
    MHD_resume_connection(req->conn);
    return NULL;
}

/* Suspend the connection and run `run` on a new thread; `respond` answers after the resume. */
static enum MHD_Result start_thread(request *req, thread_work run,
                                    enum MHD_Result (*respond)(request *req))
{
    pthread_t t;
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    req->work = WORK_THREAD;
    req->run = run;
    req->respond = respond;
    MHD_suspend_connection(req->conn);
    int failed = pthread_create(&t, &attr, thread_main, req);
    pthread_attr_destroy(&attr);
    if (failed) {
        req->work = WORK_NONE;
        MHD_resume_connection(req->conn);
        return send_error(req, SDF_EUNAVAILABLE, "cannot start a worker thread");
    }
    return MHD_YES;
}

static enum MHD_Result reply_upload(request *req);

static void load_upload(request *req)
{
    sdfd_server *srv = req->http->srv;
    sdf_mesh_options opts = {.max_triangles = srv->cfg.max_total_triangles};
    if (req->format[0] && sdf_format_from_name(req->format, &opts.format)) {
        req->work_rc = SDF_EFORMAT;
        snprintf(req->diag.message, sizeof req->diag.message,
                 "unknown format '%s' (obj, ply, stl, off)", req->format);
    } else {
        req->work_rc = sdf_mesh_load_memory(req->body, req->len, &opts, &req->uploaded, &req->diag);
    }
    if (!req->work_rc) {
        req->work_rc = sdfd_registry_put(srv->registry, req->name,
                                           sdf_mesh_retain(req->uploaded), &req->replaced);
        if (req->work_rc == SDF_ELIMIT)
            snprintf(req->diag.message, sizeof req->diag.message,
                     "loading it would exceed --max-meshes or --max-triangles");
    }
}

static enum MHD_Result start_upload(request *req)
{
    /* The loader thread must not call MHD: take what it needs from the request now. */
    const char *format = MHD_lookup_connection_value(req->conn, MHD_GET_ARGUMENT_KIND, "format");
    if (format)
        snprintf(req->format, sizeof req->format, "%s", format);
    return start_thread(req, load_upload, reply_upload);
}

static enum MHD_Result reply_upload(request *req)
{
    if (req->work_rc)
        return send_error(req, req->work_rc, "%s", req->diag.message);
    sdfd_log("info", "mesh_loaded", "%s: %s by upload", req->name, req->replaced ? "replaced" : "added");
    return send_json(req, req->replaced ? 200 : 201, report_json(req->name, req->uploaded));
}

/* ---- work: bakes, jobs and volumes -------------------------------------------------------- */

static cJSON *job_json(const sdfd_job_status *s)
{
    cJSON *o = cJSON_CreateObject();
    char href[64];
    snprintf(href, sizeof href, "/v1/jobs/%s", s->id);
    cJSON_AddStringToObject(o, "id", s->id);
    cJSON_AddStringToObject(o, "href", href);
    cJSON_AddStringToObject(o, "state", sdfd_job_state_name(s->state));
    cJSON_AddNumberToObject(o, "progress", s->progress);
    cJSON_AddNumberToObject(o, "percent", floor(s->progress * 1000) / 10);
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    cJSON_AddStringToObject(o, "volume", s->volume);
    cJSON_AddNumberToObject(o, "seconds", s->seconds);
    if (s->state == SDFD_JOB_FAILED) {
        cJSON *err = cJSON_AddObjectToObject(o, "error");
        cJSON_AddStringToObject(err, "code", sdf_errname(s->error));
        cJSON_AddStringToObject(err, "message", s->message);
    }
    return o;
}

/* Check a bake's options against the mesh and the server's limits, as the job would. */
static int check_bake(request *req, const sdf_mesh *mesh, sdfd_bake_request *bake,
                      char *err, size_t cap)
{
    const sdfd_config *cfg = &req->http->srv->cfg;
    sdf_bake_options o = bake->options;
    o.filter = bake->filtered ? &bake->filter : NULL;
    sdf_volume_info planned;
    sdf_diag diag = {0};
    int rc = sdf_volume_plan(mesh, &o, &planned, &diag);
    if (rc) {
        snprintf(err, cap, "%s", diag.message);
        return rc;
    }
    size_t nodes = planned.dims[0] * planned.dims[1] * planned.dims[2];
    size_t side = planned.order ? 2 * (size_t)planned.fine_half + 1 : 1;
    size_t points = nodes * side * side * side;
    if (bake->filtered)
        return sdfd_filter_validate(mesh, &bake->filter, points, cfg->max_bake_queries, err, cap);
    if (points > cfg->max_bake_queries) {
        snprintf(err, cap, "the bake costs %zu distance queries, over --max-bake-queries %zu; "
                 "lower the resolution", points, cfg->max_bake_queries);
        return SDF_ELIMIT;
    }
    return 0;
}

static enum MHD_Result start_bake(request *req)
{
    sdfd_server *srv = req->http->srv;
    sdfd_bake_request bake; /* the body is JSON whatever its Content-Type says (curl -d) */
    sdfd_bake_names names;
    char err[512];
    int rc = sdfd_bake_from_json(req->body, req->len, &bake, &names, err, sizeof err);
    if (rc)
        return send_error(req, rc, "%s", err);
    sdf_mesh *mesh = sdfd_registry_get(srv->registry, req->name, strlen(req->name));
    if (!mesh)
        return send_error(req, SDF_ENOTFOUND, "no mesh named '%s'", req->name);
    if (names.smoothing_mesh[0]) {
        bake.smoothing_mesh = sdfd_registry_get(srv->registry, names.smoothing_mesh,
                                                strlen(names.smoothing_mesh));
        if (!bake.smoothing_mesh) {
            sdf_mesh_release(mesh);
            return send_error(req, SDF_ENOTFOUND, "no smoothing mesh named '%s'",
                              names.smoothing_mesh);
        }
        bake.filter.smooth.mesh = bake.smoothing_mesh;
    }
    if ((rc = check_bake(req, mesh, &bake, err, sizeof err))) {
        sdf_mesh_release(mesh);
        sdf_mesh_release(bake.smoothing_mesh);
        return send_error(req, rc, "%s", err);
    }
    const char *volume = names.volume[0] ? names.volume : req->name;
    char id[24];
    /* The job takes over both mesh references, also when it fails to start. */
    rc = sdfd_volumes_bake(srv->volumes, mesh, req->name, volume, &bake, id, err, sizeof err);
    if (rc)
        return send_error(req, rc, "%s", err);
    sdfd_job_status status;
    sdfd_volumes_job(srv->volumes, id, &status);
    header location = {MHD_HTTP_HEADER_LOCATION, ""};
    snprintf(location.value, sizeof location.value, "/v1/jobs/%s", id);
    cJSON *json = job_json(&status);
    char *text = cJSON_PrintUnformatted(json);
    cJSON_Delete(json);
    return text ? send_with_headers(req, 202, "application/json", text, strlen(text), &location, 1)
                : MHD_NO;
}

static enum MHD_Result job_route(request *req)
{
    sdfd_server *srv = req->http->srv;
    sdfd_job_status s;
    int deleting = !strcmp(req->method, "DELETE");
    int rc = deleting ? sdfd_volumes_cancel(srv->volumes, req->name, &s)
                      : sdfd_volumes_job(srv->volumes, req->name, &s);
    if (rc)
        return send_error(req, rc, "no job '%s'", req->name);
    cJSON *o = job_json(&s);
    if (deleting)
        cJSON_AddBoolToObject(o, "cancel_requested",
                              s.state == SDFD_JOB_QUEUED || s.state == SDFD_JOB_RUNNING);
    return send_json(req, 200, o);
}

static enum MHD_Result list_jobs(request *req)
{
    sdfd_job_status *jobs;
    size_t n = sdfd_volumes_jobs(req->http->srv->volumes, &jobs);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "jobs");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, job_json(&jobs[i]));
    free(jobs);
    return send_json(req, 200, root);
}

static cJSON *volume_json(const sdfd_stored_volume *s)
{
    char text[1024];
    cJSON *o = sdf_volume_describe_json(s->volume, text, sizeof text) > 0 ? cJSON_Parse(text) : NULL;
    if (!o)
        o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", s->name);
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    cJSON_AddStringToObject(o, "job", s->job);
    cJSON_AddNumberToObject(o, "bake_seconds", s->bake_seconds);
    return o;
}

static enum MHD_Result list_volumes(request *req)
{
    sdfd_stored_volume **list;
    size_t n = sdfd_volumes_list(req->http->srv->volumes, &list);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "volumes");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, volume_json(list[i]));
    sdfd_volumes_free_list(list, n);
    return send_json(req, 200, root);
}

/* An uploaded EXR volume (another replica's download, say) becomes a stored volume. */
static void load_volume(request *req)
{
    sdf_volume *volume = NULL;
    req->work_rc = sdf_volume_load_exr_memory(req->body, req->len, &volume, &req->diag);
    if (!req->work_rc) {
        req->work_rc = sdfd_volumes_put(req->http->srv->volumes, req->name, volume, "",
                                        &req->replaced);
        if (req->work_rc)
            snprintf(req->diag.message, sizeof req->diag.message,
                     "storing it would exceed --max-volumes or --max-volume-bytes");
    }
}

static enum MHD_Result reply_volume_upload(request *req)
{
    if (req->work_rc)
        return send_error(req, req->work_rc, "%s", req->diag.message);
    sdfd_stored_volume *s = sdfd_volumes_get(req->http->srv->volumes, req->name);
    if (!s) /* deleted in between */
        return send_error(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
    sdfd_log("info", "volume_loaded", "%s: %s by upload", req->name,
             req->replaced ? "replaced" : "added");
    enum MHD_Result r = send_json(req, req->replaced ? 200 : 201, volume_json(s));
    sdfd_volume_release(s);
    return r;
}

static enum MHD_Result volume_route(request *req)
{
    sdfd_server *srv = req->http->srv;
    if (!strcmp(req->method, "PUT"))
        return start_thread(req, load_volume, reply_volume_upload);
    if (!strcmp(req->method, "DELETE")) {
        if (sdfd_volumes_remove(srv->volumes, req->name))
            return send_error(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
        sdfd_log("info", "volume_deleted", "%s", req->name);
        return send_buffer(req, 204, "application/json", NULL, 0, NULL);
    }
    sdfd_stored_volume *s = sdfd_volumes_get(srv->volumes, req->name);
    if (!s)
        return send_error(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
    enum MHD_Result r = send_json(req, 200, volume_json(s));
    sdfd_volume_release(s);
    return r;
}

/* npy and raw downloads are the node words as stored (after an npy header): they are sent
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

static void volume_headers(request *req, header h[4])
{
    static const char *const extensions[] = {"exr", "npy", "raw"};
    sdf_volume_info in;
    sdf_volume_get_info(req->stored->volume, &in);
    h[0] = (header){"Content-Disposition", ""}, h[1] = (header){"X-SDF-Dims", ""};
    h[2] = (header){"X-SDF-Order", ""}, h[3] = (header){"X-SDF-Encoding", ""};
    snprintf(h[0].value, sizeof h[0].value, "attachment; filename=\"%s.%s\"", req->name,
             extensions[req->file_type]);
    snprintf(h[1].value, sizeof h[1].value, "%zu,%zu,%zu", in.dims[0], in.dims[1], in.dims[2]);
    snprintf(h[2].value, sizeof h[2].value, "%d", in.order);
    snprintf(h[3].value, sizeof h[3].value, "%s", sdf_encoding_name(in.encoding));
}

static const char *volume_file_type(sdf_volume_file type)
{
    return type == SDF_VOLUME_EXR ? "image/x-exr"
           : type == SDF_VOLUME_NPY ? "application/x-npy"
                                    : "application/octet-stream";
}

static enum MHD_Result stream_volume(request *req)
{
    volume_stream *s = calloc(1, sizeof *s);
    if (!s)
        return send_error(req, SDF_ENOMEM, "out of memory");
    const sdf_volume *v = req->stored->volume;
    if (req->file_type == SDF_VOLUME_NPY) {
        long len = sdf_volume_npy_header(v, s->header, sizeof s->header);
        if (len < 0) {
            free(s);
            return send_error(req, (int)len, "cannot write the npy header");
        }
        s->header_len = (size_t)len;
    }
    s->stored = req->stored; /* the stream's own reference: it may outlive the request */
    sdfd_volume_retain(s->stored);
    size_t total = s->header_len + sdf_volume_data_bytes(v);
    struct MHD_Response *r = MHD_create_response_from_callback(total, 1 << 16, read_volume_stream,
                                                               s, free_volume_stream);
    if (!r) {
        free_volume_stream(s);
        return MHD_NO;
    }
    header h[4];
    volume_headers(req, h);
    return queue_response(req, 200, volume_file_type(req->file_type), r, total, h, 4);
}

static void encode_volume(request *req)
{
    req->work_rc = sdf_volume_save_memory(req->stored->volume, req->file_type,
                                            (void **)&req->out_body, &req->out_len, &req->diag);
}

static enum MHD_Result reply_volume_data(request *req)
{
    if (req->work_rc)
        return send_error(req, req->work_rc, "%s", req->diag.message);
    header h[4];
    volume_headers(req, h);
    char *body = req->out_body;
    req->out_body = NULL; /* MHD frees it */
    return send_with_headers(req, 200, volume_file_type(req->file_type), body, req->out_len, h, 4);
}

static enum MHD_Result start_volume_data(request *req)
{
    const char *format = MHD_lookup_connection_value(req->conn, MHD_GET_ARGUMENT_KIND, "format");
    if (sdf_volume_file_from_name(format ? format : "exr", &req->file_type))
        return send_error(req, SDF_EINVAL, "unknown format '%s' (exr, npy, raw)", format);
    req->stored = sdfd_volumes_get(req->http->srv->volumes, req->name);
    if (!req->stored)
        return send_error(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
    if (req->file_type != SDF_VOLUME_EXR)
        return stream_volume(req);
    return start_thread(req, encode_volume, reply_volume_data); /* compression takes a while */
}

static void evaluate_volume(request *req)
{
    size_t bad = 0;
    req->work_rc = sdfd_volume_eval_words(req->stored->volume, req->points_buf, req->points,
                                            req->interpolation, req->reply.mode == SDF_MODE_GRADIENT,
                                            req->reply.words, &bad);
    if (req->work_rc == SDF_ENONFINITE)
        snprintf(req->diag.message, sizeof req->diag.message,
                 "point %zu has a NaN or infinite coordinate", bad);
    else if (req->work_rc)
        snprintf(req->diag.message, sizeof req->diag.message, "%s", sdf_strerror(req->work_rc));
}

static enum MHD_Result reply_volume_query(request *req)
{
    if (req->work_rc)
        return send_error(req, req->work_rc, "%s", req->diag.message);
    return send_results(req);
}

static enum MHD_Result start_volume_query(request *req)
{
    sdfd_server *srv = req->http->srv;
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (read_points(req, &form, &params, &count, &refused))
        return refused;
    char mode_buf[32], interp_buf[32];
    const char *mode = param(req, params.mode, params.mode_len, "mode", mode_buf, sizeof mode_buf);
    const char *interp = param(req, params.interpolation, params.interpolation_len,
                               "interpolation", interp_buf, sizeof interp_buf);
    int gradient = 0;
    if (mode && strcmp(mode, "value") && !(gradient = !strcmp(mode, "gradient")))
        return send_error(req, SDF_EINVAL, "unknown volume mode '%s' (value, gradient)", mode);
    req->interpolation = SDF_VOLUME_TRILINEAR;
    if (interp && sdf_volume_filter_from_name(interp, &req->interpolation))
        return send_error(req, SDF_EINVAL, "unknown interpolation '%s' (trilinear, nearest)", interp);
    req->stored = sdfd_volumes_get(srv->volumes, req->name);
    if (!req->stored)
        return send_error(req, SDF_ENOTFOUND, "no volume named '%s'", req->name);
    req->points = count;
    req->reply_form = (sdfd_form)reply_form(req, form);
    if (sdfd_reply_init(&req->reply, req->reply_form,
                        gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED, count))
        return send_error(req, SDF_ENOMEM, "out of memory for %zu results", count);
    sdfd_metrics_points(srv->metrics, count);
    return start_thread(req, evaluate_volume, reply_volume_query);
}

/* ---- the simple routes ------------------------------------------------------------------- */

static enum MHD_Result status_reply(request *req, int status, const char *state)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "status", state);
    return send_json(req, status, o);
}

static enum MHD_Result list_meshes(request *req)
{
    sdfd_entry *list;
    size_t n = sdfd_registry_list(req->http->srv->registry, &list);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "meshes");
    for (size_t i = 0; i < n; i++) {
        sdf_mesh_report r;
        sdf_mesh_get_report(list[i].mesh, &r);
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", list[i].name);
        cJSON_AddNumberToObject(o, "triangles", (double)r.triangles);
        cJSON_AddBoolToObject(o, "closed", r.closed);
        cJSON_AddStringToObject(o, "sign", sdf_sign_name(r.auto_sign));
        cJSON_AddItemToArray(arr, o);
    }
    sdfd_registry_free_list(list, n);
    return send_json(req, 200, root);
}

static enum MHD_Result mesh_route(request *req)
{
    sdfd_server *srv = req->http->srv;
    if (!strcmp(req->method, "PUT"))
        return start_upload(req);
    if (!strcmp(req->method, "DELETE")) {
        if (sdfd_registry_remove(srv->registry, req->name))
            return send_error(req, SDF_ENOTFOUND, "no mesh named '%s'", req->name);
        sdfd_log("info", "mesh_deleted", "%s", req->name);
        return send_buffer(req, 204, "application/json", NULL, 0, NULL);
    }
    sdf_mesh *mesh = sdfd_registry_get(srv->registry, req->name, strlen(req->name));
    if (!mesh)
        return send_error(req, SDF_ENOTFOUND, "no mesh named '%s'", req->name);
    enum MHD_Result r = send_json(req, 200, report_json(req->name, mesh));
    sdf_mesh_release(mesh);
    return r;
}

static enum MHD_Result dispatch(request *req)
{
    sdfd_server *srv = req->http->srv;
    switch (req->route) {
    case SDFD_ROUTE_HEALTH:
        return status_reply(req, 200, "ok");
    case SDFD_ROUTE_READY:
        if (atomic_load(&srv->draining))
            return status_reply(req, 503, "draining");
        return atomic_load(&srv->ready) ? status_reply(req, 200, "ready")
                                        : status_reply(req, 503, "loading");
    case SDFD_ROUTE_METRICS: {
        size_t len;
        sdfd_gauges g = {.meshes_loaded = sdfd_registry_count(srv->registry),
                         .volumes_loaded = sdfd_volumes_count(srv->volumes)};
        sdfd_volumes_usage(srv->volumes, &g.volume_bytes, &g.bakes_running, &g.bakes_queued);
        char *text = sdfd_metrics_render(srv->metrics, &g, &len);
        return text ? send_buffer(req, 200, "text/plain; version=0.0.4", text, len, NULL) : MHD_NO;
    }
    case SDFD_ROUTE_MESHES:
        return list_meshes(req);
    case SDFD_ROUTE_MESH:
        return mesh_route(req);
    case SDFD_ROUTE_QUERY:
        return start_query(req);
    case SDFD_ROUTE_BAKE:
        return start_bake(req);
    case SDFD_ROUTE_JOBS:
        return list_jobs(req);
    case SDFD_ROUTE_JOB:
        return job_route(req);
    case SDFD_ROUTE_VOLUMES:
        return list_volumes(req);
    case SDFD_ROUTE_VOLUME:
        return volume_route(req);
    case SDFD_ROUTE_VOLUME_DATA:
        return start_volume_data(req);
    case SDFD_ROUTE_VOLUME_QUERY:
        return start_volume_query(req);
    default:
        return send_error(req, SDF_ENOTFOUND, "no such route");
    }
}

/* ---- MHD callbacks ----------------------------------------------------------------------- */

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version,
                                  const char *upload_data, size_t *upload_size, void **state)
{
    (void)version;
    sdfd_http *http = cls;
    request *req = *state;
    if (!req) { /* headers are in: admit or refuse before reading the body */
        req = calloc(1, sizeof *req);
        if (!req)
            return MHD_NO;
        req->http = http;
        req->conn = conn;
        req->method = method;
        req->route = SDFD_ROUTE_OTHER;
        snprintf(req->route_text, sizeof req->route_text, "%s", "other");
        req->start = sdfd_now();
        atomic_fetch_add(&http->srv->in_flight, 1);
        *state = req;
        return admit(req, url);
    }
    if (req->answered) {
        *upload_size = 0; /* refused from the headers: MHD discards the rest */
        return MHD_YES;
    }
    if (*upload_size) { /* more body */
        size_t n = *upload_size;
        if (n > req->declared - req->len)
            n = req->declared - req->len; /* never past the declared length */
        memcpy(req->body + req->len, upload_data, n);
        req->len += n;
        req->body[req->len] = '\0';
        *upload_size = 0;
        return MHD_YES;
    }
    if (req->work != WORK_NONE) { /* resumed: the work is done */
        if (!atomic_load(&req->finished))
            return MHD_YES;
        return req->work == WORK_QUERY ? reply_query(req) : req->respond(req);
    }
    return dispatch(req);
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **state,
                         enum MHD_RequestTerminationCode code)
{
    (void)cls, (void)conn, (void)code;
    request *req = *state;
    if (!req)
        return;
    sdfd_server *srv = req->http->srv;
    double seconds = sdfd_now() - req->start;
    int status = req->answered ? req->status : 499; /* client went away */
    sdfd_metrics_request(srv->metrics, req->route, status, seconds);
    if (req->route != SDFD_ROUTE_HEALTH && req->route != SDFD_ROUTE_READY &&
        req->route != SDFD_ROUTE_METRICS)
        sdfd_log_request("http", req->method, req->route_text, status, req->points, seconds * 1e6,
                         req->len, req->bytes_out);
    sdf_mesh_release(req->job.mesh);
    sdf_mesh_release(req->uploaded);
    sdf_mesh_release(req->volume);
    sdfd_volume_release(req->stored);
    free(req->out_body);
    if (req->points_owned)
        free(req->points_buf);
    free(req->reply.buffer);
    free(req->body);
    atomic_fetch_sub(&srv->in_flight, 1);
    free(req);
    *state = NULL;
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap)
{
    (void)cls;
    char message[512];
    vsnprintf(message, sizeof message, fmt, ap);
    message[strcspn(message, "\n")] = '\0';
    sdfd_log("warn", "http", "%s", message);
}

int sdfd_http_start(sdfd_server *srv, sdfd_http **out)
{
    int port;
    int fd = sdfd_listen(srv->cfg.http_addr, &port);
    if (fd < 0)
        return -1;
    sdfd_http *http = calloc(1, sizeof *http);
    http->srv = srv;
    http->listen_fd = fd;
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME |
                     MHD_USE_ERROR_LOG;
    http->daemon = MHD_start_daemon(
        flags, 0, NULL, NULL, on_request, http,
        MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, http, /* first, so every message goes through it */
        MHD_OPTION_LISTEN_SOCKET, fd,
        MHD_OPTION_THREAD_POOL_SIZE, 2u,
        MHD_OPTION_CONNECTION_LIMIT, srv->cfg.max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, srv->cfg.max_per_ip,
        MHD_OPTION_CONNECTION_TIMEOUT, srv->cfg.timeout_seconds,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, http,
        MHD_OPTION_END);
    if (!http->daemon) {
        sdfd_log("error", "listen", "libmicrohttpd failed to start on %s", srv->cfg.http_addr);
        close(fd);
        free(http);
        return -1;
    }
    sdfd_log_listening("http", srv->cfg.http_addr, port);
    *out = http;
    return 0;
}

void sdfd_http_quiesce(sdfd_http *http)
{
    int fd = MHD_quiesce_daemon(http->daemon);
    if (fd >= 0)
        close(fd);
}

void sdfd_http_stop(sdfd_http *http)
{
    if (!http)
        return;
    MHD_stop_daemon(http->daemon);
    free(http);
}
