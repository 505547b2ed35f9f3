/* registry.c - named, reference-counted meshes (see registry.h). A small array under a
 * mutex: a server holds tens of meshes, and lookups are a few string compares. */
#include "state/registry.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

struct sdfd_registry {
    pthread_mutex_t lock;
    sdfd_entry *entries;
    size_t count, max_meshes, max_triangles, triangles;
};

sdfd_registry *sdfd_registry_create(size_t max_meshes, size_t max_triangles)
{
    sdfd_registry *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    r->entries = calloc(max_meshes ? max_meshes : 1, sizeof *r->entries);
    if (!r->entries) {
        free(r);
        return NULL;
    }
    pthread_mutex_init(&r->lock, NULL);
    r->max_meshes = max_meshes;
    r->max_triangles = max_triangles;
    return r;
}

void sdfd_registry_destroy(sdfd_registry *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->count; i++)
        sdf_mesh_release(r->entries[i].mesh);
    pthread_mutex_destroy(&r->lock);
    free(r->entries);
    free(r);
}

int sdfd_valid_name(const char *name, size_t len)
{
    if (len == 0 || len > SDFD_MAX_NAME || name[0] == '.')
        return 0;
    for (size_t i = 0; i < len; i++) {
        char c = name[i];
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '.' || c == '_' || c == '-'))
            return 0;
    }
    return 1;
}

static size_t triangles_of(const sdf_mesh *m)
{
    sdf_mesh_report rep;
    sdf_mesh_get_report(m, &rep);
    return rep.triangles;
}

/* Index of `name` or r->count. Caller holds the lock. */
static size_t find(const sdfd_registry *r, const char *name, size_t n)
{
    for (size_t i = 0; i < r->count; i++)
        if (strlen(r->entries[i].name) == n && !memcmp(r->entries[i].name, name, n))
            return i;
    return r->count;
}

sdf_mesh *sdfd_registry_get(sdfd_registry *r, const char *name, size_t n)
{
    pthread_mutex_lock(&r->lock);
    size_t i = find(r, name, n);
    sdf_mesh *m = i < r->count ? sdf_mesh_retain(r->entries[i].mesh) : NULL;
    pthread_mutex_unlock(&r->lock);
    return m;
}

int sdfd_registry_put(sdfd_registry *r, const char *name, sdf_mesh *mesh, int *replaced)
{
    size_t n = strlen(name), tris = triangles_of(mesh);
    if (!sdfd_valid_name(name, n)) {
        sdf_mesh_release(mesh);
        return SDF_EINVAL;
    }
    pthread_mutex_lock(&r->lock);
    size_t i = find(r, name, n);
    size_t old = i < r->count ? triangles_of(r->entries[i].mesh) : 0;
    if ((i == r->count && r->count == r->max_meshes) || r->triangles - old + tris > r->max_triangles) {
        pthread_mutex_unlock(&r->lock);
        sdf_mesh_release(mesh);
        return SDF_ELIMIT;
    }
    sdf_mesh *previous = i < r->count ? r->entries[i].mesh : NULL;
    if (i == r->count) {
        memcpy(r->entries[i].name, name, n + 1);
        r->count++;
    }
    r->entries[i].mesh = mesh;
    r->triangles = r->triangles - old + tris;
    pthread_mutex_unlock(&r->lock);
    sdf_mesh_release(previous); /* queries still holding it keep it alive */
    if (replaced)
        *replaced = previous != NULL;
    return 0;
}

int sdfd_registry_remove(sdfd_registry *r, const char *name)
{
    pthread_mutex_lock(&r->lock);
    size_t i = find(r, name, strlen(name));
    if (i == r->count) {
        pthread_mutex_unlock(&r->lock);
        return SDF_ENOTFOUND;
    }
    sdf_mesh *m = r->entries[i].mesh;
    r->triangles -= triangles_of(m);
    r->entries[i] = r->entries[--r->count];
    pthread_mutex_unlock(&r->lock);
    sdf_mesh_release(m);
    return 0;
}

static int by_name(const void *a, const void *b)
{
    return strcmp(((const sdfd_entry *)a)->name, ((const sdfd_entry *)b)->name);
}

size_t sdfd_registry_list(sdfd_registry *r, sdfd_entry **out)
{
    pthread_mutex_lock(&r->lock);
    size_t n = r->count;
    sdfd_entry *list = malloc((n ? n : 1) * sizeof *list);
    for (size_t i = 0; list && i < n; i++) {
        list[i] = r->entries[i];
        sdf_mesh_retain(list[i].mesh);
    }
    pthread_mutex_unlock(&r->lock);
    if (!list)
        n = 0;
    else
        qsort(list, n, sizeof *list, by_name);
    *out = list;
    return n;
}

void sdfd_registry_free_list(sdfd_entry *list, size_t n)
{
    for (size_t i = 0; i < n; i++)
        sdf_mesh_release(list[i].mesh);
    free(list);
}

size_t sdfd_registry_count(sdfd_registry *r)
{
    pthread_mutex_lock(&r->lock);
    size_t n = r->count;
    pthread_mutex_unlock(&r->lock);
    return n;
}
