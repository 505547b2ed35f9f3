/* volumes.c - stored volumes and the jobs that make them, bakes and field operations (see
 * volumes.h). One mutex guards both lists; a condition variable hands freed job slots to the
 * queued jobs in arrival order. */
#include "state/volumes.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/batcher.h" /* sdfd_now */

typedef struct job {
    struct job *next;             /* newest first */
    sdfd_volumes *owner;
    sdfd_job_status status;       /* under the owner's lock, but for progress */
    _Atomic double progress;
    double phase_base, phase_scale; /* the running phase's share of progress: bake, ops */
    atomic_int cancel;
    double started;
    size_t reserved;              /* bytes promised to this job */
    sdf_mesh *mesh;               /* a bake's */
    sdfd_stored_volume *source;   /* an ops job's */
    sdfd_bake_request req;        /* an ops job: req.ops only */
    pthread_t thread;             /* none for a job restored by sdfd_volumes_add_finished */
    int has_thread;
    int finished;                 /* the thread has left the lock for the last time */
    int token;                    /* from hooks.started */
    unsigned caveats;             /* its ops' caveats, until the status takes them */
    char warning[256];
} job;

struct sdfd_volumes {
    pthread_mutex_t lock;
    pthread_cond_t slot_free;
    sdfd_stored_volume **items;   /* sorted by name */
    size_t count, max_volumes, max_bytes, bytes, reserved;
    job *jobs;
    size_t job_count, max_jobs, max_queries;
    int running, max_running, threads, closing;
    atomic_ulong next_id;
    unsigned id_prefix;
    sdfd_volumes_hooks hooks;
    sdfd_surface_sink surface_sink;
    void *surface_user;
};

static const char *const state_names[] = {"queued", "running", "done", "failed", "canceled"};

const char *sdfd_job_state_name(sdfd_job_state s)
{
    return (unsigned)s <= SDFD_JOB_CANCELED ? state_names[s] : "unknown";
}

static const char *const kind_names[] = {"bake", "ops"};

const char *sdfd_job_kind_name(sdfd_job_kind k)
{
    return (unsigned)k <= SDFD_JOB_OPS ? kind_names[k] : "unknown";
}

int sdfd_job_kind_from_name(const char *name, sdfd_job_kind *out)
{
    for (int k = SDFD_JOB_BAKE; k <= SDFD_JOB_OPS; k++)
        if (!strcmp(name, kind_names[k])) {
            *out = (sdfd_job_kind)k;
            return 0;
        }
    return SDF_EINVAL;
}

sdfd_volumes *sdfd_volumes_create(size_t max_volumes, size_t max_bytes, int max_running,
                                  size_t max_jobs, size_t max_queries, int threads)
{
    sdfd_volumes *v = calloc(1, sizeof *v);
    if (!v || !(v->items = calloc(max_volumes ? max_volumes : 1, sizeof *v->items))) {
        free(v);
        return NULL;
    }
    pthread_mutex_init(&v->lock, NULL);
    pthread_cond_init(&v->slot_free, NULL);
    v->max_volumes = max_volumes;
    v->max_bytes = max_bytes;
    v->max_running = max_running > 0 ? max_running : 1;
    v->max_jobs = max_jobs ? max_jobs : 1;
    v->max_queries = max_queries;
    v->threads = threads;
    /* Ids differ across restarts and across replicas that share jobs (catjobs.h). */
    if (getrandom(&v->id_prefix, sizeof v->id_prefix, 0) != sizeof v->id_prefix) {
        struct timespec t;
        clock_gettime(CLOCK_REALTIME, &t);
        v->id_prefix = (unsigned)(t.tv_sec * 1000003u ^ t.tv_nsec ^ (unsigned)getpid() << 16);
    }
    return v;
}

void sdfd_volumes_set_hooks(sdfd_volumes *v, const sdfd_volumes_hooks *hooks)
{
    v->hooks = *hooks;
}

void sdfd_volumes_set_surface_sink(sdfd_volumes *v, sdfd_surface_sink sink, void *user)
{
    v->surface_sink = sink, v->surface_user = user;
}

/* ---- stored volumes ---------------------------------------------------------------------- */

void sdfd_volume_retain(sdfd_stored_volume *s) { atomic_fetch_add(&s->refs, 1); }

void sdfd_volume_release(sdfd_stored_volume *s)
{
    if (s && atomic_fetch_sub(&s->refs, 1) == 1) {
        sdf_volume_destroy(s->volume);
        free(s);
    }
}

static long find(const sdfd_volumes *v, const char *name, size_t *insert_at)
{
    size_t lo = 0, hi = v->count;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        int c = strcmp(v->items[mid]->name, name);
        if (!c)
            return (long)mid;
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (insert_at)
        *insert_at = lo;
    return -1;
}

