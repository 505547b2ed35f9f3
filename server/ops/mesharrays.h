/* mesharrays.h - meshes uploaded as arrays rather than files:
 *   JSON  {"vertices": [[x, y, z], ...], "faces": [[i, j, k], ...]}
 *   npz   members `vertices` (float32 or float64, shape (V, 3)) and `faces` (any integer
 *         type, shape (F, 3)), as numpy.savez or savez_compressed write them
 * Both become the binary PLY file of the same arrays (sdf_mesh_write), which the upload then
 * loads and stores like any file: a mesh sent as OBJ, JSON or npz is the same mesh, answers
 * the same bits, and is stored and reloaded as PLY.
 *
 * Every row is checked before the PLY is made: three numbers (ragged rows are refused,
 * naming the row), finite coordinates, integral face indices within [0, V). A body is
 * read in one pass with arrays grown as they fill; no size is taken from the body before it
 * is checked against the body's length. Any thread. */
#ifndef SDFD_MESHARRAYS_H
#define SDFD_MESHARRAYS_H

#include <stddef.h>

typedef enum sdfd_mesh_body {
    SDFD_MESH_BODY_FILE, /* a mesh file: OBJ, PLY, STL or OFF */
    SDFD_MESH_BODY_JSON,
    SDFD_MESH_BODY_NPZ,
} sdfd_mesh_body;

/* What the body is: `format` (the URL's, may be NULL) "json" or "npz" (any case) says so; else a body
 * whose first non-space byte is '{' is JSON and one that starts "PK\3\4" an npz; else a file
 * (binary STL headers are free text: format=stl overrides). */
sdfd_mesh_body sdfd_mesh_body_kind(const char *format, const char *body, size_t len);

/* The binary PLY bytes (*ply, malloc'd, *ply_len) of the JSON or npz `body` (NUL-terminated
 * after len bytes). 0, or an SDF_E* code with err set: SDFD_ESYNTAX for JSON that does not
 * parse, SDF_EINVAL for arrays of the wrong shape or values, SDF_EFORMAT for an npz that is
 * not one, SDF_ELIMIT past max_triangles, SDF_ENOMEM. */
int sdfd_mesh_arrays_to_ply(sdfd_mesh_body kind, const char *body, size_t len,
                            size_t max_triangles, void **ply, size_t *ply_len, char *err,
                            size_t cap);

#endif
