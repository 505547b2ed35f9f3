/* httpvolumes.c - the HTTP routes of baked volumes (docs/api.md, "Volumes"): bake jobs and
 * field-operation jobs (volumes.h runs them), job status and cancellation, volume metadata,
 * downloads (npy and raw streamed from the stored volume, EXR compressed on a worker thread),
 * uploads, and queries (the handler's, queries.h, as for the binary protocol). */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bakeparams.h"
#include "errors.h"
#include "httpvolumes.h"
#include "log.h"
#include "opsparams.h"

typedef sdfd_http_request request;

/* A job's field-operation caveats, when it applied ops and ended done. */
static void add_caveats(cJSON *o, const sdfd_job_status *s)
{
    static const struct { unsigned bit; const char *name; } names[] = {
        {SDF_FIELD_CAVEAT_BAND, "band"}, {SDF_FIELD_CAVEAT_GRID, "grid"},
        {SDF_FIELD_CAVEAT_TOPOLOGY, "topology"}};
    cJSON *list = cJSON_AddArrayToObject(o, "caveats");
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (s->caveats & names[i].bit)
            cJSON_AddItemToArray(list, cJSON_CreateString(names[i].name));
    if (s->caveats)
        cJSON_AddStringToObject(o, "warning", s->warning);
}

static cJSON *job_json(const sdfd_job_status *s)
{
    cJSON *o = cJSON_CreateObject();
    char href[64];
    snprintf(href, sizeof href, "/v1/jobs/%s", s->id);
    cJSON_AddStringToObject(o, "id", s->id);
    cJSON_AddStringToObject(o, "href", href);
    cJSON_AddStringToObject(o, "kind", sdfd_job_kind_name(s->kind));
    cJSON_AddStringToObject(o, "state", sdfd_job_state_name(s->state));
    cJSON_AddNumberToObject(o, "progress", s->progress);
    cJSON_AddNumberToObject(o, "percent", floor(s->progress * 1000) / 10);
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    if (s->kind == SDFD_JOB_OPS)
        cJSON_AddStringToObject(o, "source", s->source);
    cJSON_AddStringToObject(o, "volume", s->volume);
    cJSON_AddNumberToObject(o, "seconds", s->seconds);
    if (s->cancel_requested) /* until it reaches its next step and ends canceled */
        cJSON_AddBoolToObject(o, "cancel_requested", 1);
    if (s->state == SDFD_JOB_FAILED) {
        cJSON *err = cJSON_AddObjectToObject(o, "error");
        cJSON_AddStringToObject(err, "code", sdfd_errname(s->error));
        cJSON_AddStringToObject(err, "message", s->message);
    }
    if (s->has_ops && s->state == SDFD_JOB_DONE)
        add_caveats(o, s);
    return o;
}

/* 202 with the job just started and its Location, as a bake or an ops job answers. */
static enum MHD_Result reply_started(request *req, const char id[24])
{
    sdfd_job_status status;
    sdfd_volumes_job(req->srv->volumes, id, &status);
    sdfd_http_header location = {MHD_HTTP_HEADER_LOCATION, ""};
    snprintf(location.value, sizeof location.value, "/v1/jobs/%s", id);
    cJSON *json = job_json(&status);
    char *text = cJSON_PrintUnformatted(json);
    cJSON_Delete(json);
    return text ? sdfd_http_send(req, 202, "application/json", text, strlen(text), &location, 1)
                : MHD_NO;
}

