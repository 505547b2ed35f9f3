/* cache.c - items in memory as a cache of the store (see cache.h): the lookups, writes,
 * start and listings. What is in memory is resident.c's table; reading an item that is not
 * is loader.c's, on its own threads; bake jobs' records are jobrecords.c's. */
#include "state/cache.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/errors.h"
#include "core/log.h"
#include "state/batcher.h" /* sdfd_now */
#include "state/jobrecords.h"
#include "state/surface.h"

struct sdfd_cache {
    sdfd_resident r; /* the table: its lock guards what the functions below read of it */
    sdfd_loader *loader; /* with a backing */
    sdfd_backing b;      /* b.ops NULL: memory only */
    sdfd_store *store;   /* the file store's job records, or NULL */
    sdfd_registry *registry;
    sdfd_volumes *volumes;
    size_t max_triangles;
};

/* Another replica changed (kind, name): the next lookup compares again. */
static void changed(void *arg, sdfd_item_kind kind, const char *name)
{
    sdfd_cache *c = arg;
    pthread_mutex_lock(&c->r.lock);
    sdfd_cached *e = sdfd_resident_find(&c->r, kind, name, 0);
    if (e)
        e->changes++, e->checked = 0;
    pthread_mutex_unlock(&c->r.lock);
}

int sdfd_cache_put_surface(sdfd_cache *c, const char *name, const sdf_volume *v,
                           const sdf_extract_options *opts, int *replaced, sdf_mesh **mesh,
                           char *msg, size_t cap)
{
    void *bytes;
    size_t n;
    sdf_mesh *made;
    int rc = sdfd_surface_mesh(v, opts, c->max_triangles, &bytes, &n, &made, msg, cap);
    if (rc)
        return rc;
    if (mesh)
        *mesh = sdf_mesh_retain(made);
    rc = sdfd_cache_put(c, SDFD_ITEM_MESH, name, made, bytes, n, replaced, msg, cap);
    free(bytes);
    if (rc && mesh) {
        sdf_mesh_release(*mesh);
        *mesh = NULL;
    }
    return rc;
}

/* A bake's surface stored as the mesh it names (volumes.h, the surface sink). */
static int store_surface(void *user, const char *name, const sdf_volume *v, int threads,
                         char *err, size_t cap)
{
    sdf_extract_options o = {.threads = threads};
    int replaced;
    return sdfd_cache_put_surface(user, name, v, &o, &replaced, NULL, err, cap);
}

sdfd_cache *sdfd_cache_create(const sdfd_backing *backing, sdfd_registry *registry,
                              sdfd_volumes *volumes, sdfd_metrics *metrics,
                              size_t max_resident_bytes, size_t max_triangles)
{
    sdfd_cache *c = calloc(1, sizeof *c);
    if (!c) {
        if (backing)
            backing->ops->close(backing->self);
        return NULL;
    }
    sdfd_resident_init(&c->r, registry, volumes, max_resident_bytes);
    c->registry = registry, c->volumes = volumes, c->max_triangles = max_triangles;
    sdfd_volumes_set_surface_sink(volumes, store_surface, c);
    if (backing) {
        c->b = *backing, c->store = backing->store;
        if (!(c->loader = sdfd_loader_create(&c->b, &c->r, metrics, max_triangles))) {
            sdfd_cache_destroy(c);
            return NULL;
        }
        c->b.ops->watch(c->b.self, changed, c);
    }
    return c;
}

void sdfd_cache_stop_loads(sdfd_cache *c)
{
    if (c->loader)
        sdfd_loader_stop(c->loader);
}

void sdfd_cache_destroy(sdfd_cache *c)
{
    if (!c)
        return;
    sdfd_loader_destroy(c->loader);
    if (c->b.ops)
        c->b.ops->close(c->b.self); /* no change is heard of after this */
    sdfd_resident_free(&c->r);
    free(c);
}

int sdfd_cache_probe(sdfd_cache *c, char *msg, size_t cap)
{
    return c->b.ops ? c->b.ops->probe(c->b.self, msg, cap) : 0;
}

/* ---- lookups ----------------------------------------------------------------------------- */

