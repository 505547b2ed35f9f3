/* jobrunner.h - this replica's part in the jobs the replicas share through the catalog
 * (catjobs.h). One thread, which every SDFD_JOBRUNNER_TICK seconds (and at once when poked):
 * - re-queues or fails the jobs of replicas that stopped renewing their leases;
 * - renews the leases of the jobs this replica runs (SDFD_JOB_LEASE_SECONDS each), writing
 *   their progress, and cancels one when a cancel was asked for or its lease was lost;
 * - claims queued jobs while fewer than max_running of its own run, and starts each through
 *   `start`, the operations layer, which reads its request again.
 * It also takes the volumes' hooks: a job's volume is kept through the cache before the job
 * says done, and its end is written to its row (retried each tick while PostgreSQL is away).
 * And it sweeps the catalog's blobs that no item has referred to for `grace` seconds, every
 * grace / 2 seconds (at least 1, at most SDFD_JOBRUNNER_SWEEP_MAX): any replica may, safely
 * beside every writer (catalog.h). Thread-safe. */
#ifndef SDFD_JOBRUNNER_H
#define SDFD_JOBRUNNER_H

#include "state/cache.h"
#include "state/catjobs.h"
#include "state/volumes.h"

#define SDFD_JOB_LEASE_SECONDS 10.0
#define SDFD_JOBRUNNER_TICK 1.0
#define SDFD_JOBRUNNER_SWEEP_MAX 300.0

typedef struct sdfd_jobrunner sdfd_jobrunner;

/* Start a claimed job locally under its id (sdfd_volumes_bake or _ops): 0, or an error
 * with err (the job fails with it). Runs on the runner's thread. */
typedef int (*sdfd_jobrunner_start_fn)(void *user, const sdfd_catjob *job, char *err,
                                       size_t cap);


/* The runner of replica `owner` over catalog c (both the caller's, kept while it runs);
 * installs the volumes' hooks (so call it before the first job). NULL if its thread cannot
 * start. */
sdfd_jobrunner *sdfd_jobrunner_create(sdfd_catalog *c, sdfd_cache *cache, sdfd_volumes *v,
                                      const char *owner, unsigned max_running, double grace,
                                      sdfd_jobrunner_start_fn start, void *user);
/* Shutdown: stop the thread before the volumes cancel their jobs, so that no row says
 * canceled for a job nobody canceled: the claims still held lapse with their leases and
 * another replica runs those jobs again. Ends reported after it are not written. */
void sdfd_jobrunner_stop(sdfd_jobrunner *r);
/* Free (after the volumes are destroyed: their hooks call it); stops first. NULL is a no-op. */
void sdfd_jobrunner_destroy(sdfd_jobrunner *r);
/* A job was queued here: look for work now rather than at the next tick. */
void sdfd_jobrunner_poke(sdfd_jobrunner *r);
sdfd_catalog *sdfd_jobrunner_catalog(sdfd_jobrunner *r);
const char *sdfd_jobrunner_owner(const sdfd_jobrunner *r);
/* What it claimed, and re-queued or failed as lost (expiry). */
void sdfd_jobrunner_counts_get(sdfd_jobrunner *r, sdfd_catalog_job_counts *out);

#endif