sdfd_stored_volume *sdfd_volumes_get(sdfd_volumes *v, const char *name)
{
    pthread_mutex_lock(&v->lock);
    long i = find(v, name, NULL);
    sdfd_stored_volume *s = i >= 0 ? v->items[i] : NULL;
    if (s)
        sdfd_volume_retain(s);
    pthread_mutex_unlock(&v->lock);
    return s;
}

/* Under the lock: the ops job that reads s, or NULL. */
static job *reader_of(sdfd_volumes *v, const sdfd_stored_volume *s)
{
    for (job *j = v->jobs; j; j = j->next)
        if (j->source == s)
            return j;
    return NULL;
}

/* Under the lock: a volume leaving the list (deleted, replaced, or evicted under
 * --max-resident-bytes) that an ops job still reads stays in memory until that job ends,
 * so its bytes move to the job's promise and are freed with it. With several jobs on one
 * source, the first found keeps them. */
static void unlist_bytes(sdfd_volumes *v, const sdfd_stored_volume *s)
{
    size_t bytes = sdf_volume_data_bytes(s->volume);
    job *j = reader_of(v, s);
    v->bytes -= bytes;
    if (j) {
        j->reserved += bytes;
        v->reserved += bytes;
    }
}

/* Under the lock: add or replace; takes over `s`. A replaced volume an ops job reads
 * frees nothing yet (unlist_bytes). */
static int put_locked(sdfd_volumes *v, sdfd_stored_volume *s)
{
    size_t at = 0, bytes = sdf_volume_data_bytes(s->volume);
    long i = find(v, s->name, &at);
    size_t freed = i >= 0 && !reader_of(v, v->items[i])
                       ? sdf_volume_data_bytes(v->items[i]->volume) : 0;
    if ((i < 0 && v->count >= v->max_volumes) || v->bytes - freed + bytes > v->max_bytes) {
        sdfd_volume_release(s);
        return SDF_ELIMIT;
    }
    if (i >= 0)
        unlist_bytes(v, v->items[i]);
    v->bytes += bytes;
    if (i >= 0) {
        sdfd_volume_release(v->items[i]);
        v->items[i] = s;
        return 0;
    }
    memmove(v->items + at + 1, v->items + at, (v->count - at) * sizeof *v->items);
    v->items[at] = s;
    v->count++;
    return 0;
}

int sdfd_volumes_put(sdfd_volumes *v, const char *name, sdf_volume *volume, const char *mesh,
                     int *replaced)
{
    sdfd_stored_volume *s = calloc(1, sizeof *s);
    if (!s) {
        sdf_volume_destroy(volume);
        return SDF_ENOMEM;
    }
    atomic_init(&s->refs, 1);
    s->volume = volume;
    snprintf(s->name, sizeof s->name, "%s", name);
    snprintf(s->mesh, sizeof s->mesh, "%s", mesh);
    return sdfd_volumes_put_stored(v, s, replaced);
}

int sdfd_volumes_put_stored(sdfd_volumes *v, sdfd_stored_volume *s, int *replaced)
{
    pthread_mutex_lock(&v->lock);
    *replaced = find(v, s->name, NULL) >= 0;
    /* Bytes promised to running bakes stay promised. */
    v->bytes += v->reserved;
    int rc = put_locked(v, s);
    v->bytes -= v->reserved;
    pthread_mutex_unlock(&v->lock);
    return rc;
}

int sdfd_volumes_remove(sdfd_volumes *v, const char *name)
{
    pthread_mutex_lock(&v->lock);
    long i = find(v, name, NULL);
    sdfd_stored_volume *s = NULL;
    if (i >= 0) {
        s = v->items[i];
        unlist_bytes(v, s);
        memmove(v->items + i, v->items + i + 1, (v->count - (size_t)i - 1) * sizeof *v->items);
        v->count--;
    }
    pthread_mutex_unlock(&v->lock);
    sdfd_volume_release(s);
    return s ? 0 : SDF_ENOTFOUND;
}

size_t sdfd_volumes_list(sdfd_volumes *v, sdfd_stored_volume ***out)
{
    pthread_mutex_lock(&v->lock);
    size_t n = v->count;
    *out = malloc((n ? n : 1) * sizeof **out);
    if (!*out)
        n = 0;
    for (size_t i = 0; i < n; i++) {
        (*out)[i] = v->items[i];
        sdfd_volume_retain(v->items[i]);
    }
    pthread_mutex_unlock(&v->lock);
    return n;
}

void sdfd_volumes_free_list(sdfd_stored_volume **list, size_t n)
{
    for (size_t i = 0; i < n; i++)
        sdfd_volume_release(list[i]);
    free(list);
}