int sdfd_cache_lookup(sdfd_cache *c, sdfd_lookup *l)
{
    if (c->loader)
        return sdfd_loader_lookup(c->loader, l);
    sdfd_cached e = {.kind = l->kind}; /* memory only */
    snprintf(e.name, sizeof e.name, "%s", l->name);
    l->item = sdfd_resident_get(&c->r, &e);
    l->status = l->item ? 0 : SDF_ENOTFOUND;
    if (!l->item)
        snprintf(l->message, sizeof l->message, "no %s named '%s'", sdfd_kind_name(l->kind),
                 l->name);
    return l->status;
}

int sdfd_cache_get(sdfd_cache *c, sdfd_item_kind kind, const char *name, size_t n, void **out,
                   char *msg, size_t cap)
{
    sdfd_lookup l = {.kind = kind};
    snprintf(l.name, sizeof l.name, "%.*s", (int)n, name);
    int rc = c->loader ? sdfd_loader_lookup_wait(c->loader, &l) : sdfd_cache_lookup(c, &l);
    if (rc && cap) { /* the message, cut to cap as the caller's snprintf would */
        size_t len = strnlen(l.message, cap - 1);
        memcpy(msg, l.message, len);
        msg[len] = '\0';
    }
    *out = l.item;
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

/* Write `item` (a mesh or stored volume, the caller's reference) to the backing, then make
 * it resident. A baked volume's entry stays claimed on success until its job has listed it
 * (sdfd_cache_baked_listed): a newer version heard of meanwhile is loaded only after that, so
 * the job's older volume cannot replace it in memory. */
static int put(sdfd_cache *c, sdfd_item_kind kind, const char *name, void *item,
               const void *file, size_t n, const char *format, char *info, int *replaced,
               char *msg, size_t cap, int baked)
{
    if (strlen(name) > c->b.ops->max_name) {
        free(info);
        snprintf(msg, cap, "with %s a name is at most %zu characters", c->b.ops->flag,
                 c->b.ops->max_name);
        return SDF_EINVAL;
    }
    pthread_mutex_lock(&c->r.lock);
    sdfd_cached *e = sdfd_resident_claim(&c->r, kind, name);
    unsigned changes = e ? e->changes : 0;
    pthread_mutex_unlock(&c->r.lock);
    if (!e) {
        free(info);
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    sdfd_sidecar meta = {.info = info};
    snprintf(meta.name, sizeof meta.name, "%s", name);
    snprintf(meta.format, sizeof meta.format, "%s", format);
    sdfd_seen seen;
    int existed = 0, rc = c->b.ops->write(c->b.self, kind, &meta, file, n, &existed, &seen, msg,
                                          cap);
    free(info);
    pthread_mutex_lock(&c->r.lock);
    if (!rc) {
        *replaced = existed || e->pinned;
        e->pinned = 0;
        e->hash = meta.hash, e->seen = seen, e->used = ++c->r.tick;
        /* A change heard of meanwhile may be a later write: compare at the next lookup. */
        e->checked = e->changes == changes ? sdfd_now() : 0;
        /* In the store, it is the client's: memory is a cache, so not fitting there is no
         * error (the next use loads it, and says why if it still cannot fit). */
        if (baked) { /* the bake's job lists it in memory next, then unclaims (baked_listed) */
            pthread_mutex_unlock(&c->r.lock);
            return 0;
        }
        if (sdfd_resident_put(&c->r, e, item))
            sdfd_log("warn", "store_put", "%s %s is stored but not kept in memory: over the "
                     "limits", sdfd_kind_name(kind), name);
        else
            sdfd_resident_enforce_budget(&c->r, e);
    }
    sdfd_lookup *waiting = sdfd_resident_unclaim(&c->r, e);
    pthread_mutex_unlock(&c->r.lock);
    sdfd_loader_retry(c->loader, waiting);
    return rc;
}

static int put_mesh(sdfd_cache *c, const char *name, sdf_mesh *mesh, const void *file,
                    size_t n, int *replaced, char *msg, size_t cap)
{
    if (!c->b.ops) {
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

static int put_volume(sdfd_cache *c, const char *name, sdf_volume *volume, const void *file,
                      size_t n, int *replaced, char *msg, size_t cap)
{
    if (!c->b.ops) {
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

int sdfd_cache_put(sdfd_cache *c, sdfd_item_kind kind, const char *name, void *item,
                   const void *file, size_t n, int *replaced, char *msg, size_t cap)
{
    return kind == SDFD_ITEM_MESH ? put_mesh(c, name, item, file, n, replaced, msg, cap)
                                  : put_volume(c, name, item, file, n, replaced, msg, cap);
}

static int remove_item(sdfd_cache *c, sdfd_item_kind kind, const char *name, char *msg,
                       size_t cap)
{
    pthread_mutex_lock(&c->r.lock);
    sdfd_cached *e = sdfd_resident_claim(&c->r, kind, name);
    pthread_mutex_unlock(&c->r.lock);
    if (!e) {
        snprintf(msg, cap, "out of memory");
        return SDF_ENOMEM;
    }
    int rc = strlen(name) > c->b.ops->max_name
                 ? SDF_ENOTFOUND
                 : c->b.ops->remove(c->b.self, kind, name, msg, cap);
    pthread_mutex_lock(&c->r.lock);
    if (e->pinned && rc == SDF_ENOTFOUND)
        rc = 0;
    if (rc != SDFD_EUNAVAILABLE && (e->resident || e->pinned))
        sdfd_resident_drop(&c->r, e);
    e->pinned = 0;
    sdfd_lookup *waiting = sdfd_resident_unclaim(&c->r, e);
    pthread_mutex_unlock(&c->r.lock);
    sdfd_loader_retry(c->loader, waiting);
    if (rc == SDF_ENOTFOUND)
        snprintf(msg, cap, "no %s named '%s'", sdfd_kind_name(kind), name);
    return rc;
}

int sdfd_cache_remove(sdfd_cache *c, sdfd_item_kind kind, const char *name, char *msg,
                      size_t cap)
{
    if (c->b.ops)
        return remove_item(c, kind, name, msg, cap);
    int rc = kind == SDFD_ITEM_MESH ? sdfd_registry_remove(c->registry, name)
                                    : sdfd_volumes_remove(c->volumes, name);
    if (rc)
        snprintf(msg, cap, "no %s named '%s'", sdfd_kind_name(kind), name);
    return rc;
}

/* ---- bake jobs --------------------------------------------------------------------------- */

int sdfd_cache_keep_baked(sdfd_cache *c, const sdfd_stored_volume *s, char *err, size_t cap)
{
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

static int keep_baked(void *user, const sdfd_stored_volume *s, char *err, size_t cap)
{
    return sdfd_cache_keep_baked(user, s, err, cap);
}

void sdfd_cache_baked_listed(sdfd_cache *c, const char *name, int rc)
{
    pthread_mutex_lock(&c->r.lock);
    sdfd_cached *e = sdfd_resident_find(&c->r, SDFD_ITEM_VOLUME, name, 0);
    sdfd_lookup *waiting = NULL;
    if (e) { /* claimed since sdfd_cache_keep_baked */
        if (rc) /* an older version in memory is stale now: the store holds the new one */
            sdfd_resident_drop(&c->r, e);
        else
            e->resident = 1, sdfd_resident_enforce_budget(&c->r, e);
        waiting = sdfd_resident_unclaim(&c->r, e);
    }
    pthread_mutex_unlock(&c->r.lock);
    sdfd_loader_retry(c->loader, waiting);
}

static void baked_listed(void *user, const char *name, int rc)
{
    sdfd_cache_baked_listed(user, name, rc);
}

static int job_started(void *user, const sdfd_job_status *s)
{
    return sdfd_jobrecords_started(((sdfd_cache *)user)->store, s);
}

static void job_ended(void *user, const sdfd_job_status *s, int token)
{
    sdfd_jobrecords_ended(((sdfd_cache *)user)->store, s, token);
}

static void job_forgotten(void *user, const char *id)
{
    sdfd_jobrecords_forgotten(((sdfd_cache *)user)->store, id);
}

int sdfd_cache_job(sdfd_cache *c, const char *id, sdfd_job_status *out)
{
    return c->store ? sdfd_jobrecords_read(c->store, id, out) : SDF_ENOTFOUND;
}

/* ---- start, listings, statistics --------------------------------------------------------- */

void sdfd_cache_pin(sdfd_cache *c, const char *name)
{
    pthread_mutex_lock(&c->r.lock);
    sdfd_cached *e = sdfd_resident_find(&c->r, SDFD_ITEM_MESH, name, 1);
    if (e)
        e->pinned = 1, e->resident = 1;
    pthread_mutex_unlock(&c->r.lock);
}

int sdfd_cache_start(sdfd_cache *c, char *err, size_t cap)
{
    if (!c->b.ops)
        return 0;
    int rc = c->b.ops->start(c->b.self, err, cap);
    if (rc)
        return rc;
    if (c->store) { /* the catalog's jobs are the job runner's (jobrunner.h) */
        sdfd_volumes_hooks hooks = {.user = c, .keep = keep_baked, .listed = baked_listed,
                                    .started = job_started, .ended = job_ended,
                                    .forgotten = job_forgotten};
        sdfd_jobrecords_restore(c->store, c->volumes);
        sdfd_volumes_set_hooks(c->volumes, &hooks);
    }
    for (int kind = SDFD_ITEM_MESH; kind <= SDFD_ITEM_VOLUME; kind++) {
        char(*names)[SDFD_MAX_NAME + 1];
        size_t n = c->b.ops->names(c->b.self, kind, 1, &names);
        for (size_t i = 0; i < n; i++) {
            char msg[512];
            void *item = NULL;
            if (c->r.budget && sdfd_resident_bytes(&c->r) >= c->r.budget) {
                /* Over the budget: the description is checked now, the data when first
                 * used. */
                sdfd_sidecar meta;
                sdfd_seen seen;
                if (c->b.ops->read(c->b.self, kind, names[i], &meta, NULL, &seen, msg,
                                   sizeof msg) == SDF_EFORMAT)
                    c->b.ops->quarantine(c->b.self, kind, names[i], msg);
                free(meta.info);
                continue;
            }
            if (!sdfd_cache_get(c, kind, names[i], strlen(names[i]), &item, msg, sizeof msg))
                sdfd_item_release(kind, item);
            else
                sdfd_log("error", "store_load", "%s", msg);
        }
        free(names);
    }
    return 0;
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
    size_t stored = c->b.ops ? c->b.ops->names(c->b.self, SDFD_ITEM_MESH, 0, &names) : 0;
    *out = malloc((n + stored + 1) * sizeof **out);
    for (size_t i = 0; *out && i < n; i++) {
        int pinned = 1;
        if (c->b.ops) {
            pthread_mutex_lock(&c->r.lock);
            sdfd_cached *e = sdfd_resident_find(&c->r, SDFD_ITEM_MESH, list[i].name, 0);
            pinned = e && e->pinned;
            pthread_mutex_unlock(&c->r.lock);
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
        sdfd_sidecar meta = {0};
        sdfd_seen seen;
        char why[64];
        int dup = 0;
        for (size_t k = 0; k < count; k++)
            dup |= !strcmp((*out)[k].name, names[i]);
        if (!dup && !c->b.ops->read(c->b.self, SDFD_ITEM_MESH, names[i], &meta, NULL, &seen, why,
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
    if (!c->b.ops)
        return NULL;
    char(*names)[SDFD_MAX_NAME + 1] = NULL;
    size_t n = c->b.ops->names(c->b.self, SDFD_ITEM_VOLUME, 0, &names);
    cJSON *arr = cJSON_CreateArray();
    for (size_t i = 0; i < n; i++) {
        sdfd_sidecar meta = {0};
        sdfd_seen seen;
        char why[64];
        if (!c->b.ops->read(c->b.self, SDFD_ITEM_VOLUME, names[i], &meta, NULL, &seen, why,
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
    pthread_mutex_lock(&c->r.lock);
    *out = (sdfd_cache_stats){sdfd_resident_bytes(&c->r), c->r.budget, c->r.loads,
                              c->r.evictions, c->r.quarantined, c->r.hits};
    pthread_mutex_unlock(&c->r.lock);
}
