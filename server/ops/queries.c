/* queries.c - the query handlers (queries.h): one admission path for a query, whichever
 * protocol it came by, which goes on from a loader's thread when a lookup waits for a load
 * (through the lookup's done callback), so the front end's thread never does. */
#include "ops/queries.h"

#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "core/errors.h"

/* A lookup's message into a front end's buffer, cut to cap as snprintf would. */
static void copy_message(char *dst, size_t cap, const char *src)
{
    size_t n = cap ? strnlen(src, cap - 1) : 0;
    if (cap) {
        memcpy(dst, src, n);
        dst[n] = '\0';
    }
}

/* ---- mesh queries ------------------------------------------------------------------------ */

static void mesh_resumed(sdfd_lookup *l);

/* Admission is a walk through these steps, from the front end's thread or, after a load,
 * from the loader's; each returns 0, SDFD_LOOKUP_PENDING (q may be gone: touch it no more),
 * or an error with msg. */

static int needs_smoothing(const sdfd_query *q)
{
    return sdf_proto_mode_filtered(q->job.mode) && q->smoothing_mesh[0];
}

/* A lookup's answer into its place: the mesh, then the smoothing mesh. */
static int take(sdfd_query *q, int rc, char *msg, size_t cap)
{
    sdfd_lookup *l = &q->lookup;
    int smoothing = q->job.mesh != NULL;
    if (rc == SDF_ENOTFOUND && smoothing)
        snprintf(msg, cap, "no smoothing mesh named '%s'", q->smoothing_mesh);
    else if (rc)
        copy_message(msg, cap, l->message);
    else if (smoothing)
        q->job.filter.smooth.mesh = q->smoothing = l->item;
    else
        q->job.mesh = l->item;
    return rc;
}

static int advance(sdfd_query *q, char *msg, size_t cap)
{
    sdfd_server *srv = q->srv;
    sdfd_job *job = &q->job;
    int rc;
    while (!job->mesh || (needs_smoothing(q) && !q->smoothing)) {
        sdfd_lookup *l = &q->lookup;
        *l = (sdfd_lookup){.kind = SDFD_ITEM_MESH, .done = mesh_resumed, .user = q};
        snprintf(l->name, sizeof l->name, "%s", job->mesh ? q->smoothing_mesh : q->mesh);
        if ((rc = sdfd_cache_lookup(srv->cache, l)) == SDFD_LOOKUP_PENDING ||
            (rc = take(q, rc, msg, cap)))
            return rc;
    }
    if (sdf_proto_mode_filtered(job->mode) &&
        (rc = sdfd_filter_validate(job->mesh, &job->filter, job->count,
                                   SDFD_FILTER_QUERIES_PER_POINT_LIMIT * srv->cfg.max_points,
                                   msg, cap)))
        return rc;
    size_t bad = 0, count = job->count; /* q may be gone once submitted */
    rc = sdfd_batcher_submit(srv->batcher, job, &bad);
    if (rc == SDF_ENONFINITE)
        snprintf(msg, cap, SDFD_BAD_POINT_MESSAGE, bad);
    else if (rc == SDFD_EBUSY)
        snprintf(msg, cap, "more than %zu points are waiting; retry later",
                 srv->cfg.max_queued_points);
    else if (rc)
        snprintf(msg, cap, "%s", sdfd_strerror(rc));
    else
        sdfd_metrics_points(srv->metrics, count);
    return rc;
}

/* A load q waited for has ended (on the loader's thread): go on, or answer the refusal. */
static void mesh_resumed(sdfd_lookup *l)
{
    sdfd_query *q = l->user;
    char msg[SDFD_QUERY_MESSAGE_MAX];
    int rc = take(q, l->status, msg, sizeof msg);
    if (!rc)
        rc = advance(q, msg, sizeof msg);
    if (!rc || rc == SDFD_LOOKUP_PENDING)
        return;
    sdfd_query_release(q);
    q->job.status = rc;
    q->refused = 1;
    snprintf(q->refusal, sizeof q->refusal, "%s", msg);
    q->job.done(&q->job);
}