size_t sdfd_volumes_count(sdfd_volumes *v)
{
    pthread_mutex_lock(&v->lock);
    size_t n = v->count;
    pthread_mutex_unlock(&v->lock);
    return n;
}

int sdfd_volume_eval_words(const sdf_volume *v, const float *points, size_t count,
                           sdf_volume_filter interpolation, int gradient, uint32_t *words,
                           size_t *bad_index)
{
    float *value = malloc((count ? count : 1) * sizeof *value);
    float *grad = gradient ? malloc((count ? 3 * count : 1) * sizeof *grad) : NULL;
    int rc = !value || (gradient && !grad) ? SDF_ENOMEM : 0;
    if (!rc)
        rc = sdf_volume_eval(v, points, count, interpolation, value, grad, bad_index);
    for (size_t i = 0; !rc && i < count; i++) {
        uint32_t *w = words + (gradient ? 4 * i : i);
        memcpy(w, value + i, 4);
        if (gradient)
            memcpy(w + 1, grad + 3 * i, 12);
    }
    free(value);
    free(grad);
    return rc;
}

/* Under the lock: how many jobs of `kind` run and wait. */
static void count_jobs(const sdfd_volumes *v, sdfd_job_kind kind, size_t *running,
                       size_t *queued)
{
    *running = *queued = 0;
    for (const job *j = v->jobs; j; j = j->next)
        if (j->status.kind == kind) {
            *running += j->status.state == SDFD_JOB_RUNNING;
            *queued += j->status.state == SDFD_JOB_QUEUED;
        }
}

void sdfd_volumes_usage(sdfd_volumes *v, size_t *bytes, size_t *running, size_t *queued)
{
    pthread_mutex_lock(&v->lock);
    *bytes = v->bytes;
    count_jobs(v, SDFD_JOB_BAKE, running, queued);
    pthread_mutex_unlock(&v->lock);
}

void sdfd_volumes_ops_usage(sdfd_volumes *v, size_t *running, size_t *queued)
{
    pthread_mutex_lock(&v->lock);
    count_jobs(v, SDFD_JOB_OPS, running, queued);
    pthread_mutex_unlock(&v->lock);
}

/* ---- jobs -------------------------------------------------------------------------------- */

/* Bytes of the volume a bake makes. */
static size_t volume_bytes(const sdf_volume_info *planned)
{
    size_t nodes = planned->dims[0] * planned->dims[1] * planned->dims[2];
    return nodes * (size_t)sdf_volume_channels(planned) * 4;
}

size_t sdfd_ops_bytes(size_t nodes, const sdfd_ops_request *req)
{
    int offsets = 0;
    for (size_t i = 0; i < req->count; i++)
        offsets |= req->ops[i].kind != SDF_FIELD_REDISTANCE;
    size_t per_node = 4 + 9 + (req->options.solver == SDF_FIELD_SUSSMAN ? 4 : 0) +
                      (offsets ? 4 : 0);
    size_t exact = 0;
    if (req->options.solver == SDF_FIELD_EXACT) {
        /* the field as a volume and its sign bits; the surface's mesh and index, ~300 bytes
         * a triangle for ~4 n^2 of them on n^3 nodes; and a batch of queries (exact.c) */
        double side = cbrt((double)nodes);
        size_t batch = nodes < ((size_t)1 << 21) ? nodes : (size_t)1 << 21;
        exact = nodes * 5 + (size_t)(4 * side * side) * 300 + batch * 24;
    }
    return nodes * per_node + exact;
}

/* Both libraries' progress callbacks: the phase's fraction into the job's. */
static int on_progress(void *user, double fraction)
{
    job *j = user;
    atomic_store(&j->progress, j->phase_base + j->phase_scale * fraction);
    return atomic_load(&j->cancel);
}

static void snapshot(job *j, sdfd_job_status *out)
{
    *out = j->status;
    out->progress = atomic_load(&j->progress);
    int unfinished = j->status.state == SDFD_JOB_QUEUED || j->status.state == SDFD_JOB_RUNNING;
    if (unfinished)
        out->seconds = sdfd_now() - j->started;
    out->cancel_requested = unfinished && atomic_load(&j->cancel);
}

/* Under the lock: is j the oldest job still waiting for a slot (and not canceled)? The list
 * is newest first, so that is the last such job in it. */
static int first_in_line(const sdfd_volumes *v, const job *j)
{
    const job *oldest = NULL;
    for (const job *k = v->jobs; k; k = k->next)
        if (k->status.state == SDFD_JOB_QUEUED && !atomic_load(&k->cancel))
            oldest = k;
    return oldest == j;
}

