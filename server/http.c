/* http.c - the HTTP API on libmicrohttpd (routes in docs/api.md): admission, mesh queries
 * and uploads, the simple routes and MHD's callbacks. The volume routes are httpvolumes.c's,
 * a query's admission is the handlers' (queries.h) as for the binary protocol, and how a
 * request is answered is httpreq.c's; this file calls them, and none of them calls back.
 *
 * MHD's threads only do I/O: they receive bodies, parse them, format replies. Geometry runs
 * elsewhere: a query becomes a batcher job and a mesh upload a loader thread, and the
 * connection is suspended (sdfd_http_wait) until that work resumes it.
 *
 * Each request walks the same steps: `admit` (route, method, auth, URL arguments,
 * Content-Length, all checked from the headers before any body byte is read), `receive`
 * (append the body, never past its declared length), `dispatch` (start the work, or answer
 * at once), and after a resume, `reply_*`. The completion callback logs, counts and frees. */
#include "http.h"

#include <cjson/cJSON.h>
#include <microhttpd.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "body.h"
#include "errors.h"
#include "filterparams.h"
#include "httpframing.h"
#include "httpreq.h"
#include "httpslice.h"
#include "httpvolumes.h"
#include "httpwatch.h"
#include "page.h"
#include "log.h"
#include "net.h"
#include "urlargs.h"

struct sdfd_http {
    sdfd_server *srv;
    struct MHD_Daemon *daemon;
    sdfd_httpwatch *watch; /* cuts off requests that arrive too slowly */
    int listen_fd;
    int quiesced; /* listen_fd handed back by MHD_quiesce_daemon: ours to close */
};

typedef sdfd_http_request request;

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
    cJSON_AddNumberToObject(o, "warnings", (double)r.warnings);
    if (r.warnings)
        cJSON_AddStringToObject(o, "warning", r.warning);
    return o;
}

/* ---- admission: everything decided from the request line and headers ------------------- */

static int parse_route(request *req, const char *url)
{
    static const struct { const char *path; sdfd_route route; } fixed[] = {
        {"/healthz", SDFD_ROUTE_HEALTH}, {"/readyz", SDFD_ROUTE_READY},
        {"/metrics", SDFD_ROUTE_METRICS}, {"/v1/meshes", SDFD_ROUTE_MESHES},
        {"/v1/jobs", SDFD_ROUTE_JOBS}, {"/v1/volumes", SDFD_ROUTE_VOLUMES},
        {"/", SDFD_ROUTE_PAGE}};
    /* collection/{name}[suffix] */
    static const struct { const char *collection, *suffix; sdfd_route route; } named[] = {
        {"/v1/meshes/", "", SDFD_ROUTE_MESH}, {"/v1/meshes/", "/query", SDFD_ROUTE_QUERY},
        {"/v1/meshes/", "/bake", SDFD_ROUTE_BAKE}, {"/v1/jobs/", "", SDFD_ROUTE_JOB},
        {"/v1/volumes/", "", SDFD_ROUTE_VOLUME}, {"/v1/volumes/", "/data", SDFD_ROUTE_VOLUME_DATA},
        {"/v1/volumes/", "/query", SDFD_ROUTE_VOLUME_QUERY},
        {"/v1/volumes/", "/ops", SDFD_ROUTE_VOLUME_OPS},
        {"/v1/meshes/", "/slice.png", SDFD_ROUTE_SLICE},
        {"/v1/volumes/", "/slice.png", SDFD_ROUTE_VOLUME_SLICE},
        {"/static/", "", SDFD_ROUTE_PAGE}};
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
    const char *list = sdfd_http_allowed_methods(req->route), *m = req->method;
    size_t n = strlen(m);
    for (const char *p = strstr(list, m); p; p = strstr(p + 1, m))
        if ((p == list || p[-1] == ' ') && (p[n] == ',' || p[n] == '\0'))
            return 1;
    return 0;
}

