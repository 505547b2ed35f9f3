/* volumes.h - the volumes sdfd has baked, by name, and the jobs that make them: bakes (of a
 * mesh, optionally followed by field operations) and field-operation jobs (of a volume).
 *
 * A stored volume is reference-counted like a mesh: a query or download holding it keeps it
 * alive through a DELETE or a replacing bake. Limits: number of volumes and their total
 * bytes (a bake that would not fit is refused before it starts).
 *
 * A job runs on its own thread; at most `max_running` jobs (bakes and field operations
 * alike) run at once (each uses the configured geometry threads), the rest wait queued and
 * start in arrival order. Progress and cancellation go through the progress callbacks of
 * sdf_volume_bake and sdf_volume_apply_ops. Finished jobs stay listed (their state and
 * error) until `max_jobs` newer ones push the oldest finished out. This module holds what is
 * in memory; with a store (cache.h) its hooks keep a finished job's volume there before the
 * job says done, and record every job, so a restart sees both. Thread-safe. */
#ifndef SDFD_VOLUMES_H
#define SDFD_VOLUMES_H

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"
#include "state/registry.h" /* SDFD_MAX_NAME */

typedef struct sdfd_volumes sdfd_volumes;

typedef struct sdfd_stored_volume {
    atomic_int refs;
    sdf_volume *volume;
    char name[SDFD_MAX_NAME + 1];
    char mesh[SDFD_MAX_NAME + 1]; /* the mesh it was baked from (an ops job: its source's) */
    char job[24];                 /* the job that made it */
    double bake_seconds;
} sdfd_stored_volume;

/* max_queries: the distance queries one bake may cost (--max-bake-queries). */
sdfd_volumes *sdfd_volumes_create(size_t max_volumes, size_t max_bytes, int max_running,
                                  size_t max_jobs, size_t max_queries, int threads);
/* Refuse new bakes and cancel every job (graceful shutdown, step 1); does not wait. */
void sdfd_volumes_close(sdfd_volumes *v);
/* Cancel every job, wait for their threads, release every volume. NULL is a no-op. */
void sdfd_volumes_destroy(sdfd_volumes *v);

/* ---- stored volumes ---- */

/* The volume called `name`, retained (release it), or NULL. */
sdfd_stored_volume *sdfd_volumes_get(sdfd_volumes *v, const char *name);
void sdfd_volume_retain(sdfd_stored_volume *s);
void sdfd_volume_release(sdfd_stored_volume *s); /* NULL is a no-op */
int sdfd_volumes_remove(sdfd_volumes *v, const char *name); /* 0 or SDF_ENOTFOUND */
/* Store `volume` (taken over, also on failure) as `name`, replacing any volume of that name;
 * *replaced says which. SDF_ELIMIT when --max-volumes or --max-volume-bytes would be broken. */
int sdfd_volumes_put(sdfd_volumes *v, const char *name, sdf_volume *volume, const char *mesh,
                     int *replaced);
/* As sdfd_volumes_put, of a stored volume made elsewhere (a reference taken over). */
int sdfd_volumes_put_stored(sdfd_volumes *v, sdfd_stored_volume *s, int *replaced);
/* Snapshot sorted by name, each retained; release with sdfd_volumes_free_list. */
size_t sdfd_volumes_list(sdfd_volumes *v, sdfd_stored_volume ***out);
void sdfd_volumes_free_list(sdfd_stored_volume **list, size_t n);
size_t sdfd_volumes_count(sdfd_volumes *v);
/* Bytes of the stored volumes, and how many bakes run and wait. */
void sdfd_volumes_usage(sdfd_volumes *v, size_t *bytes, size_t *running, size_t *queued);
/* How many field-operation jobs run and wait. */
void sdfd_volumes_ops_usage(sdfd_volumes *v, size_t *running, size_t *queued);

/* Evaluate `v` at `count` points into the wire layout (PROTOCOL.md): per point the value, and
 * with `gradient` its gradient x, y, z (W = 4). 0, SDF_ENONFINITE (*bad_index set) or
 * SDF_ENOMEM. */
int sdfd_volume_eval_words(const sdf_volume *v, const float *points, size_t count,
                           sdf_volume_filter interpolation, int gradient, uint32_t *words,
                           size_t *bad_index);