/* Wait for a slot, in arrival order; returns whether the job was canceled first. */
static int take_slot(sdfd_volumes *v, job *j)
{
    pthread_mutex_lock(&v->lock);
    while ((v->running >= v->max_running || !first_in_line(v, j)) && !atomic_load(&j->cancel))
        pthread_cond_wait(&v->slot_free, &v->lock);
    int canceled = atomic_load(&j->cancel);
    if (!canceled) {
        v->running++;
        j->status.state = SDFD_JOB_RUNNING;
        pthread_cond_broadcast(&v->slot_free); /* the next in line may fit too */
    }
    pthread_mutex_unlock(&v->lock);
    return canceled;
}

/* The job's field operations on `in` into *out; the caveats that fired are kept in j->caveats
 * and j->warning (the status takes them under the lock when the job ends). */
static int apply_ops(job *j, const sdf_volume *in, sdf_volume **out, sdf_diag *diag)
{
    sdf_field_options o = j->req.ops.options;
    o.progress = on_progress;
    o.user = j;
    o.threads = j->owner->threads;
    unsigned caveats = 0;
    int rc = sdf_volume_apply_ops(in, j->req.ops.ops, j->req.ops.count, &o, out, &caveats, diag);
    if (!rc && caveats) {
        j->caveats = caveats;
        snprintf(j->warning, sizeof j->warning, "%s", diag->message);
    }
    return rc;
}

/* The job's work: an ops job's operations, or a bake and then its operations (progress:
 * the bake 0..0.5, the operations 0.5..1; a bake without them 0..1). */
static int work(job *j, sdf_volume **out, sdf_diag *diag)
{
    if (j->status.kind == SDFD_JOB_OPS)
        return apply_ops(j, j->source->volume, out, diag);
    j->phase_scale = j->req.ops.count ? 0.5 : 1.0;
    int rc = sdf_volume_bake(j->mesh, &j->req.options, out, diag);
    if (rc || !j->req.ops.count)
        return rc;
    sdf_volume *baked = *out;
    *out = NULL;
    j->phase_base = 0.5; /* the bake's callbacks have all returned */
    rc = apply_ops(j, baked, out, diag);
    sdf_volume_destroy(baked);
    return rc;
}

/* The finished volume as a stored one, kept by the hook (the store) first, before the job
 * says done, so a client that saw "done" finds it after a restart.
 * NULL with *rc and diag set when it cannot be. Takes `volume` over. */
static sdfd_stored_volume *keep(job *j, sdf_volume *volume, int *rc, sdf_diag *diag)
{
    sdfd_volumes *v = j->owner;
    sdfd_stored_volume *stored = calloc(1, sizeof *stored);
    if (!stored) {
        sdf_volume_destroy(volume);
        *rc = SDF_ENOMEM;
        snprintf(diag->message, sizeof diag->message, "no memory to store the volume");
        return NULL;
    }
    atomic_init(&stored->refs, 1);
    stored->volume = volume;
    snprintf(stored->name, sizeof stored->name, "%s", j->status.volume);
    snprintf(stored->mesh, sizeof stored->mesh, "%s", j->status.mesh);
    snprintf(stored->job, sizeof stored->job, "%s", j->status.id);
    stored->bake_seconds = sdfd_now() - j->started;
    if (v->hooks.keep &&
        (*rc = v->hooks.keep(v->hooks.user, stored, diag->message, sizeof diag->message))) {
        sdfd_volume_release(stored);
        return NULL;
    }
    return stored;
}

/* A bake that names a mesh: its volume's surface stored as that mesh (the volume stays
 * stored if this fails, and the job fails with why). */
static int keep_surface(job *j, const sdfd_stored_volume *stored, sdf_diag *diag)
{
    sdfd_volumes *v = j->owner;
    if (!v->surface_sink) {
        snprintf(diag->message, sizeof diag->message, "this server cannot store meshes");
        return SDF_EINVAL;
    }
    return v->surface_sink(v->surface_user, j->req.surface, stored->volume,
                           j->req.options.query.threads, diag->message, sizeof diag->message);
}

/* The kept volume listed in memory (its reserved bytes become the volume's), then the keep
 * hook's `listed`: before anything else runs (a surface's extraction), so the store's claim
 * on the name is held no longer than this. Takes `stored` over; 0 or SDF_ELIMIT with diag
 * set. */
static int list_kept(job *j, sdfd_stored_volume *stored, sdf_diag *diag)
{
    sdfd_volumes *v = j->owner;
    pthread_mutex_lock(&v->lock);
    v->reserved -= j->reserved;
    j->reserved = 0;
    int put = put_locked(v, stored);
    pthread_mutex_unlock(&v->lock);
    if (v->hooks.listed)
        v->hooks.listed(v->hooks.user, j->status.volume, put);
    if (put)
        snprintf(diag->message, sizeof diag->message,
                 "the volume made no longer fits --max-volumes / --max-volume-bytes");
    return put;
}

