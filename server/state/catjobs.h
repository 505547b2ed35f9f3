/* catjobs.h - jobs (bakes, field operations) as rows of the catalog (table sdfd_jobs), so
 * that every replica lists the same jobs and any replica can run a queued one.
 *
 * A row holds the job's status (volumes.h's sdfd_job_status), the request that started it
 * (the POST body and the name in its path, enough to start it again anywhere), and who runs
 * it: owner (a replica id), attempts, and a lease. A replica claims the oldest queued row
 * (FOR UPDATE SKIP LOCKED: concurrent claimers never take the same row) and renews its lease
 * while it runs it, writing its progress; a row whose lease ran out (its replica stopped) is
 * queued again once, and after a second loss fails with "owner replica lost". Every change
 * of a running row names its owner and attempt, so a replica that lost its lease can never
 * overwrite what the next attempt wrote. Errors are sdfd's codes with err set. */
#ifndef SDFD_CATJOBS_H
#define SDFD_CATJOBS_H

#include <stddef.h>

#include "state/catalog.h"
#include "state/volumes.h"

/* A claimed job: its status, the name in its path and its request (malloc'd, free it). */
typedef struct sdfd_catjob {
    sdfd_job_status status;
    char target[SDFD_MAX_NAME + 1];
    char *request;
    size_t request_len;
} sdfd_catjob;

/* Insert s (id, kind, mesh, source, volume, has_ops) queued, with its request. SDFD_EBUSY
 * when max_jobs jobs are unfinished already; the oldest finished beyond max_jobs are
 * forgotten. */
int sdfd_catjobs_insert(sdfd_catalog *c, const sdfd_job_status *s, const char *target,
                        const void *request, size_t len, size_t max_jobs, char *err, size_t cap);
/* A job's status: 0 or SDF_ENOTFOUND. */
int sdfd_catjobs_get(sdfd_catalog *c, const char *id, sdfd_job_status *out, char *err,
                     size_t cap);
/* The newest `limit` jobs, newest first (*out malloc'd). */
int sdfd_catjobs_list(sdfd_catalog *c, size_t limit, sdfd_job_status **out, size_t *n,
                      char *err, size_t cap);
/* Claim the oldest queued job for `owner` for lease_seconds: 0 with *out, or SDF_ENOTFOUND
 * when none is queued. */
int sdfd_catjobs_claim(sdfd_catalog *c, const char *owner, double lease_seconds,
                       sdfd_catjob *out, char *err, size_t cap);
/* Renew the lease of the running job s (s->owner, s->attempts its claim's) and record its
 * progress; *cancel says a cancel was asked for. SDF_ENOTFOUND: the job is no longer this
 * claim's (its lease ran out, another attempt has it): stop running it. */
int sdfd_catjobs_renew(sdfd_catalog *c, const sdfd_job_status *s, double lease_seconds,
                       int *cancel, char *err, size_t cap);
/* Record the end (s->state done, failed or canceled, with its error and caveats) of the
 * claim s->owner, s->attempts; SDF_ENOTFOUND as for renew. */
int sdfd_catjobs_end(sdfd_catalog *c, const sdfd_job_status *s, char *err, size_t cap);
/* DELETE /v1/jobs/ID: a queued job ends canceled, a running one is asked to cancel (its
 * owner ends it at its next renewal), a finished one is forgotten; *out is its status then.
 * SDF_ENOTFOUND for an unknown id. */
int sdfd_catjobs_cancel(sdfd_catalog *c, const char *id, sdfd_job_status *out, char *err,
                        size_t cap);
/* Jobs whose lease ran out: queued again after a first loss, failed after a second (canceled
 * when a cancel was asked for); *requeued and *failed count them. */
int sdfd_catjobs_expire(sdfd_catalog *c, size_t *requeued, size_t *failed, char *err,
                        size_t cap);

#endif
