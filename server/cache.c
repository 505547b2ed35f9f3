/* cache.c - items in memory as a cache of the store (see cache.h). One table of the names
 * this process has looked up, under one mutex; the slow parts (file reads, parsing, BVH
 * builds, writes) run outside it with the name marked busy, which is what makes other
 * lookups of that name wait while leaving every other name free. */
#include "cache.h"

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "batcher.h" /* sdfd_now */
#include "errors.h"
#include "log.h"

typedef struct entry {
    sdfd_item_kind kind;
    char name[SDFD_MAX_NAME + 1];
    int busy;           /* a load or write of this name is under way */
    int resident;       /* in the registry / the volumes, as the store's version `hash` */
    int pinned;         /* from the flags: memory only */
    uint64_t hash;
    sdfd_stamp stamp;   /* the sidecar's, when last read */
    double checked;     /* when the sidecar was last compared */
    unsigned long long used;
} entry;

struct sdfd_cache {
    pthread_mutex_t lock;
    pthread_cond_t idle; /* an entry stopped being busy */
    sdfd_store *store;
    sdfd_registry *registry;
    sdfd_volumes *volumes;
    sdfd_metrics *metrics;
    size_t budget, max_triangles;
    entry **entries;
    size_t count, cap;
    unsigned long long tick, loads, evictions, quarantined;
};

static const char *const kind_names[] = {"mesh", "volume"};

sdfd_cache *sdfd_cache_create(sdfd_store *store, sdfd_registry *registry,
                              sdfd_volumes *volumes, sdfd_metrics *metrics,
                              size_t max_resident_bytes, size_t max_triangles)
{
    sdfd_cache *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    pthread_mutex_init(&c->lock, NULL);
    pthread_cond_init(&c->idle, NULL);
    c->store = store, c->registry = registry, c->volumes = volumes, c->metrics = metrics;
    c->budget = max_resident_bytes, c->max_triangles = max_triangles;
    return c;
}

void sdfd_cache_destroy(sdfd_cache *c)
{
    if (!c)
        return;
    for (size_t i = 0; i < c->count; i++)
        free(c->entries[i]);
    free(c->entries);
    sdfd_store_close(c->store);
    pthread_cond_destroy(&c->idle);
    pthread_mutex_destroy(&c->lock);
    free(c);
}

int sdfd_cache_has_store(const sdfd_cache *c) { return c->store != NULL; }

int sdfd_cache_probe(sdfd_cache *c) { return c->store ? sdfd_store_probe(c->store) : 0; }

/* ---- the table --------------------------------------------------------------------------- */

/* Under the lock: the entry of (kind, name), created if `create`; NULL if absent or no
 * memory. */
static entry *find(sdfd_cache *c, sdfd_item_kind kind, const char *name, int create)
{
    for (size_t i = 0; i < c->count; i++)
        if (c->entries[i]->kind == kind && !strcmp(c->entries[i]->name, name))
            return c->entries[i];
    if (!create)
        return NULL;
    if (c->count == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 32;
        entry **grown = realloc(c->entries, cap * sizeof *grown);
        if (!grown)
            return NULL;
        c->entries = grown, c->cap = cap;
    }
    entry *e = calloc(1, sizeof *e);
    if (!e)
        return NULL;
    e->kind = kind;
    snprintf(e->name, sizeof e->name, "%s", name);
    c->entries[c->count++] = e;
    return e;
}

/* Under the lock: wait until (kind, name) is not busy, then mark it busy. */
static entry *claim(sdfd_cache *c, sdfd_item_kind kind, const char *name)
{
    entry *e;
    while ((e = find(c, kind, name, 1)) && e->busy)
        pthread_cond_wait(&c->idle, &c->lock);
    if (e)
        e->busy = 1;
    return e;
}

static void unclaim(sdfd_cache *c, entry *e)
{
    e->busy = 0;
    pthread_cond_broadcast(&c->idle);
}

static size_t mesh_bytes(const sdf_mesh *m)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    /* The index, and the welded vertices and triangles (three floats, three indices). */
    return r.index_bytes + 12 * r.vertices + 12 * r.triangles;
}