enum MHD_Result sdfd_http_bake(request *req)
{
    sdfd_server *srv = req->srv;
    sdfd_bake_request bake; /* the body is JSON whatever its Content-Type says (curl -d) */
    sdfd_bake_names names;
    char err[512];
    int rc = sdfd_bake_from_json(req->body, req->len, &bake, &names, err, sizeof err);
    if (rc)
        return sdfd_http_error(req, rc, "%s", err);
    sdf_mesh *mesh;
    if ((rc = sdfd_cache_mesh(srv->cache, req->name, strlen(req->name), &mesh, err, sizeof err)))
        return sdfd_http_error(req, rc, "%s", err);
    if (names.smoothing_mesh[0]) {
        rc = sdfd_cache_mesh(srv->cache, names.smoothing_mesh, strlen(names.smoothing_mesh),
                             &bake.smoothing_mesh, err, sizeof err);
        if (rc) {
            sdf_mesh_release(mesh);
            if (rc == SDF_ENOTFOUND)
                snprintf(err, sizeof err, "no smoothing mesh named '%s'", names.smoothing_mesh);
            return sdfd_http_error(req, rc, "%s", err);
        }
        bake.filter.smooth.mesh = bake.smoothing_mesh;
    }
    if (bake.mesh_box) { /* "margin": 0: the corner nodes on the mesh's own box */
        sdf_mesh_report report;
        sdf_mesh_get_report(mesh, &report);
        for (int a = 0; a < 3; a++)
            bake.options.lo[a] = report.bbox_min[a], bake.options.hi[a] = report.bbox_max[a];
    }
    const char *volume = names.volume[0] ? names.volume : req->name;
    char id[24];
    /* The job takes over both mesh references, also when it fails to start. */
    rc = sdfd_volumes_bake(srv->volumes, mesh, req->name, volume, &bake, id, err, sizeof err);
    if (rc)
        return sdfd_http_error(req, rc, "%s", err);
    return reply_started(req, id);
}

enum MHD_Result sdfd_http_volume_ops(request *req)
{
    sdfd_server *srv = req->srv;
    sdfd_ops_request ops; /* the body is JSON whatever its Content-Type says, as a bake's */
    char volume[SDFD_MAX_NAME + 1], err[512];
    int rc = sdfd_ops_from_json(req->body, req->len, &ops, volume, err, sizeof err);
    if (rc)
        return sdfd_http_error(req, rc, "%s", err);
    sdfd_stored_volume *source;
    if ((rc = sdfd_cache_volume(srv->cache, req->name, strlen(req->name), &source, err,
                                sizeof err)))
        return sdfd_http_error(req, rc, "%s", err);
    char id[24];
    /* The job takes over the source's reference, also when it fails to start. */
    rc = sdfd_volumes_ops(srv->volumes, source, volume[0] ? volume : req->name, &ops, id, err,
                          sizeof err);
    if (rc)
        return sdfd_http_error(req, rc, "%s", err);
    return reply_started(req, id);
}

enum MHD_Result sdfd_http_job(request *req)
{
    sdfd_server *srv = req->srv;
    sdfd_job_status s;
    int deleting = !strcmp(req->method, "DELETE");
    int rc = deleting ? sdfd_volumes_cancel(srv->volumes, req->name, &s)
                      : sdfd_volumes_job(srv->volumes, req->name, &s);
    if (rc && !deleting) /* another replica's, or one this process forgot: its record */
        rc = sdfd_cache_job(srv->cache, req->name, &s);
    if (rc)
        return sdfd_http_error(req, rc, "no job '%s'", req->name);
    return sdfd_http_json(req, 200, job_json(&s));
}

enum MHD_Result sdfd_http_jobs(request *req)
{
    sdfd_job_status *jobs;
    size_t n = sdfd_volumes_jobs(req->srv->volumes, &jobs);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "jobs");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, job_json(&jobs[i]));
    free(jobs);
    return sdfd_http_json(req, 200, root);
}

static cJSON *volume_json(const sdfd_stored_volume *s) { return sdfd_cache_volume_json(s); }

enum MHD_Result sdfd_http_volumes(request *req)
{
    cJSON *root = cJSON_CreateObject(), *stored = sdfd_cache_list_volumes(req->srv->cache);
    if (stored) { /* the store's */
        cJSON_AddItemToObject(root, "volumes", stored);
        return sdfd_http_json(req, 200, root);
    }
    sdfd_stored_volume **list;
    size_t n = sdfd_volumes_list(req->srv->volumes, &list);
    cJSON *arr = cJSON_AddArrayToObject(root, "volumes");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, volume_json(list[i]));
    sdfd_volumes_free_list(list, n);
    return sdfd_http_json(req, 200, root);
}