/* The job's end: its slot and bytes freed, its final status recorded. */
static void finish(job *j, int canceled, int rc, sdf_diag *diag)
{
    sdfd_volumes *v = j->owner;
    pthread_mutex_lock(&v->lock);
    if (!canceled)
        v->running--;
    v->reserved -= j->reserved;
    j->reserved = 0;
    j->status.state = !rc ? SDFD_JOB_DONE : rc == SDF_ECANCELED ? SDFD_JOB_CANCELED : SDFD_JOB_FAILED;
    if (j->status.state == SDFD_JOB_FAILED) {
        j->status.error = rc;
        snprintf(j->status.message, sizeof j->status.message, "%s",
                 diag->message[0] ? diag->message : sdfd_strerror(rc));
    }
    if (!rc) {
        atomic_store(&j->progress, 1.0);
        j->status.caveats = j->caveats;
        snprintf(j->status.warning, sizeof j->status.warning, "%s", j->warning);
    }
    j->status.seconds = sdfd_now() - j->started;
    sdfd_job_status final;
    snapshot(j, &final);
    pthread_cond_broadcast(&v->slot_free);
    pthread_mutex_unlock(&v->lock);
    if (v->hooks.ended)
        v->hooks.ended(v->hooks.user, &final, j->token);
    pthread_mutex_lock(&v->lock);
    j->finished = 1; /* only now may it be forgotten, so its record cannot outlive it */
    pthread_mutex_unlock(&v->lock);
}

static void *run_job(void *arg)
{
    job *j = arg;
    const char *kind = sdfd_job_kind_name(j->status.kind);
    int canceled = take_slot(j->owner, j);
    sdf_volume *volume = NULL;
    sdf_diag diag = {0};
    int rc = SDF_ECANCELED;
    if (!canceled) {
        sdfd_log("info", j->status.kind == SDFD_JOB_OPS ? "ops_started" : "bake_started",
                 "job %s: %s -> %s", j->status.id,
                 j->status.kind == SDFD_JOB_OPS ? j->status.source : j->status.mesh,
                 j->status.volume);
        rc = work(j, &volume, &diag);
    }
    sdf_mesh_release(j->mesh);
    sdf_mesh_release(j->req.smoothing_mesh);
    j->mesh = j->req.smoothing_mesh = NULL;
    /* The source goes before the result is listed: an ops job that replaces its own source
     * frees the source's bytes then (put_locked keeps a volume's bytes while a job reads it). */
    pthread_mutex_lock(&j->owner->lock); /* unlist_bytes reads it */
    sdfd_stored_volume *source = j->source;
    j->source = NULL;
    pthread_mutex_unlock(&j->owner->lock);
    sdfd_volume_release(source);
    sdfd_stored_volume *stored = rc ? NULL : keep(j, volume, &rc, &diag);
    if (stored) { /* listed even when its surface fails next */
        sdfd_volume_retain(stored);
        rc = list_kept(j, stored, &diag);
        if (!rc && j->req.surface[0])
            rc = keep_surface(j, stored, &diag);
        sdfd_volume_release(stored);
    }
    finish(j, canceled, rc, &diag);
    sdfd_log("info", j->status.kind == SDFD_JOB_OPS ? "ops_finished" : "bake_finished",
             "job %s (%s): %s after %.3f s", j->status.id, kind,
             sdfd_job_state_name(j->status.state), j->status.seconds);
    return NULL;
}

static void free_job(sdfd_volumes *v, job *j, int forget)
{
    if (j->has_thread)
        pthread_join(j->thread, NULL);
    if (forget && v->hooks.forgotten)
        v->hooks.forgotten(v->hooks.user, j->status.id);
    free(j);
}

/* Under the lock: unlink the oldest finished job, or return NULL. */
static job *unlink_oldest_finished(sdfd_volumes *v)
{
    job **oldest = NULL;
    for (job **p = &v->jobs; *p; p = &(*p)->next)
        if ((*p)->finished)
            oldest = p;
    if (!oldest)
        return NULL;
    job *j = *oldest;
    *oldest = j->next;
    v->job_count--;
    return j;
}

/* The distance queries the planned bake costs, against the limit (a filtered bake: its
 * parameters too, as a filtered query's are checked). */