/* ---- bake jobs ---- */

typedef enum sdfd_job_state {
    SDFD_JOB_QUEUED, SDFD_JOB_RUNNING, SDFD_JOB_DONE, SDFD_JOB_FAILED, SDFD_JOB_CANCELED
} sdfd_job_state;

const char *sdfd_job_state_name(sdfd_job_state s); /* "queued", "running", ... */

typedef enum sdfd_job_kind { SDFD_JOB_BAKE, SDFD_JOB_OPS } sdfd_job_kind;

const char *sdfd_job_kind_name(sdfd_job_kind k); /* "bake", "ops" */
/* "bake" / "ops" -> kind: 0, or SDF_EINVAL. */
int sdfd_job_kind_from_name(const char *name, sdfd_job_kind *out);

typedef struct sdfd_job_status {
    char id[24];
    sdfd_job_kind kind;
    sdfd_job_state state;
    double progress;              /* 0..1 */
    char mesh[SDFD_MAX_NAME + 1]; /* a bake's mesh; an ops job: its source's ("" if none) */
    char source[SDFD_MAX_NAME + 1]; /* an ops job: the volume it reads */
    char volume[SDFD_MAX_NAME + 1];
    int has_ops;                  /* it applies field operations (an ops job, a bake with ops) */
    unsigned caveats;             /* DONE with ops: the SDF_FIELD_CAVEAT_* bits that fired */
    char warning[256];            /* ... and the first one's message */
    double seconds;               /* queued + running so far, or in all when finished */
    int error;                    /* FAILED: the SDF_E* code */
    char message[256];            /* FAILED: why */
    int cancel_requested;         /* QUEUED or RUNNING, canceled: it ends at its next step */
    char owner[64];               /* the replica running or last running it ("" none yet) */
    int attempts;                 /* times a replica started it */
} sdfd_job_status;

/* Field operations to apply (sdf_volume_apply_ops): count 0 = none. */
typedef struct sdfd_ops_request {
    sdf_field_op ops[SDF_FIELD_MAX_OPS];
    size_t count;
    sdf_field_options options;    /* progress, user and threads are set by the job */
} sdfd_ops_request;

/* The bytes an ops job holds while it runs for a zero-order volume of `nodes` nodes: its
 * result (4 a node) and the library's scratch (sdf.h: 9 a node, 4 more for SUSSMAN, 4 more
 * when an op offsets, which every op but REDISTANCE does). */
size_t sdfd_ops_bytes(size_t nodes, const sdfd_ops_request *req);

/* A bake request: what sdf_volume_bake needs, with the filter (and its smoothing mesh)
 * owned by the job, and the field operations applied to the baked grid before it is kept. */
typedef struct sdfd_bake_request {
    sdf_bake_options options;     /* progress, user, filter and query.threads are set here */
    int filtered;
    sdf_filter_options filter;
    sdf_mesh *smoothing_mesh;     /* retained reference handed over, or NULL */
    int mesh_box;                 /* "margin": 0 with no bounds: the mesh's own box (the
                                     library reads a zero margin as its default) */
    sdfd_ops_request ops;         /* count 0: none; else order 0 float32 only */
    char surface[SDFD_MAX_NAME + 1]; /* "mesh": the mesh its surface is stored as, or "" */
} sdfd_bake_request;

/* Start a job baking `mesh` (a retained reference handed over, like req->smoothing_mesh,
 * released when the job ends) into the volume `volume_name`. id: on input empty, or the id
 * the job must take (a shared job's, catjobs.h); on 0, the job's id.
 * Every admission rule is here: SDF_EINVAL for options the library refuses (its message)
 * and for ops on a bake that is not order 0 float32, SDF_ELIMIT when the bake would cost
 * more distance queries than max_queries or break the byte limit (the volume, plus the more
 * of the bake's working memory and its ops' result and scratch), SDFD_EBUSY when max_jobs
 * are still unfinished, SDFD_EUNAVAILABLE when shutting down; on failure the references are
 * released and `err` says why. */
