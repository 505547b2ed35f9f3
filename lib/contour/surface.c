/* surface.c - sdf_surface's accessors (sdf.h, "Surfaces of volumes"). */
#include "contour/surface.h"

#include <stdlib.h>

const float *sdf_surface_vertices(const sdf_surface *surface, size_t *count)
{
    *count = surface->vertex_count;
    return surface->vertices;
}

const uint32_t *sdf_surface_triangles(const sdf_surface *surface, size_t *count)
{
    *count = surface->triangle_count;
    return surface->triangles;
}

int sdf_surface_to_mesh(const sdf_surface *surface, const sdf_mesh_options *opts,
                        sdf_mesh **out, sdf_diag *diag)
{
    return sdf_mesh_create(surface->vertices, surface->vertex_count, surface->triangles,
                           surface->triangle_count, opts, out, diag);
}

void sdf_surface_destroy(sdf_surface *surface)
{
    if (!surface)
        return;
    free(surface->vertices);
    free(surface->triangles);
    free(surface);
}
