/* queries.h - the query handlers both front ends call: a point query on a mesh (through the
 * batcher) and a query of a baked volume (on a thread of its own).
 *
 * A front end decodes the request in its own wire form (http.c: JSON, npy or octets and URL
 * arguments; binrequests.c: a QUERY or VOLUME_QUERY frame), gets room for the answer, makes
 * ready to be answered from another thread (HTTP suspends the connection, the binary front
 * end counts the request in flight), and calls `admit`: the lookups, option checks and
 * limits, then the work. It returns 0 or an SDF_E* / SDFD_E* code with the message the client
 * gets, so both protocols refuse the same request with the same words. The answer comes back
 * through the `done` callback the front end set; a handler never calls a front end.
 *
 * A lookup of a name not in memory loads it from the store on a loader thread (loader.h);
 * admission then returns 0 at once and goes on when the load ends, on the loader's thread:
 * a refusal found then (the name is missing after all, the store cannot be read, a filter's
 * cost) comes through `done` with `refused` set and the message admission would have given.
 * So no front end thread waits for a load. */
#ifndef SDFD_QUERIES_H
#define SDFD_QUERIES_H

#include "state/server.h"

/* The longest refusal message a front end sends (its message buffers' size). */
#define SDFD_QUERY_MESSAGE_MAX 300

/* ---- mesh queries ---- */

typedef struct sdfd_query {
    /* in: names read during the sdfd_query_admit call only */
    const char *mesh_name;
    size_t mesh_name_len;
    const char *smoothing_name; /* filtered modes: a smoothing volume's mesh, or NULL */
    size_t smoothing_name_len;
    /* in: mode, sign, filter, points, count, words, done and user.
     * out: from admission, job.mesh (and filter.smooth.mesh) hold references */
    sdfd_job job;
    sdf_mesh *smoothing; /* the smoothing mesh's reference, or NULL */
    /* out, when done reports a status: 1 if admission refused the query after a load (answer
     * `refusal` as a refusal is answered), 0 if the computation failed (job.message) */
    int refused;
    char refusal[SDFD_QUERY_MESSAGE_MAX];
    /* private */
    sdfd_server *srv;
    char mesh[SDFD_MAX_NAME + 1], smoothing_mesh[SDFD_MAX_NAME + 1];
    sdfd_lookup lookup;
} sdfd_query;

/* Admit a query with its words, done and user set, and hand it to the batcher. Admission
 * looks up the mesh and the smoothing mesh (sdfd_cache_lookup: SDF_ENOTFOUND, or
 * SDFD_EUNAVAILABLE when the store cannot be read), checks a filtered query's options and
 * cost (sdfd_filter_validate), and the batcher checks the points: SDF_ENONFINITE, SDFD_EBUSY,
 * SDFD_EUNAVAILABLE. Returns 0 and done will be called (the points are counted in the
 * metrics once submitted), or an error with msg, and done is not called. */
int sdfd_query_admit(sdfd_server *srv, sdfd_query *q, char *msg, size_t cap);
/* Drop the references admission took (after done, or after a refusal). */
void sdfd_query_release(sdfd_query *q);

/* ---- volume queries ---- */

typedef struct sdfd_volume_query sdfd_volume_query;

struct sdfd_volume_query {
    /* in: the name is read during the sdfd_volume_query_admit call only */
    const char *volume_name;
    size_t volume_name_len;
    sdf_volume_filter interpolation;
    int gradient;                 /* 1: value and gradient (4 words a point), else 1 word */
    const float *points;
    size_t count;
    uint32_t *words;
    void (*done)(sdfd_volume_query *vq); /* on the worker thread */
    void *user;
    /* from admission until sdfd_volume_query_release */
    sdfd_stored_volume *stored;
    /* out, when done runs: a status and its message; `refused` as for sdfd_query */
    int status;
    int refused;
    char message[SDFD_QUERY_MESSAGE_MAX];
    /* private */
    sdfd_server *srv;
    sdfd_lookup lookup;
};

/* Look up the volume (sdfd_cache_lookup: SDF_ENOTFOUND, SDFD_EUNAVAILABLE) and evaluate on a
 * new thread, which calls done: 0 (the points are counted in the metrics), or an error with
 * msg (SDFD_EUNAVAILABLE: no thread) and done is not called. */
int sdfd_volume_query_admit(sdfd_server *srv, sdfd_volume_query *vq, char *msg, size_t cap);
void sdfd_volume_query_release(sdfd_volume_query *vq);

#endif
