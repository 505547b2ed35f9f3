/* surface.c - a volume's surface as a mesh file (surface.h). */
#include "state/surface.h"

#include <stdio.h>
#include <stdlib.h>

int sdfd_surface_file(const sdf_volume *v, const sdf_extract_options *opts,
                      size_t max_triangles, sdf_format format, void **bytes, size_t *n,
                      size_t *triangles, char *err, size_t cap)
{
    sdf_surface *s = NULL;
    sdf_diag diag = {0};
    *bytes = NULL, *n = *triangles = 0;
    int rc = sdf_volume_extract(v, opts, &s, &diag);
    if (rc) {
        snprintf(err, cap, "%s", diag.message);
        return rc;
    }
    size_t nv, nt;
    const float *p = sdf_surface_vertices(s, &nv);
    const uint32_t *t = sdf_surface_triangles(s, &nt);
    size_t bound = sdf_mesh_write_bound(nv, nt, format);
    *triangles = nt;
    if (max_triangles && nt > max_triangles) {
        snprintf(err, cap, "the surface has %zu triangles, more than --max-triangles (%zu)", nt,
                 max_triangles);
        rc = SDF_ELIMIT;
    } else if (!bound || !(*bytes = malloc(bound))) {
        snprintf(err, cap, "out of memory for a file of %zu triangles", nt);
        rc = SDF_ENOMEM;
    } else {
        *n = sdf_mesh_write(p, nv, t, nt, format, *bytes, bound);
    }
    sdf_surface_destroy(s);
    return rc;
}

int sdfd_surface_mesh(const sdf_volume *v, const sdf_extract_options *opts,
                      size_t max_triangles, void **bytes, size_t *n, sdf_mesh **mesh,
                      char *err, size_t cap)
{
    size_t triangles;
    *mesh = NULL;
    int rc = sdfd_surface_file(v, opts, max_triangles, SDF_FORMAT_PLY, bytes, n, &triangles,
                               err, cap);
    if (rc)
        return rc;
    sdf_mesh_options mo = {.format = SDF_FORMAT_PLY, .max_triangles = max_triangles};
    sdf_diag diag = {0};
    if ((rc = sdf_mesh_load_memory(*bytes, *n, &mo, mesh, &diag))) {
        snprintf(err, cap, "%s", diag.message);
        free(*bytes);
        *bytes = NULL;
    }
    return rc;
}