static int authorized(const request *req)
{
    const sdfd_config *cfg = &req->srv->cfg;
    int needs = !strcmp(req->method, "PUT") || !strcmp(req->method, "DELETE") ||
                req->route == SDFD_ROUTE_BAKE || req->route == SDFD_ROUTE_VOLUME_OPS ||
                (cfg->auth_queries &&
                 (req->route == SDFD_ROUTE_QUERY || req->route == SDFD_ROUTE_VOLUME_QUERY ||
                  req->route == SDFD_ROUTE_VOLUME_DATA || /* a download is every node's answer */
                  req->route == SDFD_ROUTE_SLICE || req->route == SDFD_ROUTE_VOLUME_SLICE));
    if (!cfg->token || !needs)
        return 1;
    const char *h = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                MHD_HTTP_HEADER_AUTHORIZATION);
    return h && !strncmp(h, "Bearer ", 7) && sdfd_token_matches(cfg, h + 7, strlen(h + 7));
}

/* Decide from the headers alone; returns MHD_YES with a response queued if refused. */
static enum MHD_Result admit(request *req, const char *url)
{
    sdfd_server *srv = req->srv;
    char framing[256];
    if (sdfd_http_framing_check(req->conn, framing, sizeof framing))
        return sdfd_http_error(req, SDFD_ESYNTAX, "%s", framing);
    int route = parse_route(req, url);
    if (route == -1)
        return sdfd_http_error(req, SDF_ENOTFOUND, "no route %s", url);
    if (route == -2)
        return sdfd_http_error(req, SDF_EINVAL,
                               "names are 1-255 characters of A-Z a-z 0-9 . _ - "
                               "and do not start with '.'");
    if (!method_allowed(req))
        return sdfd_http_error(req, SDFD_EMETHOD, "%s is not allowed on %s", req->method,
                               req->route_text);
    if (!authorized(req))
        return sdfd_http_error(req, SDFD_EUNAUTHORIZED,
                               "this request needs 'Authorization: Bearer <token>'");
    enum MHD_Result refused;
    if (sdfd_http_check_args(req, &refused))
        return refused;
    const char *unavailable = sdfd_unavailable(srv);
    if (unavailable && req->route != SDFD_ROUTE_HEALTH && req->route != SDFD_ROUTE_READY &&
        req->route != SDFD_ROUTE_METRICS)
        return sdfd_http_error(req, SDFD_EUNAVAILABLE, "%s", unavailable);
    int has_body = !strcmp(req->method, "POST") || !strcmp(req->method, "PUT");
    if (!has_body)
        return MHD_YES;
    const char *cl = MHD_lookup_connection_value(req->conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_CONTENT_LENGTH);
    char *end;
    unsigned long long declared = cl ? strtoull(cl, &end, 10) : 0;
    if (!cl || !*cl || *end)
        return sdfd_http_error(req, SDFD_ELENGTH, "send the body with a Content-Length header");
    if (declared > srv->cfg.max_body_bytes)
        return sdfd_http_error(req, SDF_ELIMIT, "the body is %llu bytes, over the limit of %zu",
                               declared, srv->cfg.max_body_bytes);
    /* The whole body in one allocation, sized by a checked length, NUL-terminated, and
     * counted against the budget of all connections until the request completes. */
    req->declared = (size_t)declared;
    if (sdfd_buffer_reserve(srv, req->declared + 1))
        return sdfd_http_error(req, SDFD_EBUSY, SDFD_BUFFER_BUSY_FMT, srv->cfg.max_buffered_bytes);
    req->reserved = req->declared + 1;
    req->body = malloc(req->declared + 1);
    if (!req->body)
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory for a %zu-byte body", req->declared);
    req->body[0] = '\0';
    return MHD_YES;
}

/* ---- work: queries ----------------------------------------------------------------------- */

static void query_done(sdfd_job *job)
{
    sdfd_http_resume(job->user);
}

static enum MHD_Result reply_query(request *req)
{
    if (req->query.refused) { /* after a load */
        req->points = 0;
        return sdfd_http_error(req, req->query.job.status, "%s", req->query.refusal);
    }
    if (req->query.job.status)
        return sdfd_http_error(req, req->query.job.status, "query failed: %s",
                               req->query.job.message);
    return sdfd_http_results(req);
}

/* The filter's parameters go with the filtered modes only: with another they would be
 * ignored, so they are refused. 0, or -1 with the refusal queued (its result in *refused). */