int sdfd_volumes_bake(sdfd_volumes *v, sdf_mesh *mesh, const char *mesh_name,
                      const char *volume_name, sdfd_bake_request *req, char id[24], char *err,
                      size_t err_cap);

/* Start a job applying req's field operations to `source` (a retained reference handed
 * over, released when the job ends) into the volume `volume_name`; id as for bakes.
 * Admission as for bakes:
 * SDF_EINVAL when the library refuses the source (first order, packed; its message),
 * SDF_ELIMIT (the result plus the scratch, sdfd_ops_bytes, over the byte limit),
 * SDFD_EBUSY, SDFD_EUNAVAILABLE; on failure the reference is released. Values of the ops
 * (an r the library refuses) fail the job with the library's message. */
int sdfd_volumes_ops(sdfd_volumes *v, sdfd_stored_volume *source, const char *volume_name,
                     const sdfd_ops_request *req, char id[24], char *err, size_t err_cap);

/* A new job id: "PREFIX-N", PREFIX random for this process. */
void sdfd_volumes_new_id(sdfd_volumes *v, char id[24]);

/* The checks of the request alone that sdfd_volumes_bake and sdfd_volumes_ops make (the
 * library's, the query limit, ops on the right kind of grid, the byte limit for the job by
 * itself), without starting anything or taking any reference: 0, or the code and err a start
 * would give. For a job that another replica may run (catjobs.h). */
int sdfd_volumes_check_bake(sdfd_volumes *v, const sdf_mesh *mesh, const sdfd_bake_request *req,
                            char *err, size_t err_cap);
int sdfd_volumes_check_ops(sdfd_volumes *v, const sdfd_stored_volume *source,
                           const sdfd_ops_request *req, char *err, size_t err_cap);

/* What a server with a store (--data-dir) does besides: keep a finished bake's volume
 * before its job says done, and record jobs so a restart can tell what it interrupted.
 * Called outside the lock; any member may be NULL. */
typedef struct sdfd_volumes_hooks {
    void *user;
    /* A job finished: keep `s` (0), or refuse (err set: the job fails with it). */
    int (*keep)(void *user, const sdfd_stored_volume *s, char *err, size_t cap);
    /* After each keep that returned 0, at once (before a surface is extracted): the volume
     * is listed in memory (rc 0) or is not (over the limits). */
    void (*listed)(void *user, const char *name, int rc);
    /* A job was accepted (before it can start); returns a token handed to ended. */
    int (*started)(void *user, const sdfd_job_status *s);
    /* A job reached done, failed or canceled. */
    void (*ended)(void *user, const sdfd_job_status *s, int token);
    /* A finished job was forgotten (DELETE, or pushed out by newer ones). */
    void (*forgotten)(void *user, const char *id);
} sdfd_volumes_hooks;

/* Set once, before the first bake. */
void sdfd_volumes_set_hooks(sdfd_volumes *v, const sdfd_volumes_hooks *hooks);

/* Where a bake whose request names a mesh (its `surface`) puts the finished volume's surface,
 * after the volume is kept: the cache, which stores it as that mesh. 0, or an error that fails
 * the job (err set; the volume stays). Set once, before the first bake. */
typedef int (*sdfd_surface_sink)(void *user, const char *mesh, const sdf_volume *volume,
                                 int threads, char *err, size_t cap);
void sdfd_volumes_set_surface_sink(sdfd_volumes *v, sdfd_surface_sink sink, void *user);
/* List a finished job this process did not run (one a restart interrupted); 0, or
 * SDFD_EBUSY when max_jobs are unfinished. */
int sdfd_volumes_add_finished(sdfd_volumes *v, const sdfd_job_status *s);

/* A job's status; SDF_ENOTFOUND for an unknown id. */
int sdfd_volumes_job(sdfd_volumes *v, const char *id, sdfd_job_status *out);
/* Cancel a queued or running job (it ends CANCELED at its next progress report), or forget
 * a finished one; *out is the status after the call. SDF_ENOTFOUND for an unknown id. */
int sdfd_volumes_cancel(sdfd_volumes *v, const char *id, sdfd_job_status *out);
/* Every job's status, newest first (malloc'd; free it). */
size_t sdfd_volumes_jobs(sdfd_volumes *v, sdfd_job_status **out);

#endif
