/* opextract.c - a volume's surface as a mesh (opextract.h).
 *
 * POST stores what an upload of the same file would: the binary PLY written here is the
 * item's bytes, and the mesh is what parsing them gives, so a replica or a restart that loads
 * the item from the store has exactly the mesh that was answered. Both routes refuse a
 * surface of more than --max-triangles triangles (413) before writing its file. */
#include "ops/opextract.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/errors.h"
#include "core/log.h"
#include "ops/filterparams.h"
#include "ops/opmeshes.h"
#include "state/registry.h"
#include "state/surface.h"

typedef struct extract_req {
    sdf_extract_options opts;
    sdf_format format;
    char mesh[SDFD_MAX_NAME + 1]; /* POST: the new mesh's name */
} extract_req;

/* ---- arguments --------------------------------------------------------------------------- */

static int parse_bool(const char *text, int *out)
{
    if (!strcmp(text, "1") || !strcasecmp(text, "true"))
        return *out = 1, 0;
    if (!strcmp(text, "0") || !strcasecmp(text, "false"))
        return *out = 0, 0;
    return -1;
}

static int parse_url(sdfd_call *call, extract_req *q)
{
    const char *format = sdfd_url_value(call->args, "format"), *iso = sdfd_url_value(call->args, "iso"),
               *cap = sdfd_url_value(call->args, "cap"), *method = sdfd_url_value(call->args, "method");
    char *end = NULL;
    q->format = SDF_FORMAT_PLY;
    if (format && (sdf_format_from_name(format, &q->format) || q->format == SDF_FORMAT_AUTO))
        return sdfd_call_fail(call, SDF_EINVAL, "unknown format '%s' (ply, obj, stl, off)",
                              format), -1;
    if (iso && (q->opts.iso = strtod(iso, &end), *end || !isfinite(q->opts.iso)))
        return sdfd_call_fail(call, SDF_EINVAL, "iso must be a finite number, not '%s'", iso), -1;
    if (cap && parse_bool(cap, &q->opts.cap))
        return sdfd_call_fail(call, SDF_EINVAL, "cap must be true or false, not '%s'", cap), -1;
    if (method && sdf_extract_method_from_name(method, &q->opts.method))
        return sdfd_call_fail(call, SDF_EINVAL, "unknown method '%s' (auto, marching_cubes, "
                              "dual_contouring)", method), -1;
    return 0;
}

static int body_member(const cJSON *item, extract_req *q, char *err, size_t cap)
{
    const char *k = item->string;
    if (!strcmp(k, "mesh")) {
        if (!cJSON_IsString(item) || !sdfd_valid_name(item->valuestring, strlen(item->valuestring)))
            return snprintf(err, cap, "mesh must be the new mesh's name: 1-255 characters of "
                            "A-Z a-z 0-9 . _ - not starting with '.'"), -1;
        snprintf(q->mesh, sizeof q->mesh, "%s", item->valuestring);
    } else if (!strcmp(k, "iso")) {
        if (!cJSON_IsNumber(item) || !isfinite(item->valuedouble))
            return snprintf(err, cap, "iso must be a finite number"), -1;
        q->opts.iso = item->valuedouble;
    } else if (!strcmp(k, "method")) {
        if (!cJSON_IsString(item) || sdf_extract_method_from_name(item->valuestring, &q->opts.method))
            return snprintf(err, cap, "method must be auto, marching_cubes or dual_contouring"), -1;
    } else if (!strcmp(k, "cap")) {
        if (!cJSON_IsBool(item))
            return snprintf(err, cap, "cap must be true or false"), -1;
        q->opts.cap = cJSON_IsTrue(item);
    } else {
        return snprintf(err, cap, "unknown member \"%.40s\" (mesh, iso, cap, method)", k), -1;
    }
    return 0;
}