static int filter_misplaced(request *req, const sdfd_query_params *params, const char *mode,
                            enum MHD_Result *refused)
{
    const char *arg = sdfd_url_first_filter_arg(&req->args);
    if (params->filter)
        *refused = sdfd_http_error(req, SDF_EINVAL, "\"filter\" goes with mode filtered or "
                                   "filtered-gradient, not '%s'", mode ? mode : "signed");
    else if (arg)
        *refused = sdfd_http_refuse(req, SDF_EINVAL, arg, "'%s' is a filter parameter: it goes "
                                    "with mode=filtered or filtered-gradient, not '%s'", arg,
                                    mode ? mode : "signed");
    return params->filter || arg ? -1 : 0;
}

/* The HTTP spelling of a query (body, URL arguments, Accept) into the handler's terms. */
static enum MHD_Result start_query(request *req)
{
    sdfd_server *srv = req->srv;
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (sdfd_http_read_points(req, &form, &params, &count, &refused))
        return refused;
    char err[300], mode_buf[32], sign_buf[32];
    int rc;
    const char *mode = sdfd_http_param(params.mode, params.mode_len, mode_buf, sizeof mode_buf);
    const char *sign = sdfd_http_param(params.sign, params.sign_len, sign_buf, sizeof sign_buf);
    sdf_proto_mode m = SDF_MODE_SIGNED;
    sdf_sign_method s = SDF_SIGN_AUTO;
    if (mode && sdf_proto_mode_from_name(mode, &m))
        return sdfd_http_error(req, SDF_EINVAL,
                               "unknown mode '%s' (signed, distance, gradient, closest, filtered, "
                               "filtered-gradient)",
                               mode);
    if (sign && sdf_sign_from_name(sign, &s))
        return sdfd_http_error(req, SDF_EINVAL,
                               "unknown sign '%s' (auto, pseudonormal, winding, raycast, none)",
                               sign);
    if (!sdf_proto_mode_filtered(m) && filter_misplaced(req, &params, mode, &refused))
        return refused;
    sdfd_query *q = &req->query;
    *q = (sdfd_query){.mesh_name = req->name, .mesh_name_len = strlen(req->name),
                      .job = {.mode = m, .sign = s, .points = req->points_buf, .count = count,
                              .done = query_done, .user = req}};
    char volume_name[SDFD_VOLUME_NAME_MAX + 1] = "";
    if (sdf_proto_mode_filtered(m)) {
        sdf_filter_options *filter = &q->job.filter;
        rc = params.filter ? sdfd_filter_from_json(params.filter, params.filter_len, filter,
                                                   volume_name, err, sizeof err)
                           : sdfd_filter_from_strings(sdfd_url_lookup, &req->args, filter,
                                                      volume_name, err, sizeof err);
        if (rc)
            return sdfd_http_error(req, rc, "%s", err);
        if (volume_name[0])
            q->smoothing_name = volume_name, q->smoothing_name_len = strlen(volume_name);
    }
    req->reply_form = (sdfd_form)sdfd_http_reply_form(req, form);
    if (sdfd_reply_init(&req->reply, req->reply_form, m, count))
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory for %zu results", count);
    q->job.words = req->reply.words;
    req->points = count;
    sdfd_http_wait(req, reply_query); /* admission may end on a loader's thread */
    if ((rc = sdfd_query_admit(srv, q, err, sizeof err))) {
        sdfd_http_unwait(req);
        req->points = 0;
        return sdfd_http_error(req, rc, "%s", err);
    }
    return MHD_YES;
}

/* ---- work: uploads ----------------------------------------------------------------------- */

static enum MHD_Result reply_upload(request *req);

static void load_upload(request *req)
{
    sdfd_server *srv = req->srv;
    sdf_mesh_options opts = {.max_triangles = srv->cfg.max_total_triangles};
    if (req->format[0] && sdf_format_from_name(req->format, &opts.format)) {
        req->work_rc = SDF_EFORMAT;
        snprintf(req->diag.message, sizeof req->diag.message,
                 "unknown format '%s' (obj, ply, stl, off)", req->format);
    } else {
        req->work_rc = sdf_mesh_load_memory(req->body, req->len, &opts, &req->uploaded, &req->diag);
    }
    if (!req->work_rc)
        req->work_rc = sdfd_cache_put_mesh(srv->cache, req->name, sdf_mesh_retain(req->uploaded),
                                           req->body, req->len, &req->replaced,
                                           req->diag.message, sizeof req->diag.message);
}