/* An uploaded EXR volume (another replica's download, say) becomes a stored volume. Only
 * EXR: an npy download carries no origin, spacing or encoding, so a body that is one (its
 * magic, lib/io/npy.c's) is told so by name; anything else gets the EXR reader's reason. */
static void load_volume(request *req)
{
    static const char npy_magic[] = "\x93NUMPY";
    sdf_volume *volume = NULL;
    if (req->len >= sizeof npy_magic - 1 && !memcmp(req->body, npy_magic, sizeof npy_magic - 1)) {
        req->work_rc = SDF_EFORMAT;
        snprintf(req->diag.message, sizeof req->diag.message,
                 "the body is a NumPy file; a volume upload takes the EXR file that "
                 ".../data?format=exr gives, which carries the origin, spacing and encoding");
        return;
    }
    req->work_rc = sdf_volume_load_exr_memory(req->body, req->len, &volume, &req->diag);
    if (req->work_rc == SDF_EFORMAT) {
        sdf_diag exr = req->diag;
        snprintf(req->diag.message, sizeof req->diag.message,
                 "a volume upload takes the EXR file that .../data?format=exr gives: %.180s",
                 exr.message);
    }
    if (!req->work_rc)
        req->work_rc = sdfd_cache_put_volume(req->srv->cache, req->name, volume, req->body,
                                             req->len, &req->replaced, req->diag.message,
                                             sizeof req->diag.message);
}

static enum MHD_Result reply_volume_upload(request *req)
{
    if (req->work_rc)
        return sdfd_http_error(req, req->work_rc, "%s", req->diag.message);
    sdfd_stored_volume *s;
    char msg[512];
    int rc = sdfd_cache_volume(req->srv->cache, req->name, strlen(req->name), &s, msg, sizeof msg);
    if (rc) /* deleted in between */
        return sdfd_http_error(req, rc, "%s", msg);
    sdfd_log("info", "volume_loaded", "%s: %s by upload", req->name,
             req->replaced ? "replaced" : "added");
    enum MHD_Result r = sdfd_http_json(req, req->replaced ? 200 : 201, volume_json(s));
    sdfd_volume_release(s);
    return r;
}

