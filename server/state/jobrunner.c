/* jobrunner.c - claiming, leasing and ending shared jobs (jobrunner.h). The runner keeps the
 * claims it holds (id and attempt) and the ends it could not write yet; the volumes run the
 * jobs themselves, under the rows' ids. */
#include "state/jobrunner.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/batcher.h" /* sdfd_now */

#define MAX_CLAIMS 64 /* --max-bakes is at most 64 */

typedef struct claim {
    sdfd_job_status status; /* id, owner, attempts of the claim; the end once it ended */
    int ended;              /* the end is to be written */
} claim;

struct sdfd_jobrunner {
    sdfd_catalog *cat;
    sdfd_cache *cache;
    sdfd_volumes *volumes;
    char owner[64];
    unsigned max_running;
    double grace, next_sweep; /* blobs: their grace; when to sweep next */
    sdfd_jobrunner_start_fn start;
    void *user;
    pthread_mutex_t lock; /* guards what follows */
    pthread_cond_t wake;
    claim claims[MAX_CLAIMS];
    size_t nclaims;
    int stopping, poked;
    sdfd_catalog_job_counts counts;
    pthread_t thread;
};

/* ---- the volumes' hooks ----------------------------------------------------------------- */

static int keep(void *user, const sdfd_stored_volume *s, char *err, size_t cap)
{
    return sdfd_cache_keep_baked(((sdfd_jobrunner *)user)->cache, s, err, cap);
}

static void listed(void *user, const char *name, int rc)
{
    sdfd_cache_baked_listed(((sdfd_jobrunner *)user)->cache, name, rc);
}

/* A job this replica ran ended: its end goes to its row at the next tick (now, poked). */
static void ended(void *user, const sdfd_job_status *s, int token)
{
    sdfd_jobrunner *r = user;
    (void)token;
    pthread_mutex_lock(&r->lock);
    for (size_t i = 0; i < r->nclaims; i++) {
        claim *c = &r->claims[i];
        if (!strcmp(c->status.id, s->id)) {
            char owner[64];
            int attempts = c->status.attempts;
            memcpy(owner, c->status.owner, sizeof owner);
            c->status = *s;
            memcpy(c->status.owner, owner, sizeof owner);
            c->status.attempts = attempts, c->ended = 1;
        }
    }
    r->poked = 1;
    pthread_cond_signal(&r->wake);
    pthread_mutex_unlock(&r->lock);
}

/* ---- one tick --------------------------------------------------------------------------- */

/* Under the lock: forget claim i. */
static void drop(sdfd_jobrunner *r, size_t i)
{
    r->claims[i] = r->claims[--r->nclaims];
}

/* Write the ends, renew the rest (the lock held, released around each call). */
static void tend_claims(sdfd_jobrunner *r)
{
    for (size_t i = 0; i < r->nclaims;) {
        claim c = r->claims[i];
        char err[512];
        int rc, cancel = 0;
        pthread_mutex_unlock(&r->lock);
        if (c.ended) {
            rc = sdfd_catjobs_end(r->cat, &c.status, err, sizeof err);
        } else {
            sdfd_job_status now;
            if (!sdfd_volumes_job(r->volumes, c.status.id, &now))
                c.status.progress = now.progress;
            rc = sdfd_catjobs_renew(r->cat, &c.status, SDFD_JOB_LEASE_SECONDS, &cancel, err,
                                    sizeof err);
            if (rc == SDF_ENOTFOUND || cancel) { /* lost, or asked to stop */
                sdfd_job_status ignored;
                sdfd_volumes_cancel(r->volumes, c.status.id, &ignored);
            }
            if (rc == SDF_ENOTFOUND)
                sdfd_log("warn", "job_lost", "job %s: its lease ran out before this replica "
                         "renewed it; another attempt owns it now", c.status.id);
        }
        pthread_mutex_lock(&r->lock);
        /* Written, or no longer this replica's. A claim that ended meanwhile stays: its end
         * is written next. */
        if ((!rc && c.ended) || rc == SDF_ENOTFOUND)
            drop(r, i);
        else
            i++;
    }
}

/* Claim and start jobs while there is room (the lock held, released around each call). */
static void claim_jobs(sdfd_jobrunner *r)
{
    while (!r->stopping && r->nclaims < r->max_running) {
        pthread_mutex_unlock(&r->lock);
        sdfd_catjob job;
        char err[512];
        int rc = sdfd_catjobs_claim(r->cat, r->owner, SDFD_JOB_LEASE_SECONDS, &job, err,
                                    sizeof err);
        pthread_mutex_lock(&r->lock);
        if (rc)
            return; /* none queued, or PostgreSQL away: the next tick tries again */
        r->counts.claimed++;
        size_t at = r->nclaims++; /* only this thread moves claims */
        r->claims[at] = (claim){.status = job.status};
        pthread_mutex_unlock(&r->lock);
        sdfd_log("info", "job_claimed", "job %s (%s of %s), attempt %d", job.status.id,
                 sdfd_job_kind_name(job.status.kind), job.target, job.status.attempts);
        rc = r->start(r->user, &job, err, sizeof err);
        free(job.request);
        pthread_mutex_lock(&r->lock);
        if (rc) { /* it never ran: its end is a failure, written with the others */
            sdfd_job_status *s = &r->claims[at].status;
            s->state = SDFD_JOB_FAILED, s->error = rc;
            snprintf(s->message, sizeof s->message, "%.255s", err);
            r->claims[at].ended = 1;
        }
    }
}