static int check_queries(const sdfd_volumes *v, const sdf_mesh *mesh,
                         const sdf_volume_info *planned, const sdfd_bake_request *req, char *err,
                         size_t err_cap)
{
    size_t nodes = planned->dims[0] * planned->dims[1] * planned->dims[2];
    size_t side = planned->order ? 2 * (size_t)planned->fine_half + 1 : 1;
    size_t points = nodes * side * side * side;
    if (req->filtered)
        return sdfd_filter_validate(mesh, &req->filter, points, v->max_queries, err, err_cap);
    if (points > v->max_queries) {
        snprintf(err, err_cap, "the bake costs %zu distance queries, over --max-bake-queries %zu; "
                 "lower the resolution", points, v->max_queries);
        return SDF_ELIMIT;
    }
    return 0;
}

/* Admit the prepared job `j` (its request, names and kind set), which holds `volume` bytes
 * of result and `working` more while it runs: the byte limit, the job limit, then its
 * record and its thread. 0 (id set) or an error with err; the caller frees j on failure. */
static int enqueue(sdfd_volumes *v, job *j, size_t volume, size_t working, char id[24],
                   char *err, size_t err_cap)
{
    job *pruned = NULL;
    size_t need = volume + working; /* held until the job ends: then the volume alone */
    const char *what = j->status.kind == SDFD_JOB_OPS ? "the field operations need"
                                                      : "the bake needs";
    int rc = 0;
    pthread_mutex_lock(&v->lock);
    if (v->closing)
        rc = SDFD_EUNAVAILABLE, snprintf(err, err_cap, "the server is shutting down");
    if (!rc && v->bytes + v->reserved + need > v->max_bytes)
        rc = SDF_ELIMIT, snprintf(err, err_cap,
                                  "%s %zu bytes (%zu for the volume, %zu to work in); "
                                  "%zu of --max-volume-bytes %zu are held or promised",
                                  what, need, volume, working, v->bytes + v->reserved,
                                  v->max_bytes);
    if (!rc && v->job_count >= v->max_jobs && !(pruned = unlink_oldest_finished(v)))
        rc = SDFD_EBUSY, snprintf(err, err_cap, "%zu jobs are unfinished; retry later",
                                 v->job_count);
    if (!rc) {
        if (id[0]) /* a shared job's own */
            snprintf(j->status.id, sizeof j->status.id, "%.23s", id);
        else
            sdfd_volumes_new_id(v, j->status.id);
        j->status.state = SDFD_JOB_QUEUED;
        j->started = sdfd_now();
        j->reserved = need;
        j->phase_scale = 1.0;
        /* Recorded before its thread can end it (the record says queued, then its end). */
        if (v->hooks.started)
            j->token = v->hooks.started(v->hooks.user, &j->status);
        if (pthread_create(&j->thread, NULL, run_job, j)) {
            rc = SDFD_EUNAVAILABLE, snprintf(err, err_cap, "cannot start a job thread");
            if (v->hooks.ended) {
                j->status.state = SDFD_JOB_FAILED;
                v->hooks.ended(v->hooks.user, &j->status, j->token);
            }
        } else {
            j->has_thread = 1;
            v->reserved += need;
            j->next = v->jobs;
            v->jobs = j;
            v->job_count++;
            memcpy(id, j->status.id, 24);
        }
    }
    pthread_mutex_unlock(&v->lock);
    if (pruned)
        free_job(v, pruned, 1);
    return rc;
}

/* A bake with ops must make what they take: a zero-order float32 grid. */
static int check_bake_ops(const sdf_volume_info *planned, char *err, size_t err_cap)
{
    if (planned->order == 0 && planned->encoding == SDF_ENCODING_FLOAT32)
        return 0;
    snprintf(err, err_cap, "'ops' take a zero-order float32 grid; this bake makes order %d %s "
             "(bake with order 0 and encoding float32)", planned->order,
             sdf_encoding_name(planned->encoding));
    return SDF_EINVAL;
}

/* The bake of `req` (its options made by bake_options) as the library plans it: 0 with
 * *planned and the *working bytes besides the volume, or an error with err. */
static int plan_bake(sdfd_volumes *v, const sdf_mesh *mesh, const sdfd_bake_request *req,
                     sdf_volume_info *planned, size_t *working, char *err, size_t err_cap)
{
    const sdf_bake_options *o = &req->options;
    sdf_diag diag = {0};
    int rc;
    if ((rc = sdf_volume_plan(mesh, o, planned, &diag)) ||
        (rc = sdf_volume_bake_scratch(mesh, o, working, &diag)))
        snprintf(err, err_cap, "%s", diag.message);
    else if (!(rc = check_queries(v, mesh, planned, req, err, err_cap)) && req->ops.count)
        rc = check_bake_ops(planned, err, err_cap);
    if (!rc && req->ops.count) { /* the ops run after the bake's working memory is freed */
        size_t ops = sdfd_ops_bytes(planned->dims[0] * planned->dims[1] * planned->dims[2],
                                    &req->ops);
        *working = *working > ops ? *working : ops;
    }
    return rc;
}

