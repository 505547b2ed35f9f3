/* opjobs.c - bakes, field-operation jobs and the job routes (opjobs.h). A job's JSON is the
 * same wherever it appears: the 202 that starts it, GET /v1/jobs/{id}, the list. */
#include "ops/opjobs.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "ops/bakeparams.h"
#include "ops/opsparams.h"

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

/* 202 with the job just started and where to follow it, as a bake or an ops job answers. */
static int started(sdfd_call *call, const char id[24])
{
    sdfd_job_status status;
    sdfd_volumes_job(call->srv->volumes, id, &status);
    sdfd_call_field(call, "Location", "/v1/jobs/%s", id);
    return sdfd_call_json(call, 202, job_json(&status));
}

int sdfd_op_bake(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    sdfd_bake_request bake; /* the body is JSON whatever its Content-Type says (curl -d) */
    sdfd_bake_names names;
    char err[512];
    int rc = sdfd_bake_from_json(call->body, call->len, &bake, &names, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    sdf_mesh *mesh = sdfd_call_lookup(call, SDFD_ITEM_MESH, call->name);
    if (!mesh)
        return SDFD_CALL_READY;
    if (names.smoothing_mesh[0]) {
        bake.smoothing_mesh = sdfd_call_lookup(call, SDFD_ITEM_MESH, names.smoothing_mesh);
        if (!bake.smoothing_mesh) {
            sdf_mesh_release(mesh);
            if (call->result.code == SDF_ENOTFOUND)
                sdfd_call_fail(call, SDF_ENOTFOUND, "no smoothing mesh named '%s'",
                               names.smoothing_mesh);
            return SDFD_CALL_READY;
        }
        bake.filter.smooth.mesh = bake.smoothing_mesh;
    }
    if (bake.mesh_box) { /* "margin": 0: the corner nodes on the mesh's own box */
        sdf_mesh_report report;
        sdf_mesh_get_report(mesh, &report);
        for (int a = 0; a < 3; a++)
            bake.options.lo[a] = report.bbox_min[a], bake.options.hi[a] = report.bbox_max[a];
    }
    const char *volume = names.volume[0] ? names.volume : call->name;
    char id[24];
    /* The job takes over both mesh references, also when it fails to start. */
    rc = sdfd_volumes_bake(srv->volumes, mesh, call->name, volume, &bake, id, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    return started(call, id);
}

int sdfd_op_volume_ops(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    sdfd_ops_request ops; /* the body is JSON whatever its Content-Type says, as a bake's */
    char volume[SDFD_MAX_NAME + 1], err[512];
    int rc = sdfd_ops_from_json(call->body, call->len, &ops, volume, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    sdfd_stored_volume *source = sdfd_call_lookup(call, SDFD_ITEM_VOLUME, call->name);
    if (!source)
        return SDFD_CALL_READY;
    char id[24];
    /* The job takes over the source's reference, also when it fails to start. */
    rc = sdfd_volumes_ops(srv->volumes, source, volume[0] ? volume : call->name, &ops, id, err,
                          sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    return started(call, id);
}

/* GET or DELETE of one job: this process's, else (GET) its record in the store. */
static int one_job(sdfd_call *call, int cancel)
{
    sdfd_server *srv = call->srv;
    sdfd_job_status s;
    int rc = cancel ? sdfd_volumes_cancel(srv->volumes, call->name, &s)
                    : sdfd_volumes_job(srv->volumes, call->name, &s);
    if (rc && !cancel) /* another replica's, or one this process forgot: its record */
        rc = sdfd_cache_job(srv->cache, call->name, &s);
    if (rc)
        return sdfd_call_fail(call, rc, "no job '%s'", call->name);
    return sdfd_call_json(call, 200, job_json(&s));
}

int sdfd_op_job_get(sdfd_call *call)
{
    return one_job(call, 0);
}

int sdfd_op_job_cancel(sdfd_call *call)
{
    return one_job(call, 1);
}

int sdfd_op_job_list(sdfd_call *call)
{
    sdfd_job_status *jobs;
    size_t n = sdfd_volumes_jobs(call->srv->volumes, &jobs);
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "jobs");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, job_json(&jobs[i]));
    free(jobs);
    return sdfd_call_json(call, 200, root);
}