static int parse_body(sdfd_call *call, extract_req *q)
{
    char err[256] = "";
    cJSON *root = cJSON_ParseWithLength(call->body, call->len);
    const char *twice = cJSON_IsObject(root) ? sdfd_json_repeated_key(root) : NULL;
    if (!cJSON_IsObject(root))
        snprintf(err, sizeof err, "the body must be a JSON object such as {\"mesh\": \"NEW\"}");
    else if (twice)
        snprintf(err, sizeof err, "\"%.40s\" is given twice", twice);
    for (const cJSON *item = root && !err[0] ? root->child : NULL; item && !err[0];
         item = item->next)
        body_member(item, q, err, sizeof err);
    if (!err[0] && !q->mesh[0])
        snprintf(err, sizeof err, "mesh (the new mesh's name) is required");
    cJSON_Delete(root);
    q->format = SDF_FORMAT_PLY;
    return err[0] ? sdfd_call_fail(call, SDF_EINVAL, "%s", err), -1 : 0;
}

/* ---- the work ---------------------------------------------------------------------------- */

/* The volume held in result.stream, released here once extracted. */
static sdfd_stored_volume *take_volume(sdfd_call *call)
{
    sdfd_stored_volume *s = call->result.stream;
    call->result.stream = NULL;
    return s;
}

static sdf_extract_options threaded(sdfd_call *call, const extract_req *q)
{
    sdf_extract_options o = q->opts;
    o.threads = call->srv->cfg.threads;
    return o;
}

static const char *content_type(sdf_format f)
{
    return f == SDF_FORMAT_STL ? "model/stl"
         : f == SDF_FORMAT_OBJ ? "model/obj"
         : f == SDF_FORMAT_OFF ? "text/plain"
                               : "application/octet-stream";
}

static void answer_file(sdfd_call *call)
{
    extract_req *q = call->state;
    sdfd_stored_volume *s = take_volume(call);
    sdf_extract_options o = threaded(call, q);
    char err[256];
    void *bytes;
    size_t n, nt;
    int rc = sdfd_surface_file(s->volume, &o, call->srv->cfg.max_total_triangles, q->format,
                               &bytes, &n, &nt, err, sizeof err);
    sdfd_volume_release(s);
    if (rc) {
        sdfd_call_fail(call, rc, "%s", err);
        return;
    }
    sdfd_call_field(call, "Content-Disposition", "attachment; filename=\"%s.%s\"", call->name,
                    sdf_format_name(q->format));
    sdfd_call_field(call, "X-SDF-Triangles", "%zu", nt);
    call->result.bytes = bytes, call->result.len = n;
    call->result.type = content_type(q->format);
    call->result.status = 200;
}

static void store_mesh(sdfd_call *call)
{
    extract_req *q = call->state;
    sdfd_stored_volume *s = take_volume(call);
    sdf_extract_options o = threaded(call, q);
    char err[512];
    sdf_mesh *mesh = NULL;
    int replaced = 0;
    int rc = sdfd_cache_put_surface(call->srv->cache, q->mesh, s->volume, &o, &replaced, &mesh,
                                    err, sizeof err);
    sdfd_volume_release(s);
    if (rc) {
        sdfd_call_fail(call, rc, "%s", err);
        return;
    }
    sdfd_log("info", "mesh_loaded", "%s: %s from volume %s", q->mesh,
             replaced ? "replaced" : "added", call->name);
    sdfd_call_json(call, replaced ? 200 : 201, sdfd_mesh_report_json(q->mesh, mesh));
    sdf_mesh_release(mesh);
}

/* Parse, look the volume up (held in result.stream until the worker has extracted), defer. */
static int start(sdfd_call *call, int post, void (*work)(sdfd_call *call))
{
    extract_req *q = calloc(1, sizeof *q);
    if (!q)
        return sdfd_call_fail(call, SDF_ENOMEM, "out of memory");
    call->state = q; /* freed with the call */
    if (post ? parse_body(call, q) : parse_url(call, q))
        return SDFD_CALL_READY;
    sdfd_stored_volume *s = sdfd_call_lookup(call, SDFD_ITEM_VOLUME, call->name);
    if (!s)
        return SDFD_CALL_READY;
    call->result.stream = s;
    return sdfd_call_defer(call, work);
}

int sdfd_op_volume_mesh(sdfd_call *call)
{
    return start(call, 0, answer_file);
}

int sdfd_op_volume_mesh_post(sdfd_call *call)
{
    return start(call, 1, store_mesh);
}