static void expire(sdfd_jobrunner *r)
{
    size_t requeued = 0, failed = 0;
    char err[512];
    if (sdfd_catjobs_expire(r->cat, &requeued, &failed, err, sizeof err) ||
        !(requeued + failed))
        return;
    sdfd_log("warn", "job_expired", "%zu jobs re-queued and %zu failed: their replicas stopped "
             "renewing their leases", requeued, failed);
    pthread_mutex_lock(&r->lock);
    r->counts.requeued += requeued, r->counts.lost += failed;
    pthread_mutex_unlock(&r->lock);
}

static void sweep(sdfd_jobrunner *r)
{
    double now = sdfd_now();
    if (now < r->next_sweep)
        return;
    double period = r->grace / 2 < 1 ? 1 : r->grace / 2;
    r->next_sweep = now + (period < SDFD_JOBRUNNER_SWEEP_MAX ? period : SDFD_JOBRUNNER_SWEEP_MAX);
    size_t deleted = 0;
    char err[512];
    if (sdfd_catalog_sweep(r->cat, r->grace, &deleted, err, sizeof err))
        sdfd_log("warn", "catalog_sweep", "%s", err);
    else if (deleted)
        sdfd_log("info", "catalog_sweep", "%zu blobs no item refers to deleted", deleted);
}

static void wait_tick(sdfd_jobrunner *r)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += (time_t)SDFD_JOBRUNNER_TICK;
    while (!r->stopping && !r->poked &&
           pthread_cond_timedwait(&r->wake, &r->lock, &ts) == 0)
        ;
    r->poked = 0;
}

static void *runner_main(void *arg)
{
    sdfd_jobrunner *r = arg;
    pthread_mutex_lock(&r->lock);
    while (!r->stopping) {
        pthread_mutex_unlock(&r->lock);
        expire(r);
        sweep(r);
        pthread_mutex_lock(&r->lock);
        tend_claims(r);
        claim_jobs(r);
        tend_claims(r); /* the starts that failed */
        wait_tick(r);
    }
    pthread_mutex_unlock(&r->lock);
    return NULL;
}

/* ---- life ------------------------------------------------------------------------------- */

sdfd_jobrunner *sdfd_jobrunner_create(sdfd_catalog *c, sdfd_cache *cache, sdfd_volumes *v,
                                      const char *owner, unsigned max_running, double grace,
                                      sdfd_jobrunner_start_fn start, void *user)
{
    sdfd_jobrunner *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    r->cat = c, r->cache = cache, r->volumes = v, r->start = start, r->user = user;
    r->max_running = max_running < MAX_CLAIMS ? max_running : MAX_CLAIMS;
    r->grace = grace;
    snprintf(r->owner, sizeof r->owner, "%s", owner);
    pthread_mutex_init(&r->lock, NULL);
    pthread_cond_init(&r->wake, NULL);
    sdfd_volumes_hooks hooks = {.user = r, .keep = keep, .listed = listed, .ended = ended};
    sdfd_volumes_set_hooks(v, &hooks);
    if (pthread_create(&r->thread, NULL, runner_main, r)) {
        pthread_cond_destroy(&r->wake);
        pthread_mutex_destroy(&r->lock);
        free(r);
        return NULL;
    }
    return r;
}

void sdfd_jobrunner_stop(sdfd_jobrunner *r)
{
    if (!r)
        return;
    pthread_mutex_lock(&r->lock);
    int was = r->stopping;
    r->stopping = 1;
    pthread_cond_signal(&r->wake);
    pthread_mutex_unlock(&r->lock);
    if (!was)
        pthread_join(r->thread, NULL);
}

void sdfd_jobrunner_destroy(sdfd_jobrunner *r)
{
    if (!r)
        return;
    sdfd_jobrunner_stop(r);
    pthread_cond_destroy(&r->wake);
    pthread_mutex_destroy(&r->lock);
    free(r);
}

void sdfd_jobrunner_poke(sdfd_jobrunner *r)
{
    pthread_mutex_lock(&r->lock);
    r->poked = 1;
    pthread_cond_signal(&r->wake);
    pthread_mutex_unlock(&r->lock);
}

sdfd_catalog *sdfd_jobrunner_catalog(sdfd_jobrunner *r) { return r->cat; }

const char *sdfd_jobrunner_owner(const sdfd_jobrunner *r) { return r->owner; }

void sdfd_jobrunner_counts_get(sdfd_jobrunner *r, sdfd_catalog_job_counts *out)
{
    pthread_mutex_lock(&r->lock);
    *out = r->counts;
    pthread_mutex_unlock(&r->lock);
}
