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

/* A job's JSON. A job of this replica alone (no catalog) is this replica's, at its first
 * attempt. */
static cJSON *job_json(const sdfd_server *srv, const sdfd_job_status *s)
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
    if (srv->jobs) {
        if (s->owner[0])
            cJSON_AddStringToObject(o, "owner", s->owner);
        else
            cJSON_AddNullToObject(o, "owner");
        cJSON_AddNumberToObject(o, "attempts", s->attempts);
    } else {
        cJSON_AddStringToObject(o, "owner", srv->cfg.replica_id);
        cJSON_AddNumberToObject(o, "attempts", 1);
    }
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

/* 202 with the job just started (or queued for any replica) and where to follow it. */
static int started(sdfd_call *call, const sdfd_job_status *status)
{
    sdfd_call_field(call, "Location", "/v1/jobs/%s", status->id);
    return sdfd_call_json(call, 202, job_json(call->srv, status));
}

static int started_here(sdfd_call *call, const char id[24])
{
    sdfd_job_status status;
    sdfd_volumes_job(call->srv->volumes, id, &status);
    return started(call, &status);
}

/* A job every replica may run (--catalog): its row, queued; the request is kept as it came
 * and read again by the replica that claims it (sdfd_op_start_shared). */
static int share(sdfd_call *call, sdfd_job_status *s)
{
    sdfd_server *srv = call->srv;
    char err[512];
    sdfd_volumes_new_id(srv->volumes, s->id);
    s->state = SDFD_JOB_QUEUED;
    int rc = sdfd_catjobs_insert(sdfd_jobrunner_catalog(srv->jobs), s, call->name, call->body,
                                 call->len, srv->cfg.max_jobs, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    sdfd_jobrunner_poke(srv->jobs);
    return started(call, s);
}

/* Names a job's request looks up: through a call (a refusal is the call's answer), or
 * through the cache on the job runner's thread (its code and message kept here). */
typedef struct job_lookup {
    sdfd_call *call;
    sdfd_server *srv;
    int code;
    char message[512];
} job_lookup;

#define LOOKUP_FAILED 1 /* not an error code: the lookup's refusal is in the job_lookup */

static void *lookup(job_lookup *l, sdfd_item_kind kind, const char *name)
{
    void *item = NULL;
    if (l->call) {
        item = sdfd_call_lookup(l->call, kind, name);
        l->code = item ? 0 : l->call->result.code;
        return item;
    }
    l->code = sdfd_cache_get(l->srv->cache, kind, name, strlen(name), &item, l->message,
                             sizeof l->message);
    return l->code ? NULL : item;
}

/* A bake request made ready: parsed from `body`, the mesh `target` and its smoothing mesh
 * looked up (retained: *mesh and bake->smoothing_mesh), the box. 0, LOOKUP_FAILED, or an
 * error with err. */
static int prepare_bake(job_lookup *l, const char *body, size_t len, const char *target,
                        sdfd_bake_request *bake, sdfd_bake_names *names, sdf_mesh **mesh,
                        char *err, size_t cap)
{
    int rc = sdfd_bake_from_json(body, len, bake, names, err, cap);
    if (rc)
        return rc;
    if (!(*mesh = lookup(l, SDFD_ITEM_MESH, target)))
        return LOOKUP_FAILED;
    if (names->smoothing_mesh[0]) {
        bake->smoothing_mesh = lookup(l, SDFD_ITEM_MESH, names->smoothing_mesh);
        if (!bake->smoothing_mesh) {
            sdf_mesh_release(*mesh);
            if (l->code == SDF_ENOTFOUND) {
                snprintf(err, cap, "no smoothing mesh named '%s'", names->smoothing_mesh);
                return SDF_ENOTFOUND;
            }
            return LOOKUP_FAILED;
        }
        bake->filter.smooth.mesh = bake->smoothing_mesh;
    }
    if (bake->mesh_box) { /* "margin": 0: the corner nodes on the mesh's own box */
        sdf_mesh_report report;
        sdf_mesh_get_report(*mesh, &report);
        for (int a = 0; a < 3; a++)
            bake->options.lo[a] = report.bbox_min[a], bake->options.hi[a] = report.bbox_max[a];
    }
    return 0;
}

/* A shared bake: checked here, run wherever it is claimed. */
static int share_bake(sdfd_call *call, sdf_mesh *mesh, sdfd_bake_request *bake,
                      const char *volume)
{
    char err[512];
    int rc = sdfd_volumes_check_bake(call->srv->volumes, mesh, bake, err, sizeof err);
    sdfd_job_status s = {.kind = SDFD_JOB_BAKE, .has_ops = bake->ops.count > 0};
    sdf_mesh_release(mesh);
    sdf_mesh_release(bake->smoothing_mesh);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    snprintf(s.mesh, sizeof s.mesh, "%s", call->name);
    snprintf(s.volume, sizeof s.volume, "%s", volume);
    return share(call, &s);
}

int sdfd_op_bake(sdfd_call *call)
{
    sdfd_server *srv = call->srv;
    sdfd_bake_request bake; /* the body is JSON whatever its Content-Type says (curl -d) */
    sdfd_bake_names names;
    sdf_mesh *mesh = NULL;
    char err[512];
    job_lookup l = {.call = call, .srv = srv};
    int rc = prepare_bake(&l, call->body, call->len, call->name, &bake, &names, &mesh, err,
                          sizeof err);
    if (rc == LOOKUP_FAILED)
        return SDFD_CALL_READY;
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    const char *volume = names.volume[0] ? names.volume : call->name;
    if (srv->jobs)
        return share_bake(call, mesh, &bake, volume);
    char id[24] = "";
    /* The job takes over both mesh references, also when it fails to start. */
    rc = sdfd_volumes_bake(srv->volumes, mesh, call->name, volume, &bake, id, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    return started_here(call, id);
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
    const char *target = volume[0] ? volume : call->name;
    if (srv->jobs) {
        sdfd_job_status s = {.kind = SDFD_JOB_OPS, .has_ops = 1};
        snprintf(s.mesh, sizeof s.mesh, "%s", source->mesh);
        snprintf(s.source, sizeof s.source, "%s", source->name);
        snprintf(s.volume, sizeof s.volume, "%s", target);
        rc = sdfd_volumes_check_ops(srv->volumes, source, &ops, err, sizeof err);
        sdfd_volume_release(source);
        return rc ? sdfd_call_fail(call, rc, "%s", err) : share(call, &s);
    }
    char id[24] = "";
    /* The job takes over the source's reference, also when it fails to start. */
    rc = sdfd_volumes_ops(srv->volumes, source, target, &ops, id, err, sizeof err);
    if (rc)
        return sdfd_call_fail(call, rc, "%s", err);
    return started_here(call, id);
}

int sdfd_op_start_shared(void *user, const sdfd_catjob *job, char *err, size_t cap)
{
    sdfd_server *srv = user;
    job_lookup l = {.srv = srv};
    char id[24];
    snprintf(id, sizeof id, "%s", job->status.id);
    int rc;
    if (job->status.kind == SDFD_JOB_BAKE) {
        sdfd_bake_request bake;
        sdfd_bake_names names;
        sdf_mesh *mesh = NULL;
        rc = prepare_bake(&l, job->request, job->request_len, job->target, &bake, &names,
                          &mesh, err, cap);
        if (!rc)
            rc = sdfd_volumes_bake(srv->volumes, mesh, job->target, job->status.volume, &bake,
                                   id, err, cap);
    } else {
        sdfd_ops_request ops;
        char volume[SDFD_MAX_NAME + 1];
        sdfd_stored_volume *source = NULL;
        rc = sdfd_ops_from_json(job->request, job->request_len, &ops, volume, err, cap);
        if (!rc && !(source = lookup(&l, SDFD_ITEM_VOLUME, job->target)))
            rc = LOOKUP_FAILED;
        if (!rc)
            rc = sdfd_volumes_ops(srv->volumes, source, job->status.volume, &ops, id, err, cap);
    }
    if (rc == LOOKUP_FAILED) {
        snprintf(err, cap, "%s", l.message);
        rc = l.code;
    }
    return rc;
}

/* GET or DELETE of one job: the shared rows; else this process's, else (GET) its record in
 * the store. */
static int one_job(sdfd_call *call, int cancel)
{
    sdfd_server *srv = call->srv;
    sdfd_job_status s;
    char err[512];
    int rc;
    if (srv->jobs) {
        sdfd_catalog *c = sdfd_jobrunner_catalog(srv->jobs);
        rc = cancel ? sdfd_catjobs_cancel(c, call->name, &s, err, sizeof err)
                    : sdfd_catjobs_get(c, call->name, &s, err, sizeof err);
        if (rc == SDF_ENOTFOUND)
            return sdfd_call_fail(call, rc, "no job '%s'", call->name);
        if (rc)
            return sdfd_call_fail(call, rc, "%s", err);
        if (cancel)
            sdfd_jobrunner_poke(srv->jobs); /* its owner may be this replica */
        return sdfd_call_json(call, 200, job_json(srv, &s));
    }
    rc = cancel ? sdfd_volumes_cancel(srv->volumes, call->name, &s)
                : sdfd_volumes_job(srv->volumes, call->name, &s);
    if (rc && !cancel) /* another replica's, or one this process forgot: its record */
        rc = sdfd_cache_job(srv->cache, call->name, &s);
    if (rc)
        return sdfd_call_fail(call, rc, "no job '%s'", call->name);
    return sdfd_call_json(call, 200, job_json(srv, &s));
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
    sdfd_server *srv = call->srv;
    sdfd_job_status *jobs = NULL;
    size_t n = 0;
    char err[512];
    if (!srv->jobs)
        n = sdfd_volumes_jobs(srv->volumes, &jobs);
    else if (sdfd_catjobs_list(sdfd_jobrunner_catalog(srv->jobs), srv->cfg.max_jobs, &jobs, &n,
                               err, sizeof err)) {
        return sdfd_call_fail(call, SDFD_EUNAVAILABLE, "%s", err);
    }
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "jobs");
    for (size_t i = 0; i < n; i++)
        cJSON_AddItemToArray(arr, job_json(srv, &jobs[i]));
    free(jobs);
    return sdfd_call_json(call, 200, root);
}
