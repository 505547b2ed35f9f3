/* builder.c - checked growable arrays for the parsers (see builder.h). */
#include "mesh/builder.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/diag.h"
#include "core/grow.h"

void sdf__builder_init(sdf__builder *b, const char *format, size_t max_triangles, sdf_diag *diag)
{
    *b = (sdf__builder){0};
    b->format = format;
    b->max_triangles = max_triangles ? max_triangles : SDF_DEFAULT_MAX_TRIANGLES;
    /* A mesh can use at most 3 vertices per triangle; allow unused ones up to the same. */
    b->max_vertices = 3 * b->max_triangles;
    if (b->max_vertices > UINT32_MAX - 1) /* indices are uint32 */
        b->max_vertices = UINT32_MAX - 1;
    b->offset = -1;
    b->diag = diag;
}

void sdf__builder_free(sdf__builder *b)
{
    free(b->positions);
    free(b->triangles);
    b->positions = NULL;
    b->triangles = NULL;
}

/* "<FORMAT> line L: ", "<FORMAT> byte B: " or "<FORMAT>: " for the current location. */
static void locate(const sdf__builder *b, char *dst, size_t cap)
{
    if (b->line > 0)
        snprintf(dst, cap, "%s line %ld: ", b->format, b->line);
    else if (b->offset >= 0)
        snprintf(dst, cap, "%s byte %lld: ", b->format, b->offset);
    else
        snprintf(dst, cap, "%s: ", b->format);
}

int sdf__builder_fail(sdf__builder *b, int code, const char *fmt, ...)
{
    char where[64], detail[200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    locate(b, where, sizeof where);
    return sdf__diag_set(b->diag, code, b->line > 0 ? b->line : 0, b->offset >= 0 ? b->offset : -1,
                         "%s%s", where, detail);
}

void sdf__builder_warn(sdf__builder *b, const char *fmt, ...)
{
    if (b->warnings++)
        return;
    locate(b, b->warning, sizeof b->warning);
    size_t used = strlen(b->warning);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(b->warning + used, sizeof b->warning - used, fmt, ap);
    va_end(ap);
}

static int ensure_vertices(sdf__builder *b, size_t more)
{
    if (more > b->max_vertices - b->vertex_count)
        return sdf__builder_fail(b, SDF_ELIMIT, "more than %zu vertices (limit)", b->max_vertices);
    if (sdf__grow((void **)&b->positions, &b->vertex_cap, b->vertex_count + more, 3 * sizeof(float)))
        return sdf__builder_fail(b, SDF_ENOMEM, "out of memory for %zu vertices",
                                 b->vertex_count + more);
    return 0;
}

static int ensure_triangles(sdf__builder *b, size_t more)
{
    if (more > b->max_triangles - b->triangle_count)
        return sdf__builder_fail(b, SDF_ELIMIT, "more than %zu triangles (limit)",
                                 b->max_triangles);
    if (sdf__grow((void **)&b->triangles, &b->triangle_cap, b->triangle_count + more,
             3 * sizeof(uint32_t)))
        return sdf__builder_fail(b, SDF_ENOMEM, "out of memory for %zu triangles",
                                 b->triangle_count + more);
    return 0;
}

int sdf__builder_reserve(sdf__builder *b, size_t vertices, size_t triangles)
{
    int rc = ensure_vertices(b, vertices);
    return rc ? rc : ensure_triangles(b, triangles);
}

int sdf__builder_add_vertex(sdf__builder *b, double x, double y, double z)
{
    double c[3] = {x, y, z};
    for (int i = 0; i < 3; i++) {
        if (!(fabs(c[i]) <= SDF_MAX_COORDINATE)) /* NaN fails too */
            return sdf__builder_fail(b, SDF_ENONFINITE,
                                     "vertex %zu has a coordinate that is not finite or beyond "
                                     "+-1e18 (%g)", b->vertex_count, c[i]);
    }
    int rc = ensure_vertices(b, 1);
    if (rc)
        return rc;
    float *p = b->positions + 3 * b->vertex_count++;
    p[0] = (float)x;
    p[1] = (float)y;
    p[2] = (float)z;
    return 0;
}

int sdf__builder_add_polygon(sdf__builder *b, const uint32_t *idx, size_t n, size_t face_number)
{
    if (n < 3)
        return sdf__builder_fail(b, SDF_EPARSE, "face %zu has %zu vertices; at least 3 are needed",
                                 face_number, n);
    for (size_t i = 0; i < n; i++) {
        if (idx[i] >= b->vertex_count)
            return sdf__builder_fail(b, SDF_EINDEX,
                                     "face %zu uses vertex index %u, but only %zu vertices exist",
                                     face_number, idx[i], b->vertex_count);
    }
    int rc = ensure_triangles(b, n - 2);
    if (rc)
        return rc;
    for (size_t i = 1; i + 1 < n; i++) {
        uint32_t *t = b->triangles + 3 * b->triangle_count++;
        t[0] = idx[0];
        t[1] = idx[i];
        t[2] = idx[i + 1];
    }
    return 0;
}
