/* opvolumes.c - the volume operations (opvolumes.h). */
#include "ops/opvolumes.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"

int sdfd_op_volume_list(sdfd_call *call)
{
    cJSON *root = cJSON_CreateObject(), *stored = sdfd_cache_list_volumes(call->srv->cache);
    if (stored) { /* the store's */
        cJSON_AddItemToObject(root, "volumes", stored);
        return sdfd_call_json(call, 200, root);
    }
    sdfd_stored_volume **list;
    size_t n = sdfd_volumes_list(call->srv->volumes, &list);
    cJSON *arr = cJSON_AddArrayToObject(root, "volumes");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, sdfd_cache_volume_json(list[i]));
    sdfd_volumes_free_list(list, n);
    return sdfd_call_json(call, 200, root);
}

/* The volume of the call's name as GET describes it, with `status`. */
static int describe(sdfd_call *call, int status)
{
    sdfd_stored_volume *s = sdfd_call_lookup(call, SDFD_ITEM_VOLUME, call->name);
    if (!s)
        return SDFD_CALL_READY;
    cJSON *json = sdfd_cache_volume_json(s);
    sdfd_volume_release(s);
    return sdfd_call_json(call, status, json);
}

int sdfd_op_volume_get(sdfd_call *call)
{
    return describe(call, 200);
}

/* An uploaded EXR volume (another replica's download, say) becomes a stored volume. Only
 * EXR: an npy download carries no origin, spacing or encoding, so a body that is one (its
 * magic, lib/io/npy.c's) is told so by name; anything else gets the EXR reader's reason. */
static void load_volume(sdfd_call *call)
{
    static const char npy_magic[] = "\x93NUMPY";
    sdf_volume *volume = NULL;
    sdf_diag diag = {0};
    int replaced = 0;
    if (call->len >= sizeof npy_magic - 1 &&
        !memcmp(call->body, npy_magic, sizeof npy_magic - 1)) {
        sdfd_call_fail(call, SDF_EFORMAT, "the body is a NumPy file; a volume upload takes the "
                       "EXR file that .../data?format=exr gives, which carries the origin, "
                       "spacing and encoding");
        return;
    }
    int rc = sdf_volume_load_exr_memory(call->body, call->len, &volume, &diag);
    if (rc == SDF_EFORMAT) {
        sdfd_call_fail(call, rc, "a volume upload takes the EXR file that .../data?format=exr "
                       "gives: %.180s", diag.message);
        return;
    }
    if (!rc)
        rc = sdfd_cache_put(call->srv->cache, SDFD_ITEM_VOLUME, call->name, volume, call->body,
                            call->len, &replaced, diag.message, sizeof diag.message);
    if (rc) {
        sdfd_call_fail(call, rc, "%s", diag.message);
        return;
    }
    sdfd_log("info", "volume_loaded", "%s: %s by upload", call->name,
             replaced ? "replaced" : "added");
    describe(call, replaced ? 200 : 201); /* deleted in between: its 404 */
}

int sdfd_op_volume_put(sdfd_call *call)
{
    return sdfd_call_defer(call, load_volume);
}

/* ---- downloads --------------------------------------------------------------------------- */

static const char *file_type(sdf_volume_file type)
{
    return type == SDF_VOLUME_EXR ? "image/x-exr"
           : type == SDF_VOLUME_NPY ? "application/x-npy"
                                    : "application/octet-stream";
}

/* The fields every download carries: a file name, the dimensions, order and encoding. */
static void describe_file(sdfd_call *call, const sdfd_stored_volume *s, sdf_volume_file type)
{
    static const char *const extensions[] = {"exr", "npy", "raw"};
    sdf_volume_info in;
    sdf_volume_get_info(s->volume, &in);
    sdfd_call_field(call, "Content-Disposition", "attachment; filename=\"%s.%s\"", call->name,
                    extensions[type]);
    sdfd_call_field(call, "X-SDF-Dims", "%zu,%zu,%zu", in.dims[0], in.dims[1], in.dims[2]);
    sdfd_call_field(call, "X-SDF-Order", "%d", in.order);
    sdfd_call_field(call, "X-SDF-Encoding", "%s", sdf_encoding_name(in.encoding));
}

/* On the worker: EXR compression takes a while. The volume is call->result.stream's. */
static void encode_exr(sdfd_call *call)
{
    sdfd_result *r = &call->result;
    sdf_diag diag = {0};
    void *bytes = NULL;
    int rc = sdf_volume_save_memory(r->stream->volume, SDF_VOLUME_EXR, &bytes, &r->len, &diag);
    sdfd_volume_release(r->stream);
    r->stream = NULL;
    if (rc) {
        r->n_fields = 0;
        sdfd_call_fail(call, rc, "%s", diag.message);
        return;
    }
    r->bytes = bytes;
    r->type = file_type(SDF_VOLUME_EXR);
    r->status = 200;
}

/* npy and raw are the node words as stored (after an npy header): the transport streams them
 * from the volume (result.stream) instead of a copy the size of the volume. */
int sdfd_op_volume_data(sdfd_call *call)
{
    const char *format = sdfd_url_value(call->args, "format");
    sdf_volume_file type;
    if (sdf_volume_file_from_name(format ? format : "exr", &type))
        return sdfd_call_fail(call, SDF_EINVAL, "unknown format '%s' (exr, npy, raw)", format);
    sdfd_stored_volume *s = sdfd_call_lookup(call, SDFD_ITEM_VOLUME, call->name);
    if (!s)
        return SDFD_CALL_READY;
    describe_file(call, s, type);
    call->result.stream = s;
    call->result.file = type;
    if (type != SDF_VOLUME_EXR) {
        call->result.status = 200;
        call->result.type = file_type(type);
        return SDFD_CALL_READY;
    }
    return sdfd_call_defer(call, encode_exr);
}
