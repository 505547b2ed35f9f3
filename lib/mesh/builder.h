/* builder.h - the growable vertex/triangle arrays every parser fills.
 *
 * It owns the checks that all formats share, so each parser only reads its syntax: a
 * coordinate must be finite in float32, an index must name an existing vertex, polygons are
 * fan-triangulated, and counts stay under the configured caps. Every allocation is sized by
 * a count that was first checked against a cap (and, by the parser, against the bytes the
 * input actually holds). Errors carry the parser's current location (`line`/`offset`). */
#ifndef SDF_MESH_BUILDER_H
#define SDF_MESH_BUILDER_H

#include <stddef.h>
#include <stdint.h>

#include "sdf/sdf.h"

typedef struct sdf__builder {
    float *positions;      /* 3 per vertex */
    size_t vertex_count, vertex_cap;
    uint32_t *triangles;   /* 3 per triangle */
    size_t triangle_count, triangle_cap;
    size_t max_triangles;
    size_t max_vertices;
    const char *format;    /* "OBJ", "PLY", ... for messages */
    long line;             /* current location, kept up to date by the parser */
    long long offset;
    sdf_diag *diag;
    size_t warnings;       /* inputs accepted with doubt; the first one's message: */
    char warning[SDF_MESH_WARNING_SIZE];
} sdf__builder;

void sdf__builder_init(sdf__builder *b, const char *format, size_t max_triangles, sdf_diag *diag);
void sdf__builder_free(sdf__builder *b);

/* Reserve room for `vertices` more vertices / `triangles` more triangles (checked against
 * the caps first). Parsers call this with counts they have validated against the input. */
int sdf__builder_reserve(sdf__builder *b, size_t vertices, size_t triangles);

/* Append a vertex; rejects NaN/Inf and values beyond float range. */
int sdf__builder_add_vertex(sdf__builder *b, double x, double y, double z);

/* Append a polygon of `n` >= 3 vertex indices (0-based), fan-triangulated; rejects
 * indices >= vertex_count and fewer than 3 corners. `what` names it in messages ("face 7"). */
int sdf__builder_add_polygon(sdf__builder *b, const uint32_t *idx, size_t n, size_t face_number);

/* Report an error at the current location: "<FORMAT> line L: ..." or "... byte B: ...". */
int sdf__builder_fail(sdf__builder *b, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Note something accepted with doubt at the current location (the mesh report keeps the
 * first message, located as sdf__builder_fail's, and the count). */
void sdf__builder_warn(sdf__builder *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#endif