static enum MHD_Result start_upload(request *req)
{
    /* The loader thread must not call MHD: take what it needs from the request now. */
    const char *format = sdfd_url_value(&req->args, "format");
    if (format)
        snprintf(req->format, sizeof req->format, "%s", format);
    return sdfd_http_start_thread(req, load_upload, reply_upload);
}

static enum MHD_Result reply_upload(request *req)
{
    if (req->work_rc)
        return sdfd_http_error(req, req->work_rc, "%s", req->diag.message);
    sdfd_log("info", "mesh_loaded", "%s: %s by upload", req->name,
             req->replaced ? "replaced" : "added");
    return sdfd_http_json(req, req->replaced ? 200 : 201, report_json(req->name, req->uploaded));
}

/* ---- the simple routes ------------------------------------------------------------------- */

static enum MHD_Result status_reply(request *req, int status, const char *state)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "status", state);
    return sdfd_http_json(req, status, o);
}

static enum MHD_Result list_meshes(request *req)
{
    sdfd_mesh_summary *list;
    size_t n = sdfd_cache_list_meshes(req->srv->cache, &list);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "meshes");
    for (size_t i = 0; i < n; i++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", list[i].name);
        cJSON_AddNumberToObject(o, "triangles", (double)list[i].triangles);
        cJSON_AddBoolToObject(o, "closed", list[i].closed);
        cJSON_AddStringToObject(o, "sign", sdf_sign_name(list[i].sign));
        cJSON_AddItemToArray(arr, o);
    }
    free(list);
    return sdfd_http_json(req, 200, root);
}

static enum MHD_Result mesh_route(request *req)
{
    sdfd_server *srv = req->srv;
    if (!strcmp(req->method, "PUT"))
        return start_upload(req);
    char msg[512];
    int rc;
    if (!strcmp(req->method, "DELETE")) {
        if ((rc = sdfd_cache_remove_mesh(srv->cache, req->name, msg, sizeof msg)))
            return sdfd_http_error(req, rc, "%s", msg);
        sdfd_log("info", "mesh_deleted", "%s", req->name);
        return sdfd_http_buffer(req, 204, "application/json", NULL, 0, NULL);
    }
    sdf_mesh *mesh;
    if ((rc = sdfd_cache_mesh(srv->cache, req->name, strlen(req->name), &mesh, msg, sizeof msg)))
        return sdfd_http_error(req, rc, "%s", msg);
    enum MHD_Result r = sdfd_http_json(req, 200, report_json(req->name, mesh));
    sdf_mesh_release(mesh);
    return r;
}

