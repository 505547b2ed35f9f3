/* resident.c - the table of names the cache has looked up and what of them is in memory
 * (resident.h): claims, and residency within the byte budget, least recently used first
 * out. The registry and the volumes hold the items themselves; this file decides which. */
#include "state/resident.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/log.h"

void sdfd_resident_init(sdfd_resident *r, sdfd_registry *registry, sdfd_volumes *volumes,
                        size_t budget)
{
    memset(r, 0, sizeof *r);
    pthread_mutex_init(&r->lock, NULL);
    pthread_cond_init(&r->idle, NULL);
    r->registry = registry, r->volumes = volumes, r->budget = budget;
}

void sdfd_resident_free(sdfd_resident *r)
{
    for (size_t i = 0; i < r->count; i++)
        free(r->entries[i]);
    free(r->entries);
    pthread_cond_destroy(&r->idle);
    pthread_mutex_destroy(&r->lock);
}

const char *sdfd_kind_name(sdfd_item_kind kind)
{
    return kind == SDFD_ITEM_MESH ? "mesh" : "volume";
}

/* ---- the table --------------------------------------------------------------------------- */

sdfd_cached *sdfd_resident_find(sdfd_resident *r, sdfd_item_kind kind, const char *name,
                                int create)
{
    for (size_t i = 0; i < r->count; i++)
        if (r->entries[i]->kind == kind && !strcmp(r->entries[i]->name, name))
            return r->entries[i];
    if (!create)
        return NULL;
    if (r->count == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 32;
        sdfd_cached **grown = realloc(r->entries, cap * sizeof *grown);
        if (!grown)
            return NULL;
        r->entries = grown, r->cap = cap;
    }
    sdfd_cached *e = calloc(1, sizeof *e);
    if (!e)
        return NULL;
    e->kind = kind;
    snprintf(e->name, sizeof e->name, "%s", name);
    r->entries[r->count++] = e;
    return e;
}

sdfd_cached *sdfd_resident_claim(sdfd_resident *r, sdfd_item_kind kind, const char *name)
{
    sdfd_cached *e;
    while ((e = sdfd_resident_find(r, kind, name, 1)) && e->busy)
        pthread_cond_wait(&r->idle, &r->lock);
    if (e)
        e->busy = 1;
    return e;
}

/* Waiters find their entry again by name: it may be freed here. */
sdfd_lookup *sdfd_resident_unclaim(sdfd_resident *r, sdfd_cached *e)
{
    sdfd_lookup *waiting = e->waiting;
    e->waiting = NULL;
    e->busy = e->reloading = 0;
    pthread_cond_broadcast(&r->idle);
    if (e->resident || e->pinned)
        return waiting;
    for (size_t i = 0; i < r->count; i++)
        if (r->entries[i] == e) {
            r->entries[i] = r->entries[--r->count];
            free(e);
            break;
        }
    return waiting;
}

/* ---- residency --------------------------------------------------------------------------- */

static size_t mesh_bytes(const sdf_mesh *m)
{
    sdf_mesh_report rep;
    sdf_mesh_get_report(m, &rep);
    /* The index, and the welded vertices and triangles (three floats, three indices). */
    return rep.index_bytes + 12 * rep.vertices + 12 * rep.triangles;
}

size_t sdfd_resident_bytes(sdfd_resident *r)
{
    sdfd_entry *list;
    size_t n = sdfd_registry_list(r->registry, &list), bytes = 0, running, queued, vbytes;
    for (size_t i = 0; i < n; i++)
        bytes += mesh_bytes(list[i].mesh);
    sdfd_registry_free_list(list, n);
    sdfd_volumes_usage(r->volumes, &vbytes, &running, &queued);
    return bytes + vbytes;
}

void sdfd_resident_drop(sdfd_resident *r, sdfd_cached *e)
{
    if (e->kind == SDFD_ITEM_MESH)
        sdfd_registry_remove(r->registry, e->name);
    else
        sdfd_volumes_remove(r->volumes, e->name);
    e->resident = 0;
}

/* The least recently used item that may leave memory (of `kind`, or any kind when
 * kind < 0), other than `keep`. */
static sdfd_cached *eviction_candidate(sdfd_resident *r, int kind, const sdfd_cached *keep)
{
    sdfd_cached *best = NULL;
    for (size_t i = 0; i < r->count; i++) {
        sdfd_cached *e = r->entries[i];
        if (e != keep && e->resident && !e->pinned && !e->busy &&
            (kind < 0 || (int)e->kind == kind) && (!best || e->used < best->used))
            best = e;
    }
    return best;
}

/* Evict one item (of `kind`, or any); 0, or -1 when there is none. */
static int evict_one(sdfd_resident *r, int kind, const sdfd_cached *keep)
{
    sdfd_cached *victim = eviction_candidate(r, kind, keep);
    if (!victim)
        return -1;
    sdfd_resident_drop(r, victim);
    r->evictions++;
    sdfd_log("info", "store_evicted", "%s %s left memory (least recently used)",
             sdfd_kind_name(victim->kind), victim->name);
    return 0;
}

void sdfd_resident_enforce_budget(sdfd_resident *r, const sdfd_cached *keep)
{
    while (r->budget && sdfd_resident_bytes(r) > r->budget && !evict_one(r, -1, keep))
        ;
}

int sdfd_resident_put(sdfd_resident *r, sdfd_cached *e, void *item)
{
    for (;;) {
        int rc, replaced;
        if (e->kind == SDFD_ITEM_MESH) {
            rc = sdfd_registry_put(r->registry, e->name, sdf_mesh_retain(item), &replaced);
        } else {
            sdfd_volume_retain(item);
            rc = sdfd_volumes_put_stored(r->volumes, item, &replaced);
        }
        if (rc != SDF_ELIMIT || evict_one(r, (int)e->kind, e)) {
            e->resident = !rc;
            return rc;
        }
    }
}

void *sdfd_resident_get(sdfd_resident *r, const sdfd_cached *e)
{
    if (e->kind == SDFD_ITEM_MESH)
        return sdfd_registry_get(r->registry, e->name, strlen(e->name));
    return sdfd_volumes_get(r->volumes, e->name);
}

void *sdfd_item_retain(sdfd_item_kind kind, void *item)
{
    if (item && kind == SDFD_ITEM_MESH)
        sdf_mesh_retain(item);
    else if (item)
        sdfd_volume_retain(item);
    return item;
}

void sdfd_item_release(sdfd_item_kind kind, void *item)
{
    if (kind == SDFD_ITEM_MESH)
        sdf_mesh_release(item);
    else
        sdfd_volume_release(item);
}
