/* jobrecords.c - jobs' records in the store (jobrecords.h): a job's status as one JSON
 * object, written when the job is accepted and when it ends, read back after a restart. The
 * keys an ops job added ("kind", "source", "ops", "caveats", "warning") are optional when
 * read: a record without them is a bake's. */
#include "state/jobrecords.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"

static char *job_record(const sdfd_job_status *s)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "id", s->id);
    cJSON_AddStringToObject(o, "kind", sdfd_job_kind_name(s->kind));
    cJSON_AddStringToObject(o, "state", sdfd_job_state_name(s->state));
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    cJSON_AddStringToObject(o, "source", s->source);
    cJSON_AddStringToObject(o, "volume", s->volume);
    cJSON_AddBoolToObject(o, "ops", s->has_ops);
    cJSON_AddNumberToObject(o, "caveats", s->caveats);
    cJSON_AddStringToObject(o, "warning", s->warning);
    cJSON_AddNumberToObject(o, "seconds", s->seconds);
    cJSON_AddNumberToObject(o, "error", s->error);
    cJSON_AddStringToObject(o, "message", s->message);
    char *text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return text;
}

/* The optional keys of a record (see the top). */
static void parse_ops(const cJSON *o, sdfd_job_status *out)
{
    const cJSON *kind = cJSON_GetObjectItemCaseSensitive(o, "kind"),
                *source = cJSON_GetObjectItemCaseSensitive(o, "source"),
                *ops = cJSON_GetObjectItemCaseSensitive(o, "ops"),
                *caveats = cJSON_GetObjectItemCaseSensitive(o, "caveats"),
                *warning = cJSON_GetObjectItemCaseSensitive(o, "warning");
    if (cJSON_IsString(kind))
        sdfd_job_kind_from_name(kind->valuestring, &out->kind);
    if (cJSON_IsString(source))
        snprintf(out->source, sizeof out->source, "%s", source->valuestring);
    out->has_ops = cJSON_IsTrue(ops);
    if (cJSON_IsNumber(caveats) && caveats->valuedouble >= 0 && caveats->valuedouble < 256)
        out->caveats = (unsigned)caveats->valuedouble;
    if (cJSON_IsString(warning))
        snprintf(out->warning, sizeof out->warning, "%s", warning->valuestring);
}

/* A record back into a status; 0 or -1. */
static int parse_job(const char *text, sdfd_job_status *out)
{
    cJSON *o = cJSON_Parse(text);
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(o, "id"),
                *state = cJSON_GetObjectItemCaseSensitive(o, "state"),
                *mesh = cJSON_GetObjectItemCaseSensitive(o, "mesh"),
                *volume = cJSON_GetObjectItemCaseSensitive(o, "volume"),
                *seconds = cJSON_GetObjectItemCaseSensitive(o, "seconds"),
                *error = cJSON_GetObjectItemCaseSensitive(o, "error"),
                *message = cJSON_GetObjectItemCaseSensitive(o, "message");
    int ok = cJSON_IsString(id) && cJSON_IsString(state) && cJSON_IsString(mesh) &&
             cJSON_IsString(volume) && cJSON_IsNumber(seconds) && cJSON_IsNumber(error) &&
             cJSON_IsString(message);
    memset(out, 0, sizeof *out);
    int found = -1;
    for (int s = SDFD_JOB_QUEUED; ok && s <= SDFD_JOB_CANCELED; s++)
        if (!strcmp(state->valuestring, sdfd_job_state_name((sdfd_job_state)s)))
            found = s;
    ok = ok && found >= 0;
    if (ok) {
        out->state = (sdfd_job_state)found;
        snprintf(out->id, sizeof out->id, "%s", id->valuestring);
        snprintf(out->mesh, sizeof out->mesh, "%s", mesh->valuestring);
        snprintf(out->volume, sizeof out->volume, "%s", volume->valuestring);
        snprintf(out->message, sizeof out->message, "%s", message->valuestring);
        out->seconds = seconds->valuedouble;
        out->error = (int)error->valuedouble;
        out->progress = out->state == SDFD_JOB_DONE;
        parse_ops(o, out);
    }
    cJSON_Delete(o);
    return ok ? 0 : -1;
}

int sdfd_jobrecords_started(sdfd_store *store, const sdfd_job_status *s)
{
    int fd = sdfd_store_lock_job(store, s->id); /* before the record says queued */
    char *text = job_record(s);
    if (text)
        sdfd_store_write_job(store, s->id, text);
    free(text);
    return fd;
}

void sdfd_jobrecords_ended(sdfd_store *store, const sdfd_job_status *s, int token)
{
    char *text = job_record(s);
    if (text)
        sdfd_store_write_job(store, s->id, text);
    free(text);
    sdfd_store_unlock_job(store, s->id, token);
}

void sdfd_jobrecords_forgotten(sdfd_store *store, const char *id)
{
    sdfd_store_remove_job(store, id);
}

int sdfd_jobrecords_read(sdfd_store *store, const char *id, sdfd_job_status *out)
{
    char *text = sdfd_store_read_job(store, id);
    int rc = text && !parse_job(text, out) && !strcmp(out->id, id) ? 0 : SDF_ENOTFOUND;
    free(text);
    return rc;
}

void sdfd_jobrecords_restore(sdfd_store *store, sdfd_volumes *volumes)
{
    char(*ids)[64];
    size_t n = sdfd_store_job_ids(store, &ids);
    for (size_t i = 0; i < n; i++) {
        sdfd_job_status s;
        char *text = sdfd_store_read_job(store, ids[i]);
        int ok = text && !parse_job(text, &s) && !strcmp(s.id, ids[i]);
        free(text);
        if (!ok || (s.state != SDFD_JOB_QUEUED && s.state != SDFD_JOB_RUNNING))
            continue;
        int fd = sdfd_store_lock_job(store, s.id);
        if (fd < 0)
            continue; /* a live process runs it */
        /* Its owner may have ended it (record, then unlock) since the record was read. */
        text = sdfd_store_read_job(store, ids[i]);
        ok = text && !parse_job(text, &s) && !strcmp(s.id, ids[i]) &&
             (s.state == SDFD_JOB_QUEUED || s.state == SDFD_JOB_RUNNING);
        free(text);
        if (!ok) {
            sdfd_store_unlock_job(store, ids[i], fd);
            continue;
        }
        s.state = SDFD_JOB_FAILED;
        s.error = SDFD_EUNAVAILABLE;
        snprintf(s.message, sizeof s.message, "interrupted: the sdfd running this %s stopped "
                 "(a restart or a crash) before it finished; %s again",
                 s.kind == SDFD_JOB_OPS ? "job" : "bake",
                 s.kind == SDFD_JOB_OPS ? "post the ops" : "bake");
        text = job_record(&s);
        if (text)
            sdfd_store_write_job(store, s.id, text);
        free(text);
        sdfd_store_unlock_job(store, s.id, fd);
        sdfd_volumes_add_finished(volumes, &s);
        sdfd_log("warn", "bake_interrupted", "job %s (%s, %s -> %s) was interrupted by a restart",
                 s.id, sdfd_job_kind_name(s.kind), s.kind == SDFD_JOB_OPS ? s.source : s.mesh,
                 s.volume);
    }
    free(ids);
}
