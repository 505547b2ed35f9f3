/* loader.c - lookups that hand loads to a pool of threads (loader.h). A name whose item must
 * be read from the backing is claimed (resident.h: busy) and queued; the lookups that find it
 * busy queue themselves on it, and the thread that ends the load answers them all with its
 * result. The slow parts (file reads, parsing, BVH builds) run on the pool's threads, outside
 * the table's lock. */
#include "state/loader.h"

#include <cjson/cJSON.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/batcher.h" /* sdfd_now */

/* What a check found: the item must be read from the backing (not an error code). */
#define NEED_LOAD 2

struct sdfd_loader {
    const sdfd_backing *b;
    sdfd_resident *r;
    sdfd_metrics *metrics;
    size_t max_triangles;
    /* under r->lock */
    pthread_cond_t work;
    sdfd_cached *head, *tail; /* claimed entries to load, oldest first */
    int stopping;
    pthread_t threads[SDFD_LOADER_THREADS];
    int started;
};

static int answer(sdfd_lookup *l, int status, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

static int answer(sdfd_lookup *l, int status, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(l->message, sizeof l->message, fmt, ap);
    va_end(ap);
    l->status = status;
    return status;
}

static int not_found(sdfd_lookup *l)
{
    return answer(l, SDF_ENOTFOUND, "no %s named '%s'", sdfd_kind_name(l->kind), l->name);
}

/* ---- reading an item --------------------------------------------------------------------- */

/* A stored volume from an EXR and its sidecar's info. */
static int parse_volume(const sdfd_sidecar *meta, const void *data, void **out, sdf_diag *diag)
{
    sdf_volume *volume = NULL;
    sdfd_stored_volume *s = calloc(1, sizeof *s);
    int rc = s ? sdf_volume_load_exr_memory(data, meta->bytes, &volume, diag) : SDF_ENOMEM;
    if (rc) {
        free(s);
        return rc;
    }
    atomic_init(&s->refs, 1);
    s->volume = volume;
    snprintf(s->name, sizeof s->name, "%s", meta->name);
    cJSON *info = cJSON_Parse(meta->info ? meta->info : "{}");
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(info, "mesh"),
                *j = cJSON_GetObjectItemCaseSensitive(info, "job"),
                *t = cJSON_GetObjectItemCaseSensitive(info, "bake_seconds");
    snprintf(s->mesh, sizeof s->mesh, "%s", cJSON_IsString(m) ? m->valuestring : "");
    snprintf(s->job, sizeof s->job, "%s", cJSON_IsString(j) ? j->valuestring : "");
    s->bake_seconds = cJSON_IsNumber(t) ? t->valuedouble : 0;
    cJSON_Delete(info);
    *out = s;
    return 0;
}

/* Parse a data file into a mesh or a stored volume. */
static int parse_item(sdfd_loader *ld, const sdfd_sidecar *meta, const void *data, void **out,
                      char *why, size_t cap)
{
    sdf_diag diag = {0};
    int rc;
    if (!strcmp(meta->format, "exr")) {
        rc = parse_volume(meta, data, out, &diag);
    } else {
        sdf_mesh_options opts = {.max_triangles = ld->max_triangles};
        sdf_mesh *mesh = NULL;
        rc = sdf_format_from_name(meta->format, &opts.format);
        if (rc)
            snprintf(diag.message, sizeof diag.message, "unknown format '%s'", meta->format);
        else
            rc = sdf_mesh_load_memory(data, meta->bytes, &opts, &mesh, &diag);
        *out = mesh;
    }
    if (rc)
        snprintf(why, cap, "%s", diag.message[0] ? diag.message : sdfd_strerror(rc));
    return rc;
}

/* Read and parse e's item from the backing (e claimed, the lock not held): 0 with *item (one
 * reference) and its hash and version; or an error with msg. A damaged item is quarantined,
 * unless it changed while it was read (another replica's write: read again). */
static int load(sdfd_loader *ld, sdfd_cached *e, void **item, uint64_t *hash, sdfd_seen *seen,
                char *msg, size_t cap)
{
    char why[400];
    const char *kind = sdfd_kind_name(e->kind);
    for (int attempt = 0;; attempt++) {
        double t0 = sdfd_now();
        sdfd_sidecar meta;
        void *data = NULL;
        int rc = ld->b->ops->read(ld->b->self, e->kind, e->name, &meta, &data, seen, why,
                                  sizeof why);
        if (!rc) {
            rc = parse_item(ld, &meta, data, item, why, sizeof why) ? SDF_EFORMAT : 0;
            *hash = meta.hash;
        }
        free(data);
        free(meta.info);
        if (!rc) {
            double seconds = sdfd_now() - t0;
            sdfd_metrics_store_load(ld->metrics, seconds);
            sdfd_log("info", "store_loaded", "%s %s from %s in %.3f s", kind, e->name,
                     ld->b->ops->flag, seconds);
            return 0;
        }
        if (rc != SDF_EFORMAT) {
            if (rc == SDF_ENOTFOUND)
                snprintf(msg, cap, "no %s named '%s'", kind, e->name);
            else
                snprintf(msg, cap, "%s", why);
            return rc;
        }
        sdfd_seen now;
        char ignored[64];
        int moved = ld->b->ops->stat(ld->b->self, e->kind, e->name, &now, ignored,
                                     sizeof ignored) ||
                    ld->b->ops->changed(&now, seen);
        if (moved && attempt < 5)
            continue;
        ld->b->ops->quarantine(ld->b->self, e->kind, e->name, why);
        pthread_mutex_lock(&ld->r->lock);
        ld->r->quarantined++;
        pthread_mutex_unlock(&ld->r->lock);
        snprintf(msg, cap, "no %s named '%s' (what %s holds of it is damaged and set aside: "
                 "%.200s)", kind, e->name, ld->b->ops->flag, why);
        return SDF_ENOTFOUND;
    }
}

/* Compare e (claimed, the lock not held) with the backing: 0 with l->item (what is in memory
 * is current, or the backing cannot be read just now), an error in l, or NEED_LOAD. */
static int check(sdfd_loader *ld, sdfd_cached *e, sdfd_lookup *l)
{
    sdfd_resident *r = ld->r;
    sdfd_seen seen;
    pthread_mutex_lock(&r->lock);
    unsigned changes = e->changes;
    pthread_mutex_unlock(&r->lock);
    int rc = ld->b->ops->stat(ld->b->self, e->kind, e->name, &seen, l->message,
                              sizeof l->message);
    pthread_mutex_lock(&r->lock);
    int resident = e->resident;
    uint64_t hash = e->hash;
    if (rc == SDF_ENOTFOUND && resident)
        sdfd_resident_drop(r, e); /* deleted, on this replica or another */
    /* Serve what is in memory: unchanged, or a backing that cannot be read just now. */
    if (resident && (rc == SDFD_EUNAVAILABLE || (!rc && !ld->b->ops->changed(&seen, &e->seen))) &&
        (l->item = sdfd_resident_get(r, e))) {
        e->checked = e->changes == changes ? sdfd_now() : 0;
        pthread_mutex_unlock(&r->lock);
        return 0;
    }
    pthread_mutex_unlock(&r->lock);
    if (rc == SDF_ENOTFOUND)
        return not_found(l);
    if (rc)
        return l->status = rc;
    /* A volume's description also names the job that made it and its time, which the same
     * bytes baked again do not share: only a mesh rewritten with its content stays. */
    if (!resident || e->kind != SDFD_ITEM_MESH)
        return NEED_LOAD;
    /* Rewritten: with the same content? */
    sdfd_sidecar meta;
    char why[64];
    int same = !ld->b->ops->read(ld->b->self, e->kind, e->name, &meta, NULL, &seen, why,
                                 sizeof why) && meta.hash == hash;
    free(meta.info);
    if (!same)
        return NEED_LOAD;
    pthread_mutex_lock(&r->lock);
    e->checked = e->changes == changes ? sdfd_now() : 0, e->seen = seen;
    l->item = sdfd_resident_get(r, e);
    pthread_mutex_unlock(&r->lock);
    return l->item ? 0 : NEED_LOAD;
}

/* ---- the pool ---------------------------------------------------------------------------- */

/* Under the lock: queue e (claimed) for a thread; 0, or -1 once stopping. */
static int enqueue(sdfd_loader *ld, sdfd_cached *e)
{
    if (ld->stopping)
        return -1;
    e->queued = NULL;
    if (ld->tail)
        ld->tail->queued = e;
    else
        ld->head = e;
    ld->tail = e;
    pthread_cond_signal(&ld->work);
    return 0;
}

/* Answer the lookups that waited for a load with its result (the lock not held). */
static void answer_all(sdfd_lookup *waiting, int rc, void *item, const char *msg)
{
    for (sdfd_lookup *l = waiting, *next; l; l = next) {
        next = l->next; /* done may reuse l */
        l->status = rc;
        l->item = rc ? NULL : sdfd_item_retain(l->kind, item);
        snprintf(l->message, sizeof l->message, "%s", rc ? msg : "");
        l->done(l);
    }
}

/* Load e (claimed), make it resident, and answer the lookups that waited for it. */
static void run_load(sdfd_loader *ld, sdfd_cached *e)
{
    sdfd_resident *r = ld->r;
    void *item = NULL;
    uint64_t hash = 0;
    sdfd_seen seen;
    char msg[sizeof ((sdfd_lookup *)0)->message];
    sdfd_item_kind kind = e->kind;
    pthread_mutex_lock(&r->lock);
    unsigned changes = e->changes;
    pthread_mutex_unlock(&r->lock);
    int rc = load(ld, e, &item, &hash, &seen, msg, sizeof msg);
    pthread_mutex_lock(&r->lock);
    if (rc) {
        if (e->resident && rc == SDF_ENOTFOUND)
            sdfd_resident_drop(r, e);
    } else {
        /* A change heard of during the load: compare again at the next lookup. */
        e->checked = e->changes == changes ? sdfd_now() : 0, e->seen = seen, e->hash = hash;
        r->loads++;
        if ((rc = sdfd_resident_put(r, e, item)))
            snprintf(msg, sizeof msg, "%s %s does not fit in memory beside the items in use "
                     "(--max-meshes, --max-triangles, --max-volumes, --max-volume-bytes)",
                     sdfd_kind_name(kind), e->name);
        else
            sdfd_resident_enforce_budget(r, e);
        e->used = ++r->tick;
    }
    sdfd_lookup *waiting = sdfd_resident_unclaim(r, e); /* e may be gone */
    pthread_mutex_unlock(&r->lock);
    answer_all(waiting, rc, item, msg);
    sdfd_item_release(kind, item);
}

static void *loader_main(void *arg)
{
    sdfd_loader *ld = arg;
    pthread_mutex_lock(&ld->r->lock);
    for (;;) {
        while (!ld->head && !ld->stopping)
            pthread_cond_wait(&ld->work, &ld->r->lock);
        sdfd_cached *e = ld->head;
        if (!e)
            break; /* stopping, and nothing left */
        if (!(ld->head = e->queued))
            ld->tail = NULL;
        pthread_mutex_unlock(&ld->r->lock);
        run_load(ld, e);
        pthread_mutex_lock(&ld->r->lock);
    }
    pthread_mutex_unlock(&ld->r->lock);
    return NULL;
}

sdfd_loader *sdfd_loader_create(const sdfd_backing *b, sdfd_resident *r, sdfd_metrics *metrics,
                                size_t max_triangles)
{
    sdfd_loader *ld = calloc(1, sizeof *ld);
    if (!ld)
        return NULL;
    ld->b = b, ld->r = r, ld->metrics = metrics, ld->max_triangles = max_triangles;
    pthread_cond_init(&ld->work, NULL);
    while (ld->started < SDFD_LOADER_THREADS &&
           !pthread_create(&ld->threads[ld->started], NULL, loader_main, ld))
        ld->started++;
    if (ld->started < SDFD_LOADER_THREADS) {
        sdfd_loader_destroy(ld);
        return NULL;
    }
    return ld;
}

void sdfd_loader_stop(sdfd_loader *ld)
{
    pthread_mutex_lock(&ld->r->lock);
    ld->stopping = 1;
    pthread_cond_broadcast(&ld->work);
    pthread_mutex_unlock(&ld->r->lock);
    for (int i = 0; i < ld->started; i++)
        pthread_join(ld->threads[i], NULL);
    ld->started = 0;
}

void sdfd_loader_destroy(sdfd_loader *ld)
{
    if (!ld)
        return;
    sdfd_loader_stop(ld);
    pthread_cond_destroy(&ld->work);
    free(ld);
}

/* ---- lookups ----------------------------------------------------------------------------- */

int sdfd_loader_lookup(sdfd_loader *ld, sdfd_lookup *l)
{
    sdfd_resident *r = ld->r;
    l->item = NULL;
    l->status = 0;
    l->message[0] = '\0';
    pthread_mutex_lock(&r->lock);
    sdfd_cached *e = sdfd_resident_find(r, l->kind, l->name, 1);
    if (!e) {
        pthread_mutex_unlock(&r->lock);
        return answer(l, SDF_ENOMEM, "out of memory");
    }
    /* The version in memory answers while it is current, and while its successor loads. */
    int current = e->busy ? e->reloading
                          : e->pinned || (e->resident && sdfd_now() - e->checked <
                                                             SDFD_LOADER_RECHECK_SECONDS);
    if (current && (l->item = sdfd_resident_get(r, e))) {
        e->used = ++r->tick;
        r->hits++;
        pthread_mutex_unlock(&r->lock);
        return 0;
    }
    if (e->busy) { /* a load or a write of the name is under way: wait for its end */
        l->next = e->waiting;
        e->waiting = l;
        pthread_mutex_unlock(&r->lock);
        return SDFD_LOOKUP_PENDING;
    }
    if (e->pinned) {
        pthread_mutex_unlock(&r->lock);
        return not_found(l);
    }
    e->busy = 1;
    pthread_mutex_unlock(&r->lock);
    int rc = check(ld, e, l);
    pthread_mutex_lock(&r->lock);
    if (rc == NEED_LOAD && !enqueue(ld, e)) {
        /* A replaced item keeps answering (this lookup too) until its successor is in. */
        e->reloading = e->resident;
        if (e->reloading && (l->item = sdfd_resident_get(r, e))) {
            rc = 0;
        } else {
            l->next = e->waiting;
            e->waiting = l;
            rc = SDFD_LOOKUP_PENDING;
        }
        if (!rc)
            e->used = ++r->tick;
        pthread_mutex_unlock(&r->lock);
        return rc;
    }
    if (rc == NEED_LOAD)
        rc = answer(l, SDFD_EUNAVAILABLE, "the server is shutting down");
    else if (!rc)
        e->used = ++r->tick;
    sdfd_lookup *waiting = sdfd_resident_unclaim(r, e);
    pthread_mutex_unlock(&r->lock);
    sdfd_loader_retry(ld, waiting);
    return rc;
}

void sdfd_loader_retry(sdfd_loader *ld, sdfd_lookup *waiting)
{
    for (sdfd_lookup *l = waiting, *next; l; l = next) {
        next = l->next; /* queued again, or answered and reused */
        if (sdfd_loader_lookup(ld, l) != SDFD_LOOKUP_PENDING)
            l->done(l);
    }
}

/* ---- waiting on the caller's thread ------------------------------------------------------ */

typedef struct sync_wait {
    pthread_mutex_t lock;
    pthread_cond_t cond;
    int done;
} sync_wait;

static void wake(sdfd_lookup *l)
{
    sync_wait *w = l->user;
    pthread_mutex_lock(&w->lock);
    w->done = 1;
    pthread_cond_signal(&w->cond);
    pthread_mutex_unlock(&w->lock);
}

int sdfd_loader_lookup_wait(sdfd_loader *ld, sdfd_lookup *l)
{
    sync_wait w = {.done = 0};
    pthread_mutex_init(&w.lock, NULL);
    pthread_cond_init(&w.cond, NULL);
    l->done = wake;
    l->user = &w;
    int rc = sdfd_loader_lookup(ld, l);
    if (rc == SDFD_LOOKUP_PENDING) {
        pthread_mutex_lock(&w.lock);
        while (!w.done)
            pthread_cond_wait(&w.cond, &w.lock);
        pthread_mutex_unlock(&w.lock);
        rc = l->status;
    }
    pthread_cond_destroy(&w.cond);
    pthread_mutex_destroy(&w.lock);
    return rc;
}
