/* query.h - the inside of sdf_query (query/query.c), for the code above it: the filtered
 * field (query/filter.c) queries its points with sdf__query, and the lattice test is shared
 * with the tests. */
#ifndef SDF_QUERY_QUERY_H
#define SDF_QUERY_QUERY_H

#include <stddef.h>

#include "sdf/sdf.h"

/* sdf_query on options whose workspace the caller has claimed (core/workspace.h): the scan
 * for a large lattice, else the point engine. */
int sdf__query(const sdf_mesh *mesh, const float *points, size_t count,
               const sdf_query_options *opts, sdf_query_result *out);

/* Is the batch (xyz floats `stride` bytes apart, 0 = packed) a full lattice: point
 * (k ny + j) nx + i at (x_i, y_j, z_k), each axis at least 2 long? Then 1, its dims and its
 * axes (malloc'ed, the caller frees them); else 0 and NULLs. */
int sdf__find_lattice(const float *points, size_t stride, size_t count, size_t dims[3],
                      float *axis[3]);

#endif
