/* surface.h - a volume's surface as a mesh file (sdf_volume_extract, then sdf_mesh_write),
 * for the route that answers or stores it (ops/opextract.c) and the bake that stores it
 * (volumes.c, "mesh" in a bake request). A surface with more triangles than the server's
 * --max-triangles is refused before its file is written. */
#ifndef SDFD_SURFACE_H
#define SDFD_SURFACE_H

#include <stddef.h>

#include "sdf/sdf.h"

/* The surface of `v` by `opts` as a file of `format` in *bytes (malloc'd, *n bytes; free it),
 * *triangles its triangles. max_triangles 0: no bound. 0, or the library's code, SDF_ELIMIT
 * (too many triangles) or SDF_ENOMEM, with err set. */
int sdfd_surface_file(const sdf_volume *v, const sdf_extract_options *opts,
                      size_t max_triangles, sdf_format format, void **bytes, size_t *n,
                      size_t *triangles, char *err, size_t cap);

/* The surface as a stored mesh would be: its binary PLY (*bytes, *n, as above) and the mesh
 * parsing them gives (*mesh, one reference), so that a restart or a replica that loads the
 * bytes has exactly this mesh. 0 or an error code with err set. */
int sdfd_surface_mesh(const sdf_volume *v, const sdf_extract_options *opts,
                      size_t max_triangles, void **bytes, size_t *n, sdf_mesh **mesh,
                      char *err, size_t cap);

#endif
