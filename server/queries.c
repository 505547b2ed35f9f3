/* queries.c - the query handlers (queries.h): one admission path for a query, whichever
 * protocol it came by. */
#include "queries.h"

#include <pthread.h>
#include <stdio.h>

#include "errors.h"

/* ---- mesh queries ------------------------------------------------------------------------ */

int sdfd_query_admit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap)
{
    sdfd_job *job = &q->job;
    q->smoothing = NULL;
    int rc = sdfd_cache_mesh(srv->cache, q->mesh_name, q->mesh_name_len, &job->mesh, msg, cap);
    if (rc)
        return rc;
    if (!sdf_proto_mode_filtered(job->mode))
        return 0;
    if (q->smoothing_name) {
        rc = sdfd_cache_mesh(srv->cache, q->smoothing_name, q->smoothing_name_len, &q->smoothing,
                             msg, cap);
        if (rc) {
            if (rc == SDF_ENOTFOUND)
                snprintf(msg, cap, "no smoothing mesh named '%.*s'", (int)q->smoothing_name_len,
                         q->smoothing_name);
            sdfd_query_release(q);
            return rc;
        }
        job->filter.smooth.mesh = q->smoothing;
    }
    rc = sdfd_filter_validate(job->mesh, &job->filter, job->count,
                                  SDFD_FILTER_QUERIES_PER_POINT_LIMIT * srv->cfg.max_points, msg,
                                  cap);
    if (rc)
        sdfd_query_release(q);
    return rc;
}

int sdfd_query_submit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap)
{
    size_t bad = 0;
    int rc = sdfd_batcher_submit(srv->batcher, &q->job, &bad);
    if (rc == SDF_ENONFINITE)
        snprintf(msg, cap, SDFD_BAD_POINT_MESSAGE, bad);
    else if (rc == SDFD_EBUSY)
        snprintf(msg, cap, "more than %zu points are waiting; retry later",
                 srv->cfg.max_queued_points);
    else if (rc)
        snprintf(msg, cap, "%s", sdfd_strerror(rc));
    else
        sdfd_metrics_points(srv->metrics, q->job.count);
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

int sdfd_volume_query_admit(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap)
{
    int rc = sdfd_cache_volume(srv->cache, vq->volume_name, vq->volume_name_len, &vq->stored,
                               msg, cap);
    if (rc || vq->interpolation != SDF_VOLUME_HERMITE)
        return rc;
    sdf_volume_info info;
    sdf_volume_get_info(vq->stored->volume, &info);
    if (info.order == 1)
        return 0;
    snprintf(msg, cap, "interpolation 'hermite' needs a first-order volume; '%s' is zero order "
             "(trilinear or nearest)", vq->stored->name);
    sdfd_volume_release(vq->stored);
    vq->stored = NULL;
    return SDF_EINVAL;
}

static void *evaluate(void *arg)
{
    sdfd_volume_query *vq = arg;
    size_t bad = 0;
    vq->status = sdfd_volume_eval_words(vq->stored->volume, vq->points, vq->count,
                                        vq->interpolation, vq->gradient, vq->words, &bad);
    if (vq->status == SDF_ENONFINITE)
        snprintf(vq->message, sizeof vq->message, "point %zu has a NaN or infinite coordinate",
                 bad);
    else
        snprintf(vq->message, sizeof vq->message, "%s",
                 vq->status ? sdfd_strerror(vq->status) : "");
    vq->done(vq);
    return NULL;
}

int sdfd_volume_query_start(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap)
{
    pthread_t thread;
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
    size_t count = vq->count; /* vq may be gone once the thread has started */
    int failed = pthread_create(&thread, &attr, evaluate, vq);
    pthread_attr_destroy(&attr);
    if (failed) {
        snprintf(msg, cap, "cannot start a worker thread");
        return SDFD_EUNAVAILABLE;
    }
    sdfd_metrics_points(srv->metrics, count);
    return 0;
}

void sdfd_volume_query_release(sdfd_volume_query *vq)
{
    sdfd_volume_release(vq->stored);
    vq->stored = NULL;
}
