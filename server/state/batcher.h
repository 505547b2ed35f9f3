/* batcher.h - request coalescing, the heart of sdfd.
 *
 * Every query, HTTP or binary, becomes a job submitted here. One dispatcher thread takes
 * the oldest job, waits up to the batch window (or until enough points wait) for more jobs
 * with the same mesh, mode, sign (and filter parameters), and runs them all as ONE library
 * batch (sdf_query, or sdf_query_filtered for the filtered modes, with
 * the configured worker threads), so points from many small requests are traversed
 * together. Batches of up to the coalescing cap share one sdf_workspace, so the library's
 * scratch is not allocated and faulted in afresh for each. Results are written into each
 * job's own `words` buffer in the wire layout (PROTOCOL.md: W 32-bit words per point), then
 * each job's `done` callback runs on the dispatcher thread. Under load the queue fills while
 * a batch computes, so batches grow without any waiting; the window only matters when the
 * server is idle.
 *
 * Points are checked (finite) at submission, and a shared batch that fails all the same (a
 * filtered kernel that displaces one request's samples out of range, memory for the whole
 * batch) is run again request by request, so each gets its own answer and one request's
 * trouble never fails another's. */
#ifndef SDFD_BATCHER_H
#define SDFD_BATCHER_H

#include <stddef.h>
#include <stdint.h>

#include "core/metrics.h"
#include "proto.h"
#include "sdf/sdf.h"

typedef struct sdfd_job sdfd_job;

/* Which jobs may share a batch: equal keys (byte for byte) and only those. Sized for the
 * mesh, mode, sign and every scalar of the filter options (batcher.c checks it). */
typedef struct sdfd_batch_key {
    unsigned char bytes[sizeof(void *) + 2 * sizeof(int) + sizeof(sdf_filter_options)];
} sdfd_batch_key;

struct sdfd_job {
    /* in: set by the submitter; the job and its buffers must stay alive until `done` */
    sdf_mesh *mesh;          /* a reference the job holds; the batcher does not release it */
    sdf_proto_mode mode;
    sdf_sign_method sign;
    sdf_filter_options filter; /* filtered modes: checked with sdfd_filter_validate first */
    const float *points;     /* 3 * count */
    size_t count;
    uint32_t *words;         /* out: count * sdf_proto_words(mode) words */
    void (*done)(sdfd_job *job);
    void *user;
    /* out */
    int status;              /* 0 or an SDF_E* code */
    char message[256];       /* with a status: what went wrong, for the client (the size
                                of sdf_diag's message) */
    /* private */
    sdfd_batch_key key;      /* set at submission */
    sdfd_job *next;
    double enqueued;
};

typedef struct sdfd_batcher sdfd_batcher;

/* `max_queued` bounds the points waiting: a job arriving while more wait is refused
 * (SDFD_EBUSY, HTTP 429), so overload sheds requests instead of growing memory and latency. */
int sdfd_batcher_create(int threads, unsigned window_us, size_t max_points, size_t max_queued,
                        sdfd_metrics *metrics, sdfd_batcher **out);
/* Finish every queued job, then stop the thread and free. */
void sdfd_batcher_destroy(sdfd_batcher *b);

/* Queue a job. Returns 0 (done will be called), or an error and done is NOT called:
 * SDF_ENONFINITE (*bad_index set: NaN, Inf or beyond SDF_MAX_COORDINATE), SDFD_EBUSY (queue
 * full), SDFD_EUNAVAILABLE (shutting down). */
int sdfd_batcher_submit(sdfd_batcher *b, sdfd_job *job, size_t *bad_index);

/* The key of a job as submitted: every parameter that shapes its answer (mesh, mode, sign,
 * and the filter's fields in the filtered modes), with the spellings of one answer made
 * one. Exposed for tests/server/test_batcher.c. */
void sdfd_batch_key_of(const sdfd_job *job, sdfd_batch_key *key);

/* Bytes the batcher keeps between batches: its gathered points and answers (as large as the
 * largest batch) and the library's workspace (batches up to max_points). Any thread. */
size_t sdfd_batcher_kept_bytes(sdfd_batcher *b);

/* What both protocols tell a client whose point *bad_index was refused (printf, %zu). */
#define SDFD_BAD_POINT_MESSAGE "point %zu has a coordinate that is NaN, Inf or beyond +-1e18"

/* Check a filtered query of `count` points before submitting it, so one bad request never
 * fails a batch: its parameters (SDF_EINVAL with the library's message in `msg`) and its cost,
 * at most `max_queries` distance queries (SDF_ELIMIT), so one request cannot hold the batcher
 * for minutes. */
int sdfd_filter_validate(const sdf_mesh *mesh, const sdf_filter_options *f, size_t count,
                         size_t max_queries, char *msg, size_t cap);

/* The filtered-query cost limit for a server whose requests hold at most max_points points. */
#define SDFD_FILTER_QUERIES_PER_POINT_LIMIT 16

/* Seconds on a monotonic clock. */
double sdfd_now(void);

#endif