int sdfd_query_admit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap)
{
    q->srv = srv;
    q->job.mesh = q->smoothing = NULL;
    q->refused = 0;
    snprintf(q->mesh, sizeof q->mesh, "%.*s", (int)q->mesh_name_len, q->mesh_name);
    snprintf(q->smoothing_mesh, sizeof q->smoothing_mesh, "%.*s",
             q->smoothing_name ? (int)q->smoothing_name_len : 0,
             q->smoothing_name ? q->smoothing_name : "");
    int rc = advance(q, msg, cap);
    if (rc == SDFD_LOOKUP_PENDING)
        return 0;
    if (rc)
        sdfd_query_release(q);
    return rc;
}

void sdfd_query_release(sdfd_query *q)
{
    sdf_mesh_release(q->job.mesh);
    sdf_mesh_release(q->smoothing);
    q->job.mesh = q->smoothing = NULL;
}

/* ---- volume queries: arithmetic, not the batcher's geometry, but too slow for a front
 * end's I/O threads ------------------------------------------------------------------------- */

static void evaluate(void *arg)
{
    sdfd_volume_query *vq = arg;
    size_t bad = 0;
    vq->status = sdfd_volume_eval_words(vq->stored->volume, vq->points, vq->count,
                                        vq->interpolation, vq->gradient, vq->words, &bad);
    if (vq->status == SDF_ENONFINITE)
        snprintf(vq->message, sizeof vq->message, SDFD_BAD_POINT_MESSAGE, bad);
    else
        snprintf(vq->message, sizeof vq->message, "%s",
                 vq->status ? sdfd_strerror(vq->status) : "");
    vq->done(vq);
}

/* Evaluate on a worker thread, which calls done; hermite is refused on a zero-order volume. */
static int start(sdfd_volume_query *vq, char *msg, size_t cap)
{
    sdf_volume_info info;
    sdf_volume_get_info(vq->stored->volume, &info);
    if (vq->interpolation == SDF_VOLUME_HERMITE && info.order != 1) {
        snprintf(msg, cap, "interpolation 'hermite' needs a first-order volume; '%.128s' is zero "
                 "order (trilinear or nearest)", vq->stored->name);
        return SDF_EINVAL;
    }
    sdfd_server *srv = vq->srv;
    size_t count = vq->count; /* vq may be gone once the task has started */
    if (sdfd_workers_run(srv->workers, evaluate, vq)) {
        snprintf(msg, cap, "cannot start a worker thread");
        return SDFD_EUNAVAILABLE;
    }
    sdfd_metrics_points(srv->metrics, count);
    return 0;
}

/* The load vq waited for has ended (on the loader's thread). */
static void volume_resumed(sdfd_lookup *l)
{
    sdfd_volume_query *vq = l->user;
    vq->stored = l->item;
    int rc = l->status;
    if (rc)
        copy_message(vq->message, sizeof vq->message, l->message);
    else
        rc = start(vq, vq->message, sizeof vq->message);
    if (!rc)
        return;
    sdfd_volume_query_release(vq);
    vq->status = rc;
    vq->refused = 1;
    vq->done(vq);
}

int sdfd_volume_query_admit(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap)
{
    sdfd_lookup *l = &vq->lookup;
    vq->srv = srv;
    vq->stored = NULL;
    vq->refused = 0;
    *l = (sdfd_lookup){.kind = SDFD_ITEM_VOLUME, .done = volume_resumed, .user = vq};
    snprintf(l->name, sizeof l->name, "%.*s", (int)vq->volume_name_len, vq->volume_name);
    int rc = sdfd_cache_lookup(srv->cache, l);
    if (rc == SDFD_LOOKUP_PENDING)
        return 0;
    if (rc) {
        copy_message(msg, cap, l->message);
        return rc;
    }
    vq->stored = l->item;
    if ((rc = start(vq, msg, cap)))
        sdfd_volume_query_release(vq);
    return rc;
}

void sdfd_volume_query_release(sdfd_volume_query *vq)
{
    sdfd_volume_release(vq->stored);
    vq->stored = NULL;
}
