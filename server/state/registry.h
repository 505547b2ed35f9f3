/* registry.h - the named meshes sdfd serves. Lookups hand out a retained reference, so
 * replacing or deleting a mesh is atomic for clients: queries already holding the old mesh
 * finish on it, and it is freed when the last of them releases it. Limits: number of
 * meshes and total triangles. Thread-safe. */
#ifndef SDFD_REGISTRY_H
#define SDFD_REGISTRY_H

#include <stddef.h>

#include "sdf/sdf.h"

typedef struct sdfd_registry sdfd_registry;

#define SDFD_MAX_NAME 255

sdfd_registry *sdfd_registry_create(size_t max_meshes, size_t max_triangles);
void sdfd_registry_destroy(sdfd_registry *r);

/* Is `name` acceptable: 1-255 characters of [A-Za-z0-9._-], not starting with '.'? */
int sdfd_valid_name(const char *name, size_t len);

/* The mesh called `name` (n bytes), retained (release it), or NULL. */
sdf_mesh *sdfd_registry_get(sdfd_registry *r, const char *name, size_t n);

/* Add or replace; takes over the caller's reference. *replaced tells which. SDF_ELIMIT if
 * the limits would be exceeded (the mesh is then released). */
int sdfd_registry_put(sdfd_registry *r, const char *name, sdf_mesh *mesh, int *replaced);

/* Remove; SDF_ENOTFOUND if absent. */
int sdfd_registry_remove(sdfd_registry *r, const char *name);

/* Snapshot of names and retained meshes, sorted by name; free with sdfd_registry_free_list. */
typedef struct sdfd_entry {
    char name[SDFD_MAX_NAME + 1];
    sdf_mesh *mesh;
} sdfd_entry;

size_t sdfd_registry_list(sdfd_registry *r, sdfd_entry **out);
void sdfd_registry_free_list(sdfd_entry *list, size_t n);
size_t sdfd_registry_count(sdfd_registry *r);

#endif