enum MHD_Result sdfd_http_volume(request *req)
{
    sdfd_server *srv = req->srv;
    if (!strcmp(req->method, "PUT"))
        return sdfd_http_start_thread(req, load_volume, reply_volume_upload);
    char msg[512];
    int rc;
    if (!strcmp(req->method, "DELETE")) {
        if ((rc = sdfd_cache_remove_volume(srv->cache, req->name, msg, sizeof msg)))
            return sdfd_http_error(req, rc, "%s", msg);
        sdfd_log("info", "volume_deleted", "%s", req->name);
        return sdfd_http_buffer(req, 204, "application/json", NULL, 0, NULL);
    }
    sdfd_stored_volume *s;
    if ((rc = sdfd_cache_volume(srv->cache, req->name, strlen(req->name), &s, msg, sizeof msg)))
        return sdfd_http_error(req, rc, "%s", msg);
    enum MHD_Result r = sdfd_http_json(req, 200, volume_json(s));
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

static void volume_headers(request *req, sdfd_http_header h[4])
{
    static const char *const extensions[] = {"exr", "npy", "raw"};
    sdf_volume_info in;
    sdf_volume_get_info(req->stored->volume, &in);
    h[0] = (sdfd_http_header){"Content-Disposition", ""},
    h[1] = (sdfd_http_header){"X-SDF-Dims", ""};
    h[2] = (sdfd_http_header){"X-SDF-Order", ""}, h[3] = (sdfd_http_header){"X-SDF-Encoding", ""};
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
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory");
    const sdf_volume *v = req->stored->volume;
    if (req->file_type == SDF_VOLUME_NPY) {
        long len = sdf_volume_npy_header(v, s->header, sizeof s->header);
        if (len < 0) {
            free(s);
            return sdfd_http_error(req, (int)len, "cannot write the npy header");
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
    sdfd_http_header h[4];
    volume_headers(req, h);
    return sdfd_http_queue(req, 200, volume_file_type(req->file_type), r, total, h, 4);
}

static void encode_volume(request *req)
{
    req->work_rc = sdf_volume_save_memory(req->stored->volume, req->file_type,
                                            (void **)&req->out_body, &req->out_len, &req->diag);
}

static enum MHD_Result reply_volume_data(request *req)
{
    if (req->work_rc)
        return sdfd_http_error(req, req->work_rc, "%s", req->diag.message);
    sdfd_http_header h[4];
    volume_headers(req, h);
    char *body = req->out_body;
    req->out_body = NULL; /* MHD frees it */
    return sdfd_http_send(req, 200, volume_file_type(req->file_type), body, req->out_len, h, 4);
}

enum MHD_Result sdfd_http_volume_data(request *req)
{
    const char *format = sdfd_url_value(&req->args, "format");
    if (sdf_volume_file_from_name(format ? format : "exr", &req->file_type))
        return sdfd_http_error(req, SDF_EINVAL, "unknown format '%s' (exr, npy, raw)", format);
    char msg[512];
    int rc = sdfd_cache_volume(req->srv->cache, req->name, strlen(req->name), &req->stored, msg,
                               sizeof msg);
    if (rc)
        return sdfd_http_error(req, rc, "%s", msg);
    if (req->file_type != SDF_VOLUME_EXR)
        return stream_volume(req);
    return sdfd_http_start_thread(req, encode_volume,
                                  reply_volume_data); /* compression takes a while */
}

static void volume_query_done(sdfd_volume_query *vq)
{
    sdfd_http_resume(vq->user);
}

static enum MHD_Result reply_volume_query(request *req)
{
    if (req->volume_query.refused) /* after a load */
        req->points = 0;
    if (req->volume_query.status)
        return sdfd_http_error(req, req->volume_query.status, "%s", req->volume_query.message);
    return sdfd_http_results(req);
}

enum MHD_Result sdfd_http_volume_query(request *req)
{
    sdfd_server *srv = req->srv;
    sdfd_form form;
    sdfd_query_params params;
    size_t count;
    enum MHD_Result refused;
    if (sdfd_http_read_points(req, &form, &params, &count, &refused))
        return refused;
    char err[300], mode_buf[32], interp_buf[32];
    const char *mode = sdfd_http_param(params.mode, params.mode_len, mode_buf, sizeof mode_buf);
    const char *interp = sdfd_http_param(params.interpolation, params.interpolation_len,
                                         interp_buf, sizeof interp_buf);
    int gradient = 0, rc;
    if (mode && strcmp(mode, "value") && !(gradient = !strcmp(mode, "gradient")))
        return sdfd_http_error(req, SDF_EINVAL, "unknown volume mode '%s' (value, gradient)", mode);
    sdfd_volume_query *vq = &req->volume_query;
    *vq = (sdfd_volume_query){.volume_name = req->name, .volume_name_len = strlen(req->name),
                              .interpolation = SDF_VOLUME_DEFAULT, .gradient = gradient,
                              .points = req->points_buf, .count = count,
                              .done = volume_query_done, .user = req};
    if (interp && sdf_volume_filter_from_name(interp, &vq->interpolation))
        return sdfd_http_error(req, SDF_EINVAL, "unknown interpolation '%s' (default, trilinear, "
                               "nearest, hermite)", interp);
    req->reply_form = (sdfd_form)sdfd_http_reply_form(req, form);
    if (sdfd_reply_init(&req->reply, req->reply_form,
                        gradient ? SDF_MODE_GRADIENT : SDF_MODE_SIGNED, count))
        return sdfd_http_error(req, SDF_ENOMEM, "out of memory for %zu results", count);
    vq->words = req->reply.words;
    req->points = count;
    sdfd_http_wait(req, reply_volume_query); /* admission may end on a loader's thread */
    if ((rc = sdfd_volume_query_admit(srv, vq, err, sizeof err))) {
        sdfd_http_unwait(req);
        req->points = 0;
        return sdfd_http_error(req, rc, "%s", err);
    }
    return MHD_YES;
}