static enum MHD_Result dispatch(request *req)
{
    sdfd_server *srv = req->srv;
    switch (req->route) {
    case SDFD_ROUTE_HEALTH:
        return status_reply(req, 200, "ok");
    case SDFD_ROUTE_READY:
        if (atomic_load(&srv->draining))
            return status_reply(req, 503, "draining");
        if (!atomic_load(&srv->ready))
            return status_reply(req, 503, "loading");
        return sdfd_cache_probe(srv->cache) ? status_reply(req, 503, "store unreadable")
                                            : status_reply(req, 200, "ready");
    case SDFD_ROUTE_METRICS: {
        size_t len;
        sdfd_gauges g = {.meshes_loaded = sdfd_registry_count(srv->registry),
                         .volumes_loaded = sdfd_volumes_count(srv->volumes),
                         .buffered_bytes = atomic_load(&srv->buffered),
                         .batch_scratch_bytes = sdfd_batcher_kept_bytes(srv->batcher)};
        sdfd_volumes_usage(srv->volumes, &g.volume_bytes, &g.bakes_running, &g.bakes_queued);
        sdfd_volumes_ops_usage(srv->volumes, &g.ops_running, &g.ops_queued);
        sdfd_workers_counts(srv->workers, &g.workers_idle, &g.workers_started);
        sdfd_cache_stats st;
        sdfd_cache_stats_get(srv->cache, &st);
        g.resident_bytes = st.resident_bytes, g.resident_budget = st.budget;
        g.store_loads = st.loads, g.store_evictions = st.evictions;
        g.store_quarantined = st.quarantined;
        char *text = sdfd_metrics_render(srv->metrics, &g, &len);
        return text ? sdfd_http_buffer(req, 200, "text/plain; version=0.0.4", text, len, NULL)
                    : MHD_NO;
    }
    case SDFD_ROUTE_MESHES:
        return list_meshes(req);
    case SDFD_ROUTE_MESH:
        return mesh_route(req);
    case SDFD_ROUTE_QUERY:
        return start_query(req);
    case SDFD_ROUTE_BAKE:
        return sdfd_http_bake(req);
    case SDFD_ROUTE_VOLUME_OPS:
        return sdfd_http_volume_ops(req);
    case SDFD_ROUTE_JOBS:
        return sdfd_http_jobs(req);
    case SDFD_ROUTE_JOB:
        return sdfd_http_job(req);
    case SDFD_ROUTE_VOLUMES:
        return sdfd_http_volumes(req);
    case SDFD_ROUTE_VOLUME:
        return sdfd_http_volume(req);
    case SDFD_ROUTE_VOLUME_DATA:
        return sdfd_http_volume_data(req);
    case SDFD_ROUTE_VOLUME_QUERY:
        return sdfd_http_volume_query(req);
    case SDFD_ROUTE_SLICE:
    case SDFD_ROUTE_VOLUME_SLICE:
        return sdfd_http_slice(req);
    case SDFD_ROUTE_PAGE:
        return sdfd_http_page(req);
    default:
        return sdfd_http_error(req, SDF_ENOTFOUND, "no such route");
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
        req->srv = http->srv;
        req->conn = conn;
        req->method = method;
        req->route = SDFD_ROUTE_OTHER;
        snprintf(req->route_text, sizeof req->route_text, "%s", "other");
        req->start = sdfd_now();
        atomic_fetch_add(&http->srv->in_flight, 1);
        *state = req;
        return admit(req, url);
    }
    if (*upload_size)
        sdfd_httpwatch_received(http->watch, conn, *upload_size);
    else
        sdfd_httpwatch_arrived(http->watch, conn);
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
    if (req->waiting) { /* resumed: the work is done */
        if (!atomic_load(&req->finished))
            return MHD_YES;
        return req->respond(req);
    }
    return dispatch(req);
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **state,
                         enum MHD_RequestTerminationCode code)
{
    (void)code;
    sdfd_http *http = cls;
    sdfd_httpwatch_next(http->watch, conn);
    request *req = *state;
    if (!req)
        return;
    sdfd_server *srv = req->srv;
    double seconds = sdfd_now() - req->start;
    int status = req->answered ? req->status : 499; /* client went away */
    sdfd_metrics_request(srv->metrics, req->route, status, seconds);
    if (req->route != SDFD_ROUTE_HEALTH && req->route != SDFD_ROUTE_READY &&
        req->route != SDFD_ROUTE_METRICS)
        sdfd_log_request("http", req->method, req->route_text, status, req->points, seconds * 1e6,
                         req->len, req->bytes_out);
    sdfd_query_release(&req->query);
    sdfd_volume_query_release(&req->volume_query);
    sdf_mesh_release(req->uploaded);
    sdfd_volume_release(req->stored);
    free(req->out_body);
    free(req->route_state);
    if (req->points_owned)
        free(req->points_buf);
    free(req->reply.buffer);
    free(req->body);
    sdfd_buffer_release(srv, req->reserved);
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

static int hex_digit(char c)
{
    return c >= '0' && c <= '9' ? c - '0'
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                  : -1;
}

/* URL paths and arguments decoded as MHD's default does (%HH), except that %00 stays as it
 * is: every route reads the decoded text as a C string, so a decoded NUL would cut
 * "/v1/meshes/a%00b" to the mesh "a"; kept literal, the name is refused for its '%'. */
static size_t unescape_url(void *cls, struct MHD_Connection *connection, char *s)
{
    (void)cls, (void)connection;
    char *out = s;
    for (const char *in = s; *in;) {
        int hi = in[0] == '%' ? hex_digit(in[1]) : -1, lo = hi >= 0 ? hex_digit(in[2]) : -1;
        if (lo >= 0 && (hi || lo)) {
            *out++ = (char)(hi * 16 + lo);
            in += 3;
        } else {
            *out++ = *in++;
        }
    }
    *out = '\0';
    return (size_t)(out - s);
}

/* What sdfd keeps per connection: its entry in the slow-request watch (httpwatch.c) and,
 * with TLS, its hold on the certificate it may have been handshaken with (tls.c). */
typedef struct connection_context {
    void *watch; /* first: httpwatch.c reads it through the socket context */
    void *tls;
} connection_context;

/* A connection opens or closes: it is watched for requests that arrive too slowly, and with
 * TLS a certificate replaced by a reload is freed only once no connection that may have been
 * handshaken with it is open. */
static void on_connection(void *cls, struct MHD_Connection *connection, void **socket_context,
                          enum MHD_ConnectionNotificationCode code)
{
    sdfd_http *http = cls;
    connection_context *ctx = *socket_context;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        ctx = calloc(1, sizeof *ctx);
        *socket_context = ctx;
        if (!ctx)
            return; /* unwatched, and no certificate is held: MHD's idle timeout applies */
        sdfd_httpwatch_notify(http->watch, connection, &ctx->watch, code);
        if (http->srv->tls)
            ctx->tls = sdfd_tls_connection_opened(http->srv->tls);
        return;
    }
    if (!ctx)
        return;
    sdfd_httpwatch_notify(http->watch, connection, &ctx->watch, code);
    if (ctx->tls)
        sdfd_tls_connection_closed(http->srv->tls, ctx->tls);
    free(ctx);
    *socket_context = NULL;
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
    http->watch = sdfd_httpwatch_start(srv->cfg.timeout_seconds);
    if (!http->watch) {
        close(fd);
        free(http);
        return -1;
    }
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME |
                     MHD_USE_ERROR_LOG;
    /* HTTPS: MHD asks sdfd_tls_retrieve for the certificate at each handshake, so a reload
     * (SIGHUP) reaches new connections without restarting the daemon. */
    struct MHD_OptionItem tls_options[] = {
        {MHD_OPTION_HTTPS_CERT_CALLBACK, 0, (void *)sdfd_tls_retrieve},
        {MHD_OPTION_HTTPS_PRIORITIES, 0, (void *)SDFD_TLS_PRIORITIES},
        {MHD_OPTION_END, 0, NULL},
    };
    if (srv->tls)
        flags |= MHD_USE_TLS;
    else
        tls_options[0].option = MHD_OPTION_END;
    http->daemon = MHD_start_daemon(
        flags, 0, NULL, NULL, on_request, http,
        MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, http, /* first, so every message goes through it */
        MHD_OPTION_LISTEN_SOCKET, fd,
        MHD_OPTION_THREAD_POOL_SIZE, 2u,
        MHD_OPTION_CONNECTION_LIMIT, srv->cfg.max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, srv->cfg.max_per_ip,
        MHD_OPTION_CONNECTION_TIMEOUT, srv->cfg.timeout_seconds,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, http,
        MHD_OPTION_NOTIFY_CONNECTION, on_connection, http,
        MHD_OPTION_UNESCAPE_CALLBACK, unescape_url, NULL,
        MHD_OPTION_ARRAY, tls_options,
        MHD_OPTION_END);
    if (!http->daemon) {
        sdfd_log("error", "listen", "libmicrohttpd failed to start on %s%s", srv->cfg.http_addr,
                 srv->tls && MHD_is_feature_supported(MHD_FEATURE_HTTPS_CERT_CALLBACK) != MHD_YES
                     ? ": this libmicrohttpd has no HTTPS certificate callback (GnuTLS 3)"
                     : "");
        sdfd_httpwatch_stop(http->watch);
        close(fd);
        free(http);
        return -1;
    }
    sdfd_log_listening("http", srv->cfg.http_addr, port);
    *out = http;
    return 0;
}

/* MHD stops accepting and hands the listening socket back. It is shut down at once, so new
 * connections are refused while the rest drains, but closed only after MHD's threads have
 * stopped: closed here, its number could be reused while a worker still held it in its
 * epoll set (ThreadSanitizer reported the close racing a worker's epoll_ctl). */
void sdfd_http_quiesce(sdfd_http *http)
{
    int fd = MHD_quiesce_daemon(http->daemon);
    if (fd >= 0) {
        shutdown(fd, SHUT_RDWR);
        http->listen_fd = fd;
        http->quiesced = 1;
    }
}

void sdfd_http_stop(sdfd_http *http)
{
    if (!http)
        return;
    MHD_stop_daemon(http->daemon);
    sdfd_httpwatch_stop(http->watch);
    if (http->quiesced)
        close(http->listen_fd);
    free(http);
}
