/* opmeshes.c - the mesh operations (opmeshes.h). A mesh's description is its library report
 * (sdf_mesh_get_report) in JSON, the same for GET and for the answer to an upload. */
#include "ops/opmeshes.h"

#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"
#include "ops/mesharrays.h"

cJSON *sdfd_mesh_report_json(const char *name, const sdf_mesh *mesh)
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

int sdfd_op_mesh_list(sdfd_call *call)
{
    sdfd_mesh_summary *list;
    size_t n = sdfd_cache_list_meshes(call->srv->cache, &list);
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
    return sdfd_call_json(call, 200, root);
}

int sdfd_op_mesh_get(sdfd_call *call)
{
    sdf_mesh *mesh = sdfd_call_lookup(call, SDFD_ITEM_MESH, call->name);
    if (!mesh)
        return SDFD_CALL_READY;
    cJSON *json = sdfd_mesh_report_json(call->name, mesh);
    sdf_mesh_release(mesh);
    return sdfd_call_json(call, 200, json);
}

/* On the worker: parse and index the body, then store it through the cache. Arrays (JSON or
 * npz, mesharrays.h) become the PLY file of the same arrays first, stored as such. */
static void load_upload(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    sdf_mesh_options opts = {.max_triangles = srv->cfg.max_total_triangles};
    const char *format = sdfd_url_value(call->args, "format");
    sdfd_mesh_body kind = sdfd_mesh_body_kind(format, call->body, call->len);
    sdf_mesh *mesh = NULL;
    sdf_diag diag = {0};
    int rc, replaced = 0;
    if (kind == SDFD_MESH_BODY_FILE && format && sdf_format_from_name(format, &opts.format)) {
        sdfd_call_fail(call, SDF_EFORMAT, "unknown format '%s' (obj, ply, stl, off, json, npz)",
                       format);
        return;
    }
    void *ply = NULL;
    size_t len = call->len;
    const void *file = call->body;
    if (kind != SDFD_MESH_BODY_FILE) {
        rc = sdfd_mesh_arrays_to_ply(kind, call->body, call->len, opts.max_triangles, &ply, &len,
                                     diag.message, sizeof diag.message);
        if (rc) {
            sdfd_call_fail(call, rc, "%s", diag.message);
            return;
        }
        file = ply, opts.format = SDF_FORMAT_PLY;
    }
    rc = sdf_mesh_load_memory(file, len, &opts, &mesh, &diag);
    if (!rc)
        rc = sdfd_cache_put(srv->cache, SDFD_ITEM_MESH, call->name, sdf_mesh_retain(mesh), file,
                            len, &replaced, diag.message, sizeof diag.message);
    free(ply);
    if (rc) {
        sdf_mesh_release(mesh);
        sdfd_call_fail(call, rc, "%s", diag.message);
        return;
    }
    sdfd_log("info", "mesh_loaded", "%s: %s by upload", call->name,
             replaced ? "replaced" : "added");
    sdfd_call_json(call, replaced ? 200 : 201, sdfd_mesh_report_json(call->name, mesh));
    sdf_mesh_release(mesh);
}

int sdfd_op_mesh_put(sdfd_call *call)
{
    return sdfd_call_defer(call, load_upload);
}
