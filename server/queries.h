/* queries.h - the query handlers both front ends call: a point query on a mesh (through the
 * batcher) and a query of a baked volume (on a thread of its own).
 *
 * A front end decodes the request in its own wire form (http.c: JSON, npy or octets and URL
 * arguments; binrequests.c: a QUERY or VOLUME_QUERY frame), then calls `admit` (the lookups,
 * option checks and limits), gets room for the answer, and calls `submit` or `start`. Each
 * call returns 0 or an SDF_E* / SDFD_E* code with the message the client gets, so both
 * protocols refuse the same request with the same words. The answer comes back through the
 * `done` callback the front end set; a handler never calls a front end. */
#ifndef SDFD_QUERIES_H
#define SDFD_QUERIES_H

#include "server.h"

/* ---- mesh queries ---- */

typedef struct sdfd_query {
    /* in: names read during sdfd_query_admit only */
    const char *mesh_name;
    size_t mesh_name_len;
    const char *smoothing_name; /* filtered modes: a smoothing volume's mesh, or NULL */
    size_t smoothing_name_len;
    /* in: mode, sign, filter, points and count; before submitting also words, done, user.
     * out: from admission, job.mesh (and filter.smooth.mesh) hold references */
    sdfd_job job;
    sdf_mesh *smoothing; /* the smoothing mesh's reference, or NULL */
} sdfd_query;

/* Look up the mesh and the smoothing mesh (sdfd_cache_mesh: SDF_ENOTFOUND, or
 * SDFD_EUNAVAILABLE when the store cannot be read), and check a filtered query's
 * options and cost (sdfd_filter_validate). On failure nothing is held. */
int sdfd_query_admit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap);
/* Hand an admitted query with its words, done and user set to the batcher: 0 (done will be
 * called, and the points are counted in the metrics), or SDF_ENONFINITE, SDFD_EBUSY,
 * SDFD_EUNAVAILABLE and done is not called. The references stay held either way. */
int sdfd_query_submit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap);
/* Drop the references admission took (after done, or after a refusal). */
void sdfd_query_release(sdfd_query *q);

/* ---- volume queries ---- */

typedef struct sdfd_volume_query sdfd_volume_query;

struct sdfd_volume_query {
    /* in: the name is read during sdfd_volume_query_admit only */
    const char *volume_name;
    size_t volume_name_len;
    sdf_volume_filter interpolation;
    int gradient;                 /* 1: value and gradient (4 words a point), else 1 word */
    const float *points;
    size_t count;
    uint32_t *words;              /* set before starting */
    void (*done)(sdfd_volume_query *vq); /* on the worker thread */
    void *user;
    /* from admission until sdfd_volume_query_release */
    sdfd_stored_volume *stored;
    /* out, when done runs */
    int status;
    char message[256];
};

/* Look up the volume (sdfd_cache_volume): 0, SDF_ENOTFOUND or SDFD_EUNAVAILABLE. */
int sdfd_volume_query_admit(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap);
/* Evaluate on a new thread, which calls done: 0 (the points are counted in the metrics), or
 * SDFD_EUNAVAILABLE and done is not called. */
int sdfd_volume_query_start(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap);
void sdfd_volume_query_release(sdfd_volume_query *vq);

#endif
