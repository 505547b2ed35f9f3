/* parsers.h - the mesh file parsers. Each reads `size` bytes at `data` (followed by a NUL
 * that is not part of the input) into a builder, checking every count against the caps and
 * the bytes present before reserving room for it. Each returns 0 or an SDF_E* code with
 * the builder's diag filled in. Implemented one per file: obj.c, off.c, stl.c, ply.c. */
#ifndef SDF_MESH_PARSERS_H
#define SDF_MESH_PARSERS_H

#include <stddef.h>

#include "mesh/builder.h"

int sdf__parse_obj(const char *data, size_t size, sdf__builder *b);
int sdf__parse_off(const char *data, size_t size, sdf__builder *b);
int sdf__parse_stl(const char *data, size_t size, sdf__builder *b);
int sdf__parse_ply(const char *data, size_t size, sdf__builder *b);

/* Is this exactly a binary STL (size == 84 + 50 * declared count)? */
int sdf__stl_is_binary(const char *data, size_t size);

/* Guess the format from the first bytes (and, for binary STL, the size). Returns
 * SDF_FORMAT_AUTO when nothing matches. */
sdf_format sdf__sniff_format(const char *data, size_t size);

/* A growable list of polygon corner indices, shared by the parsers. */
typedef struct sdf__polygon {
    uint32_t *idx;
    size_t count, cap;
} sdf__polygon;

int sdf__polygon_push(sdf__polygon *poly, uint32_t index);
void sdf__polygon_free(sdf__polygon *poly);

#endif