/* What the registry and the volumes hold now (pinned meshes too). */
static size_t resident_bytes(sdfd_cache *c)
{
    sdfd_entry *list;
    size_t n = sdfd_registry_list(c->registry, &list), bytes = 0, running, queued, vbytes;
    for (size_t i = 0; i < n; i++)
        bytes += mesh_bytes(list[i].mesh);
    sdfd_registry_free_list(list, n);
    sdfd_volumes_usage(c->volumes, &vbytes, &running, &queued);
    return bytes + vbytes;
}

static void drop(sdfd_cache *c, entry *e)
{
    if (e->kind == SDFD_ITEM_MESH)
        sdfd_registry_remove(c->registry, e->name);
    else
        sdfd_volumes_remove(c->volumes, e->name);
    e->resident = 0;
}

/* Under the lock: the least recently used item that may leave memory (of `kind`, or any
 * kind when kind < 0), other than `keep`. */
static entry *eviction_candidate(sdfd_cache *c, int kind, const entry *keep)
{
    entry *best = NULL;
    for (size_t i = 0; i < c->count; i++) {
        entry *e = c->entries[i];
        if (e != keep && e->resident && !e->pinned && !e->busy &&
            (kind < 0 || (int)e->kind == kind) && (!best || e->used < best->used))
            best = e;
    }
    return best;
}

/* Under the lock: evict one item (of `kind`, or any); 0, or -1 when there is none. */
static int evict_one(sdfd_cache *c, int kind, const entry *keep)
{
    entry *victim = eviction_candidate(c, kind, keep);
    if (!victim)
        return -1;
    drop(c, victim);
    c->evictions++;
    sdfd_log("info", "store_evicted", "%s %s left memory (least recently used)",
             kind_names[victim->kind], victim->name);
    return 0;
}

/* Under the lock: keep the resident bytes within the budget, `keep` aside. */
static void enforce_budget(sdfd_cache *c, const entry *keep)
{
    while (c->budget && resident_bytes(c) > c->budget && !evict_one(c, -1, keep))
        ;
}

/* Make `item` (a mesh, or a stored volume; the caller's reference stays its own) resident
 * as e, evicting others of its kind while the registry's or the volumes' own limits refuse
 * it. 0 or SDF_ELIMIT. The lock is held. */
static int make_resident(sdfd_cache *c, entry *e, void *item)
{
    for (;;) {
        int rc, replaced;
        if (e->kind == SDFD_ITEM_MESH) {
            rc = sdfd_registry_put(c->registry, e->name, sdf_mesh_retain(item), &replaced);
        } else {
            sdfd_volume_retain(item);
            rc = sdfd_volumes_put_stored(c->volumes, item, &replaced);
        }
        if (rc != SDF_ELIMIT || evict_one(c, (int)e->kind, e)) {
            e->resident = !rc;
            return rc;
        }
    }
}

static void *get_resident(sdfd_cache *c, const entry *e)
{
    if (e->kind == SDFD_ITEM_MESH)
        return sdfd_registry_get(c->registry, e->name, strlen(e->name));
    return sdfd_volumes_get(c->volumes, e->name);
}

static void release_item(sdfd_item_kind kind, void *item)
{
    if (kind == SDFD_ITEM_MESH)
        sdf_mesh_release(item);
    else
        sdfd_volume_release(item);
}

/* ---- loading ----------------------------------------------------------------------------- */

static int same_stamp(const sdfd_stamp *a, const sdfd_stamp *b)
{
    return a->dev == b->dev && a->ino == b->ino && a->size == b->size &&
           a->mtime_ns == b->mtime_ns;
}

