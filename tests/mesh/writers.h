/* writers.h - the test suite's mesh writers: one mesh re-encoded in every format and
 * variant the parsers accept (CRLF, comments, v/vt/vn corners, negative indices, polygons,
 * big-endian PLY with extra properties and elements, binary STL with a "solid" header ...).
 * Coordinates are printed with %.9g, which round-trips float32 exactly, so every variant
 * must load to bit-identical geometry. Buffers are malloc'd; *size gets their length. */
#ifndef SDF_TESTS_WRITERS_H
#define SDF_TESTS_WRITERS_H

#include <stddef.h>

#include "sdf/sdf.h"

char *write_obj(const sdf_mesh *mesh, int variant, size_t *size);   /* variants 0..2 */
char *write_off(const sdf_mesh *mesh, size_t *size);
char *write_stl_ascii(const sdf_mesh *mesh, size_t *size);
char *write_stl_binary(const sdf_mesh *mesh, const char *header, size_t *size);
char *write_ply(const sdf_mesh *mesh, const char *encoding, size_t *size); /* "ascii", "binary_little_endian", "binary_big_endian" */

#endif