/* The options the library gets for request `req` (a copy the job owns, or the caller's). */
static void bake_options(sdfd_volumes *v, sdfd_bake_request *req, job *j)
{
    sdf_bake_options *o = &req->options;
    o->filter = req->filtered ? &req->filter : NULL;
    if (req->filtered)
        req->filter.smooth.mesh = req->smoothing_mesh;
    o->progress = on_progress;
    o->user = j;
    o->query.threads = v->threads;
}

/* Over --max-volume-bytes by itself, whatever else is held. */
static int check_alone(const sdfd_volumes *v, size_t need, char *err, size_t err_cap)
{
    if (need <= v->max_bytes)
        return 0;
    snprintf(err, err_cap, "the job needs %zu bytes, over --max-volume-bytes %zu", need,
             v->max_bytes);
    return SDF_ELIMIT;
}

void sdfd_volumes_new_id(sdfd_volumes *v, char id[24])
{
    snprintf(id, 24, "%08x-%lu", v->id_prefix, atomic_fetch_add(&v->next_id, 1) + 1);
}

int sdfd_volumes_check_bake(sdfd_volumes *v, const sdf_mesh *mesh, const sdfd_bake_request *req,
                            char *err, size_t err_cap)
{
    sdfd_bake_request copy = *req;
    sdf_volume_info planned = {0};
    size_t working = 0;
    bake_options(v, &copy, NULL);
    int rc = plan_bake(v, mesh, &copy, &planned, &working, err, err_cap);
    return rc ? rc : check_alone(v, volume_bytes(&planned) + working, err, err_cap);
}

int sdfd_volumes_bake(sdfd_volumes *v, sdf_mesh *mesh, const char *mesh_name,
                      const char *volume_name, sdfd_bake_request *req, char id[24], char *err,
                      size_t err_cap)
{
    job *j = calloc(1, sizeof *j);
    int rc = j ? 0 : SDF_ENOMEM;
    sdf_volume_info planned = {0};
    size_t working = 0; /* the bake's working memory besides the volume (sdf.h) */
    if (!rc) {
        j->req = *req;
        j->mesh = mesh;
        j->owner = v;
        j->status.kind = SDFD_JOB_BAKE;
        j->status.has_ops = req->ops.count > 0;
        bake_options(v, &j->req, j);
        /* The library's own checks and defaults say what the bake will make. */
        rc = plan_bake(v, mesh, &j->req, &planned, &working, err, err_cap);
        snprintf(j->status.mesh, sizeof j->status.mesh, "%s", mesh_name);
        snprintf(j->status.volume, sizeof j->status.volume, "%s", volume_name);
    }
    if (!rc)
        rc = enqueue(v, j, volume_bytes(&planned), working, id, err, err_cap);
    if (rc) {
        if (rc == SDF_ENOMEM)
            snprintf(err, err_cap, "out of memory");
        sdf_mesh_release(mesh);
        sdf_mesh_release(req->smoothing_mesh);
        free(j);
    }
    return rc;
}

/* The library's reason for refusing `in` (first order, packed), asked with no operations:
 * it checks the options and the volume before the count. 0 when it takes it. */
static int check_source(const sdf_volume *in, const sdfd_ops_request *req, char *err,
                        size_t err_cap)
{
    sdf_volume_info info;
    sdf_volume_get_info(in, &info);
    if (info.order == 0 && info.encoding == SDF_ENCODING_FLOAT32)
        return 0;
    sdf_volume *out = NULL;
    sdf_diag diag = {0};
    int rc = sdf_volume_apply_ops(in, req->ops, 0, &req->options, &out, NULL, &diag);
    sdf_volume_destroy(out);
    snprintf(err, err_cap, "%s", diag.message);
    return rc ? rc : SDF_EINVAL;
}

int sdfd_volumes_check_ops(sdfd_volumes *v, const sdfd_stored_volume *source,
                           const sdfd_ops_request *req, char *err, size_t err_cap)
{
    int rc = check_source(source->volume, req, err, err_cap);
    size_t bytes = sdf_volume_data_bytes(source->volume);
    return rc ? rc : check_alone(v, sdfd_ops_bytes(bytes / 4, req), err, err_cap);
}