/* Parse a data file into a mesh or a stored volume (with the sidecar's info). */
static int parse_item(sdfd_cache *c, const sdfd_sidecar *meta, const void *data, void **out,
                      char *why, size_t cap)
{
    sdf_diag diag = {0};
    int rc;
    if (!strcmp(meta->format, "exr")) {
        sdf_volume *volume = NULL;
        sdfd_stored_volume *s = calloc(1, sizeof *s);
        rc = s ? sdf_volume_load_exr_memory(data, meta->bytes, &volume, &diag) : SDF_ENOMEM;
        if (!rc) {
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
        } else {
            free(s);
        }
    } else {
        sdf_mesh_options opts = {.max_triangles = c->max_triangles};
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

/* Read and parse e's item from the store (e busy, the lock not held): 0 with *item (one
 * reference) and the sidecar's hash and stamp; or an error. A damaged item is quarantined,
 * unless its sidecar changed while it was read (another replica's write: read again). */
static int load(sdfd_cache *c, entry *e, void **item, uint64_t *hash, sdfd_stamp *stamp,
                char *msg, size_t cap)
{
    char why[400];
    for (int attempt = 0;; attempt++) {
        double t0 = sdfd_now();
        sdfd_sidecar meta;
        void *data = NULL;
        int rc = sdfd_store_read(c->store, e->kind, e->name, &meta, &data, stamp, why, sizeof why);
        if (!rc) {
            rc = parse_item(c, &meta, data, item, why, sizeof why) ? SDF_EFORMAT : 0;
            *hash = meta.hash;
        }
        free(data);
        free(meta.info);
        if (!rc) {
            double seconds = sdfd_now() - t0;
            sdfd_metrics_store_load(c->metrics, seconds);
            sdfd_log("info", "store_loaded", "%s %s from the store in %.3f s", kind_names[e->kind],
                     e->name, seconds);
            return 0;
        }
        if (rc != SDF_EFORMAT) {
            if (rc == SDF_ENOTFOUND)
                snprintf(msg, cap, "no %s named '%s'", kind_names[e->kind], e->name);
            else
                snprintf(msg, cap, "%s", why);
            return rc;
        }
        sdfd_stamp now;
        char ignored[64];
        int moved = sdfd_store_stat(c->store, e->kind, e->name, &now, ignored, sizeof ignored) ||
                    !same_stamp(&now, stamp);
        if (moved && attempt < 5)
            continue;
        sdfd_store_quarantine(c->store, e->kind, e->name, why);
        pthread_mutex_lock(&c->lock);
        c->quarantined++;
        pthread_mutex_unlock(&c->lock);
        snprintf(msg, cap, "no %s named '%s' (its files in the store were damaged and are "
                 "quarantined: %.200s)", kind_names[e->kind], e->name, why);
        return SDF_ENOTFOUND;
    }
}

/* Under the lock: e is no longer busy; an entry of nothing in memory is forgotten (so
 * lookups of names that do not exist cannot grow the table). Waiters find their entry again
 * by name when they wake. */
static void release_claim(sdfd_cache *c, entry *e)
{
    unclaim(c, e);
    if (e->resident || e->pinned)
        return;
    for (size_t i = 0; i < c->count; i++)
        if (c->entries[i] == e) {
            c->entries[i] = c->entries[--c->count];
            free(e);
            return;
        }
}

/* Bring e up to date with the store (e busy, the lock not held) and return its item,
 * retained, in *out. */
static int refresh(sdfd_cache *c, entry *e, void **out, char *msg, size_t cap)
{
    sdfd_stamp stamp;
    int rc = sdfd_store_stat(c->store, e->kind, e->name, &stamp, msg, cap);
    pthread_mutex_lock(&c->lock);
    int resident = e->resident;
    uint64_t hash = e->hash;
    if (rc == SDF_ENOTFOUND && resident)
        drop(c, e); /* deleted, on this replica or another */
    /* Serve what is in memory: unchanged, or a store that cannot be read just now. */
    int keep = resident && (rc == SDFD_EUNAVAILABLE || (!rc && same_stamp(&stamp, &e->stamp)));
    void *present = keep ? get_resident(c, e) : NULL;
    if (keep && !present) /* a bake's volume that did not fit after all */
        keep = resident = e->resident = 0;
    release_item(e->kind, present);
    pthread_mutex_unlock(&c->lock);
    if (rc && !keep) {
        if (rc == SDF_ENOTFOUND)
            snprintf(msg, cap, "no %s named '%s'", kind_names[e->kind], e->name);
        return rc;
    }
    int stamped = !rc; /* `stamp` is the sidecar's now */
    rc = 0;
    if (!keep && resident) { /* rewritten: with the same content? */
        sdfd_sidecar meta;
        char why[64];
        keep = !sdfd_store_read(c->store, e->kind, e->name, &meta, NULL, &stamp, why,
                                sizeof why) && meta.hash == hash;
        free(meta.info);
    }
    void *item = NULL;
    if (!keep && (rc = load(c, e, &item, &hash, &stamp, msg, cap))) {
        pthread_mutex_lock(&c->lock);
        if (e->resident && rc == SDF_ENOTFOUND)
            drop(c, e);
        pthread_mutex_unlock(&c->lock);
        return rc;
    }
    pthread_mutex_lock(&c->lock);
    e->checked = sdfd_now();
    if (stamped)
        e->stamp = stamp, e->hash = hash;
    if (item) {
        c->loads++;
        if ((rc = make_resident(c, e, item)))
            snprintf(msg, cap, "%s %s does not fit in memory beside the items in use "
                     "(--max-meshes, --max-triangles, --max-volumes, --max-volume-bytes)",
                     kind_names[e->kind], e->name);
        else
            enforce_budget(c, e);
    } else if (!(item = get_resident(c, e))) {
        e->resident = 0;
        rc = SDF_ENOTFOUND;
        snprintf(msg, cap, "no %s named '%s'", kind_names[e->kind], e->name);
    }
    pthread_mutex_unlock(&c->lock);
    if (rc) {
        release_item(e->kind, item);
        return rc;
    }
    *out = item;
    return 0;
}

static int lookup(sdfd_cache *c, sdfd_item_kind kind, const char *name, size_t n, void **out,
                  char *msg, size_t cap)
{
    entry e0 = {.kind = kind}, *e;
    snprintf(e0.name, sizeof e0.name, "%.*s", (int)n, name);
    if (!c->store) {
        *out = get_resident(c, &e0);
        if (!*out)
            snprintf(msg, cap, "no %s named '%s'", kind_names[kind], e0.name);
        return *out ? 0 : SDF_ENOTFOUND;
    }
    *out = NULL;
    pthread_mutex_lock(&c->lock);
    if (!(e = claim(c, kind, e0.name))) {
        pthread_mutex_unlock(&c->lock);
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    if (e->pinned || (e->resident && sdfd_now() - e->checked < SDFD_CACHE_RECHECK_SECONDS))
        *out = get_resident(c, e);
    int rc = 0;
    if (!*out && !e->pinned) {
        pthread_mutex_unlock(&c->lock);
        rc = refresh(c, e, out, msg, cap);
        pthread_mutex_lock(&c->lock);
    } else if (!*out) {
        rc = SDF_ENOTFOUND;
        snprintf(msg, cap, "no %s named '%s'", kind_names[kind], e0.name);
    }
    if (!rc)
        e->used = ++c->tick;
    release_claim(c, e);
    pthread_mutex_unlock(&c->lock);
    return rc;
}

int sdfd_cache_mesh(sdfd_cache *c, const char *name, size_t n, sdf_mesh **out, char *msg,
                    size_t cap)
{
    void *item;
    int rc = lookup(c, SDFD_ITEM_MESH, name, n, &item, msg, cap);
    *out = item;
    return rc;
}

int sdfd_cache_volume(sdfd_cache *c, const char *name, size_t n, sdfd_stored_volume **out,
                      char *msg, size_t cap)
{
    void *item;
    int rc = lookup(c, SDFD_ITEM_VOLUME, name, n, &item, msg, cap);
    *out = item;
    return rc;
}
/* ---- writes ------------------------------------------------------------------------------ */

cJSON *sdfd_cache_volume_json(const sdfd_stored_volume *s)
{
    char text[1024];
    cJSON *o =
        sdf_volume_describe_json(s->volume, text, sizeof text) > 0 ? cJSON_Parse(text) : NULL;
    if (!o)
        o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", s->name);
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    cJSON_AddStringToObject(o, "job", s->job);
    cJSON_AddNumberToObject(o, "bake_seconds", s->bake_seconds);
    return o;
}

/* What a listing shows of a mesh, kept in its sidecar. */
static char *mesh_info(const sdf_mesh *m)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "triangles", (double)r.triangles);
    cJSON_AddBoolToObject(o, "closed", r.closed);
    cJSON_AddStringToObject(o, "sign", sdf_sign_name(r.auto_sign));
    char *text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return text;
}

/* Write `item` (a mesh or stored volume, the caller's reference) to the store, then make it
 * resident. */
static int put(sdfd_cache *c, sdfd_item_kind kind, const char *name, void *item,
               const void *file, size_t n, const char *format, char *info, int *replaced,
               char *msg, size_t cap, int baked)
{
    if (strlen(name) > SDFD_STORE_MAX_NAME) {
        free(info);
        snprintf(msg, cap, "with --data-dir a name is at most %d characters (the file system's "
                 "limit on a file name)", SDFD_STORE_MAX_NAME);
        return SDF_EINVAL;
    }
    pthread_mutex_lock(&c->lock);
    entry *e = claim(c, kind, name);
    pthread_mutex_unlock(&c->lock);
    if (!e) {
        free(info);
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    sdfd_sidecar meta = {.info = info};
    snprintf(meta.name, sizeof meta.name, "%s", name);
    snprintf(meta.format, sizeof meta.format, "%s", format);
    sdfd_stamp stamp;
    int existed = 0, rc = sdfd_store_write(c->store, kind, &meta, file, n, &existed, &stamp, msg,
                                           cap);
    free(info);
    pthread_mutex_lock(&c->lock);
    if (!rc) {
        *replaced = existed || e->pinned;
        e->pinned = 0;
        e->hash = meta.hash, e->stamp = stamp, e->checked = sdfd_now(), e->used = ++c->tick;
        /* In the store, it is the client's: memory is a cache, so not fitting there is no
         * error (the next use loads it, and says why if it still cannot fit). */
        if (baked) /* the bake's job puts it in memory next */
            e->resident = 1;
        else if (make_resident(c, e, item))
            sdfd_log("warn", "store_put", "%s %s is stored but not kept in memory: over the "
                     "limits", kind_names[kind], name);
        else
            enforce_budget(c, e);
    }
    release_claim(c, e);
    pthread_mutex_unlock(&c->lock);
    return rc;
}

int sdfd_cache_put_mesh(sdfd_cache *c, const char *name, sdf_mesh *mesh, const void *file,
                        size_t n, int *replaced, char *msg, size_t cap)
{
    if (!c->store) {
        int rc = sdfd_registry_put(c->registry, name, mesh, replaced);
        if (rc == SDF_ELIMIT)
            snprintf(msg, cap, "loading it would exceed --max-meshes or --max-triangles");
        return rc;
    }
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    int rc = put(c, SDFD_ITEM_MESH, name, mesh, file, n, sdf_format_name(r.format),
                 mesh_info(mesh), replaced, msg, cap, 0);
    sdf_mesh_release(mesh);
    return rc;
}

int sdfd_cache_put_volume(sdfd_cache *c, const char *name, sdf_volume *volume,
                          const void *file, size_t n, int *replaced, char *msg, size_t cap)
{
    if (!c->store) {
        int rc = sdfd_volumes_put(c->volumes, name, volume, "", replaced);
        if (rc)
            snprintf(msg, cap, "storing it would exceed --max-volumes or --max-volume-bytes");
        return rc;
    }
    sdfd_stored_volume *s = calloc(1, sizeof *s);
    if (!s) {
        sdf_volume_destroy(volume);
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    atomic_init(&s->refs, 1);
    s->volume = volume;
    snprintf(s->name, sizeof s->name, "%s", name);
    cJSON *o = sdfd_cache_volume_json(s);
    char *info = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    int rc = put(c, SDFD_ITEM_VOLUME, name, s, file, n, "exr", info, replaced, msg, cap, 0);
    sdfd_volume_release(s);
    return rc;
}

static int remove_item(sdfd_cache *c, sdfd_item_kind kind, const char *name, char *msg,
                       size_t cap)
{
    pthread_mutex_lock(&c->lock);
    entry *e = claim(c, kind, name);
    pthread_mutex_unlock(&c->lock);
    if (!e) {
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    int rc = strlen(name) > SDFD_STORE_MAX_NAME
                 ? SDF_ENOTFOUND
                 : sdfd_store_remove(c->store, kind, name, msg, cap);
    pthread_mutex_lock(&c->lock);
    if (e->pinned && rc == SDF_ENOTFOUND)
        rc = 0;
    if (rc != SDFD_EUNAVAILABLE && (e->resident || e->pinned))
        drop(c, e);
    e->pinned = 0;
    release_claim(c, e);
    pthread_mutex_unlock(&c->lock);
    if (rc == SDF_ENOTFOUND)
        snprintf(msg, cap, "no %s named '%s'", kind_names[kind], name);
    return rc;
}

int sdfd_cache_remove_mesh(sdfd_cache *c, const char *name, char *msg, size_t cap)
{
    if (!c->store) {
        int rc = sdfd_registry_remove(c->registry, name);
        if (rc)
            snprintf(msg, cap, "no mesh named '%s'", name);
        return rc;
    }
    return remove_item(c, SDFD_ITEM_MESH, name, msg, cap);
}

int sdfd_cache_remove_volume(sdfd_cache *c, const char *name, char *msg, size_t cap)
{
    if (!c->store) {
        int rc = sdfd_volumes_remove(c->volumes, name);
        if (rc)
            snprintf(msg, cap, "no volume named '%s'", name);
        return rc;
    }
    return remove_item(c, SDFD_ITEM_VOLUME, name, msg, cap);
}

/* ---- bake jobs --------------------------------------------------------------------------- */

/* A finished bake's volume, into the store before its job says done. */
static int keep_baked(void *user, const sdfd_stored_volume *s, char *err, size_t cap)
{
    sdfd_cache *c = user;
    void *exr = NULL;
    size_t n = 0;
    sdf_diag diag = {0};
    if (sdf_volume_save_memory(s->volume, SDF_VOLUME_EXR, &exr, &n, &diag)) {
        snprintf(err, cap, "cannot encode the volume for the store: %s", diag.message);
        return SDFD_EUNAVAILABLE;
    }
    cJSON *o = sdfd_cache_volume_json(s);
    char *info = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    int replaced, rc = put(c, SDFD_ITEM_VOLUME, s->name, (void *)s, exr, n, "exr", info,
                           &replaced, err, cap, 1);
    free(exr);
    return rc;
}

static char *job_record(const sdfd_job_status *s)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "id", s->id);
    cJSON_AddStringToObject(o, "state", sdfd_job_state_name(s->state));
    cJSON_AddStringToObject(o, "mesh", s->mesh);
    cJSON_AddStringToObject(o, "volume", s->volume);
    cJSON_AddNumberToObject(o, "seconds", s->seconds);
    cJSON_AddNumberToObject(o, "error", s->error);
    cJSON_AddStringToObject(o, "message", s->message);
    char *text = cJSON_PrintUnformatted(o);
    cJSON_Delete(o);
    return text;
}

/* A record back into a status; 0 or -1. */
static int parse_job(const char *text, sdfd_job_status *out)
{
    cJSON *o = cJSON_Parse(text);
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(o, "id"),
                *state = cJSON_GetObjectItemCaseSensitive(o, "state"),
                *mesh = cJSON_GetObjectItemCaseSensitive(o, "mesh"),
                *volume = cJSON_GetObjectItemCaseSensitive(o, "volume"),
                *seconds = cJSON_GetObjectItemCaseSensitive(o, "seconds"),
                *error = cJSON_GetObjectItemCaseSensitive(o, "error"),
                *message = cJSON_GetObjectItemCaseSensitive(o, "message");
    int ok = cJSON_IsString(id) && cJSON_IsString(state) && cJSON_IsString(mesh) &&
             cJSON_IsString(volume) && cJSON_IsNumber(seconds) && cJSON_IsNumber(error) &&
             cJSON_IsString(message);
    memset(out, 0, sizeof *out);
    int found = -1;
    for (int s = SDFD_JOB_QUEUED; ok && s <= SDFD_JOB_CANCELED; s++)
        if (!strcmp(state->valuestring, sdfd_job_state_name((sdfd_job_state)s)))
            found = s;
    ok = ok && found >= 0;
    if (ok) {
        out->state = (sdfd_job_state)found;
        snprintf(out->id, sizeof out->id, "%s", id->valuestring);
        snprintf(out->mesh, sizeof out->mesh, "%s", mesh->valuestring);
        snprintf(out->volume, sizeof out->volume, "%s", volume->valuestring);
        snprintf(out->message, sizeof out->message, "%s", message->valuestring);
        out->seconds = seconds->valuedouble;
        out->error = (int)error->valuedouble;
        out->progress = out->state == SDFD_JOB_DONE;
    }
    cJSON_Delete(o);
    return ok ? 0 : -1;
}

static int job_started(void *user, const sdfd_job_status *s)
{
    sdfd_cache *c = user;
    int fd = sdfd_store_lock_job(c->store, s->id); /* before the record says queued */
    char *text = job_record(s);
    if (text)
        sdfd_store_write_job(c->store, s->id, text);
    free(text);
    return fd;
}

static void job_ended(void *user, const sdfd_job_status *s, int token)
{
    sdfd_cache *c = user;
    char *text = job_record(s);
    if (text)
        sdfd_store_write_job(c->store, s->id, text);
    free(text);
    sdfd_store_unlock_job(c->store, s->id, token);
}

static void job_forgotten(void *user, const char *id)
{
    sdfd_cache *c = user;
    sdfd_store_remove_job(c->store, id);
}

int sdfd_cache_job(sdfd_cache *c, const char *id, sdfd_job_status *out)
{
    char *text = c->store ? sdfd_store_read_job(c->store, id) : NULL;
    int rc = text && !parse_job(text, out) && !strcmp(out->id, id) ? 0 : SDF_ENOTFOUND;
    free(text);
    return rc;
}

/* Jobs the store says are queued or running, but whose owner is gone (their lock is free):
 * a restart interrupted them. They end failed, in the store and in this process's list. */
static void restore_jobs(sdfd_cache *c)
{
    char(*ids)[64];
    size_t n = sdfd_store_job_ids(c->store, &ids);
    for (size_t i = 0; i < n; i++) {
        sdfd_job_status s;
        char *text = sdfd_store_read_job(c->store, ids[i]);
        int ok = text && !parse_job(text, &s) && !strcmp(s.id, ids[i]);
        free(text);
        if (!ok || (s.state != SDFD_JOB_QUEUED && s.state != SDFD_JOB_RUNNING))
            continue;
        int fd = sdfd_store_lock_job(c->store, s.id);
        if (fd < 0)
            continue; /* a live replica runs it */
        /* Its owner may have ended it (record, then unlock) since the record was read. */
        text = sdfd_store_read_job(c->store, ids[i]);
        ok = text && !parse_job(text, &s) && !strcmp(s.id, ids[i]) &&
             (s.state == SDFD_JOB_QUEUED || s.state == SDFD_JOB_RUNNING);
        free(text);
        if (!ok) {
            sdfd_store_unlock_job(c->store, ids[i], fd);
            continue;
        }
        s.state = SDFD_JOB_FAILED;
        s.error = SDFD_EUNAVAILABLE;
        snprintf(s.message, sizeof s.message, "interrupted: the sdfd running this bake stopped "
                 "(a restart or a crash) before it finished; bake again");
        text = job_record(&s);
        if (text)
            sdfd_store_write_job(c->store, s.id, text);
        free(text);
        sdfd_store_unlock_job(c->store, s.id, fd);
        sdfd_volumes_add_finished(c->volumes, &s);
        sdfd_log("warn", "bake_interrupted", "job %s (%s -> %s) was interrupted by a restart",
                 s.id, s.mesh, s.volume);
    }
    free(ids);
}

/* ---- start, listings, statistics --------------------------------------------------------- */

void sdfd_cache_pin(sdfd_cache *c, const char *name)
{
    pthread_mutex_lock(&c->lock);
    entry *e = find(c, SDFD_ITEM_MESH, name, 1);
    if (e)
        e->pinned = 1, e->resident = 1;
    pthread_mutex_unlock(&c->lock);
}

void sdfd_cache_start(sdfd_cache *c)
{
    if (!c->store)
        return;
    sdfd_volumes_hooks hooks = {c, keep_baked, job_started, job_ended, job_forgotten};
    sdfd_volumes_set_hooks(c->volumes, &hooks);
    restore_jobs(c);
    for (int kind = SDFD_ITEM_MESH; kind <= SDFD_ITEM_VOLUME; kind++) {
        char(*names)[SDFD_MAX_NAME + 1];
        size_t n = sdfd_store_scan(c->store, kind, &names);
        for (size_t i = 0; i < n; i++) {
            char msg[512];
            void *item = NULL;
            if (c->budget && resident_bytes(c) >= c->budget) {
                /* Over the budget: the sidecar is checked now, the data when first used. */
                sdfd_sidecar meta;
                sdfd_stamp stamp;
                if (sdfd_store_read(c->store, kind, names[i], &meta, NULL, &stamp, msg,
                                    sizeof msg) == SDF_EFORMAT)
                    sdfd_store_quarantine(c->store, kind, names[i], msg);
                free(meta.info);
                continue;
            }
            if (!lookup(c, kind, names[i], strlen(names[i]), &item, msg, sizeof msg))
                release_item(kind, item);
            else
                sdfd_log("error", "store_load", "%s", msg);
        }
        free(names);
    }
}

static int by_summary_name(const void *a, const void *b)
{
    return strcmp(((const sdfd_mesh_summary *)a)->name, ((const sdfd_mesh_summary *)b)->name);
}

/* Append the summary of a mesh from its sidecar's info. */
static int summary_from_info(const char *name, const char *info, sdfd_mesh_summary *out)
{
    cJSON *o = cJSON_Parse(info ? info : "");
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(o, "triangles"),
                *closed = cJSON_GetObjectItemCaseSensitive(o, "closed"),
                *sign = cJSON_GetObjectItemCaseSensitive(o, "sign");
    int ok = cJSON_IsNumber(t) && cJSON_IsBool(closed) && cJSON_IsString(sign);
    if (ok) {
        snprintf(out->name, sizeof out->name, "%s", name);
        out->triangles = (size_t)t->valuedouble;
        out->closed = cJSON_IsTrue(closed);
        ok = !sdf_sign_from_name(sign->valuestring, &out->sign);
    }
    cJSON_Delete(o);
    return ok ? 0 : -1;
}

size_t sdfd_cache_list_meshes(sdfd_cache *c, sdfd_mesh_summary **out)
{
    sdfd_entry *list;
    size_t n = sdfd_registry_list(c->registry, &list), count = 0;
    char(*names)[SDFD_MAX_NAME + 1] = NULL;
    size_t stored = c->store ? sdfd_store_names(c->store, SDFD_ITEM_MESH, &names) : 0;
    *out = malloc((n + stored + 1) * sizeof **out);
    for (size_t i = 0; *out && i < n; i++) {
        int pinned = 1;
        if (c->store) {
            pthread_mutex_lock(&c->lock);
            entry *e = find(c, SDFD_ITEM_MESH, list[i].name, 0);
            pinned = e && e->pinned;
            pthread_mutex_unlock(&c->lock);
        }
        if (!pinned)
            continue; /* listed from the store below */
        sdf_mesh_report r;
        sdf_mesh_get_report(list[i].mesh, &r);
        sdfd_mesh_summary *s = &(*out)[count++];
        snprintf(s->name, sizeof s->name, "%s", list[i].name);
        s->triangles = r.triangles, s->closed = r.closed, s->sign = r.auto_sign;
    }
    sdfd_registry_free_list(list, n);
    for (size_t i = 0; *out && i < stored; i++) {
        sdfd_sidecar meta;
        sdfd_stamp stamp;
        char why[64];
        int dup = 0;
        for (size_t k = 0; k < count; k++)
            dup |= !strcmp((*out)[k].name, names[i]);
        if (!dup && !sdfd_store_read(c->store, SDFD_ITEM_MESH, names[i], &meta, NULL, &stamp, why,
                                     sizeof why) &&
            !summary_from_info(names[i], meta.info, &(*out)[count]))
            count++;
        free(meta.info);
    }
    free(names);
    if (*out)
        qsort(*out, count, sizeof **out, by_summary_name);
    return *out ? count : 0;
}

cJSON *sdfd_cache_list_volumes(sdfd_cache *c)
{
    if (!c->store)
        return NULL;
    char(*names)[SDFD_MAX_NAME + 1] = NULL;
    size_t n = sdfd_store_names(c->store, SDFD_ITEM_VOLUME, &names);
    cJSON *arr = cJSON_CreateArray();
    for (size_t i = 0; i < n; i++) {
        sdfd_sidecar meta;
        sdfd_stamp stamp;
        char why[64];
        if (!sdfd_store_read(c->store, SDFD_ITEM_VOLUME, names[i], &meta, NULL, &stamp, why,
                             sizeof why)) {
            cJSON *o = cJSON_Parse(meta.info);
            if (cJSON_IsObject(o))
                cJSON_AddItemToArray(arr, o);
            else
                cJSON_Delete(o);
        }
        free(meta.info);
    }
    free(names);
    return arr;
}

void sdfd_cache_stats_get(sdfd_cache *c, sdfd_cache_stats *out)
{
    pthread_mutex_lock(&c->lock);
    *out = (sdfd_cache_stats){resident_bytes(c), c->budget, c->loads, c->evictions,
                              c->quarantined};
    pthread_mutex_unlock(&c->lock);
}