int sdfd_volumes_ops(sdfd_volumes *v, sdfd_stored_volume *source, const char *volume_name,
                     const sdfd_ops_request *req, char id[24], char *err, size_t err_cap)
{
    job *j = calloc(1, sizeof *j);
    int rc = j ? check_source(source->volume, req, err, err_cap) : SDF_ENOMEM;
    if (!rc) {
        j->req.ops = *req;
        j->source = source;
        j->owner = v;
        j->status.kind = SDFD_JOB_OPS;
        j->status.has_ops = 1;
        snprintf(j->status.mesh, sizeof j->status.mesh, "%s", source->mesh);
        snprintf(j->status.source, sizeof j->status.source, "%s", source->name);
        snprintf(j->status.volume, sizeof j->status.volume, "%s", volume_name);
        size_t bytes = sdf_volume_data_bytes(source->volume), nodes = bytes / 4;
        size_t total = sdfd_ops_bytes(nodes, req);
        rc = enqueue(v, j, bytes, total - bytes, id, err, err_cap);
    }
    if (rc) {
        if (rc == SDF_ENOMEM)
            snprintf(err, err_cap, "out of memory");
        sdfd_volume_release(source);
        free(j);
    }
    return rc;
}

static job *find_job(sdfd_volumes *v, const char *id, job ***link)
{
    for (job **p = &v->jobs; *p; p = &(*p)->next)
        if (!strcmp((*p)->status.id, id)) {
            if (link)
                *link = p;
            return *p;
        }
    return NULL;
}

int sdfd_volumes_job(sdfd_volumes *v, const char *id, sdfd_job_status *out)
{
    pthread_mutex_lock(&v->lock);
    job *j = find_job(v, id, NULL);
    if (j)
        snapshot(j, out);
    pthread_mutex_unlock(&v->lock);
    return j ? 0 : SDF_ENOTFOUND;
}

int sdfd_volumes_cancel(sdfd_volumes *v, const char *id, sdfd_job_status *out)
{
    job **link = NULL, *forgotten = NULL;
    pthread_mutex_lock(&v->lock);
    job *j = find_job(v, id, &link);
    if (j && j->finished) { /* forget it */
        snapshot(j, out);
        *link = j->next;
        v->job_count--;
        forgotten = j;
    } else if (j) {
        atomic_store(&j->cancel, 1);
        pthread_cond_broadcast(&v->slot_free); /* a queued job notices at once */
        snapshot(j, out);
    }
    pthread_mutex_unlock(&v->lock);
    if (forgotten)
        free_job(v, forgotten, 1);
    return j ? 0 : SDF_ENOTFOUND;
}

size_t sdfd_volumes_jobs(sdfd_volumes *v, sdfd_job_status **out)
{
    pthread_mutex_lock(&v->lock);
    size_t n = 0;
    *out = malloc((v->job_count ? v->job_count : 1) * sizeof **out);
    for (job *j = v->jobs; *out && j; j = j->next)
        snapshot(j, &(*out)[n++]);
    pthread_mutex_unlock(&v->lock);
    return n;
}

int sdfd_volumes_add_finished(sdfd_volumes *v, const sdfd_job_status *s)
{
    job *j = calloc(1, sizeof *j), *pruned = NULL;
    if (!j)
        return SDF_ENOMEM;
    j->owner = v;
    j->status = *s;
    j->finished = 1;
    j->started = sdfd_now() - s->seconds;
    pthread_mutex_lock(&v->lock);
    int rc = v->job_count >= v->max_jobs && !(pruned = unlink_oldest_finished(v)) ? SDFD_EBUSY : 0;
    if (!rc) {
        j->next = v->jobs;
        v->jobs = j;
        v->job_count++;
    }
    pthread_mutex_unlock(&v->lock);
    if (pruned)
        free_job(v, pruned, 1);
    if (rc)
        free(j);
    return rc;
}

void sdfd_volumes_close(sdfd_volumes *v)
{
    pthread_mutex_lock(&v->lock);
    v->closing = 1;
    for (job *j = v->jobs; j; j = j->next)
        atomic_store(&j->cancel, 1);
    pthread_cond_broadcast(&v->slot_free);
    pthread_mutex_unlock(&v->lock);
}

void sdfd_volumes_destroy(sdfd_volumes *v)
{
    if (!v)
        return;
    sdfd_volumes_close(v);
    pthread_mutex_lock(&v->lock);
    job *jobs = v->jobs;
    v->jobs = NULL;
    pthread_mutex_unlock(&v->lock);
    while (jobs) { /* each stops at its next slab */
        job *next = jobs->next;
        free_job(v, jobs, 0);
        jobs = next;
    }
    for (size_t i = 0; i < v->count; i++)
        sdfd_volume_release(v->items[i]);
    pthread_cond_destroy(&v->slot_free);
    pthread_mutex_destroy(&v->lock);
    free(v->items);
    free(v);
}
