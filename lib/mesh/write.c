/* write.c - mesh files from arrays (sdf.h, sdf_mesh_write): binary little-endian PLY, OBJ,
 * binary STL and OFF, each of which the parsers read back to the same floats (text prints
 * every float with 9 significant digits, which round-trips float32).
 *
 * The caller sizes the buffer with sdf_mesh_write_bound, a bound a little above the largest
 * text, so that nothing here allocates; the binary formats' bound is their exact size. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "sdf/sdf.h"

#define NUMBER_MAX 16    /* "%.9g" of a float: "-1.23456789e-38" and a separator */
#define INDEX_MAX 11     /* a uint32 in decimal and a separator */
#define HEADER_MAX 256
#define STL_HEADER 80

static const char PLY_HEADER[] =
    "ply\nformat binary_little_endian 1.0\ncomment made by sdfd\nelement vertex %zu\n"
    "property float x\nproperty float y\nproperty float z\nelement face %zu\n"
    "property list uchar uint vertex_indices\nend_header\n";

/* a * b + c, or SIZE_MAX when it overflows */
static size_t mul_add(size_t a, size_t b, size_t c)
{
    if (b && a > (SIZE_MAX - c) / b)
        return SIZE_MAX;
    return a * b + c;
}

size_t sdf_mesh_write_bound(size_t vertex_count, size_t triangle_count, sdf_format format)
{
    size_t v, t;
    switch (format) {
    case SDF_FORMAT_PLY: v = 12, t = 13; break;
    case SDF_FORMAT_OBJ: v = 3 + 3 * NUMBER_MAX, t = 3 + 3 * INDEX_MAX; break;
    case SDF_FORMAT_OFF: v = 1 + 3 * NUMBER_MAX, t = 3 + 3 * INDEX_MAX; break;
    case SDF_FORMAT_STL:
        return triangle_count > UINT32_MAX ? 0 : mul_add(triangle_count, 50, STL_HEADER + 4);
    default: return 0;
    }
    size_t n = mul_add(vertex_count, v, HEADER_MAX);
    n = n == SIZE_MAX ? n : mul_add(triangle_count, t, n);
    return n == SIZE_MAX ? 0 : n;
}

static char *put_floats(char *p, const float *f, int n, const char *sep, const char *end)
{
    for (int i = 0; i < n; i++)
        p += sprintf(p, "%.9g%s", (double)f[i], i + 1 < n ? sep : end);
    return p;
}

static size_t write_text(const float *v, size_t nv, const uint32_t *t, size_t nt, int obj,
                         char *dst)
{
    char *p = dst;
    if (!obj)
        p += sprintf(p, "OFF\n%zu %zu 0\n", nv, nt);
    for (size_t i = 0; i < nv; i++) {
        if (obj)
            p += sprintf(p, "v ");
        p = put_floats(p, v + 3 * i, 3, " ", "\n");
    }
    for (size_t i = 0; i < nt; i++) {
        const uint32_t *x = t + 3 * i, base = obj ? 1 : 0;
        p += sprintf(p, "%s %u %u %u\n", obj ? "f" : "3", x[0] + base, x[1] + base, x[2] + base);
    }
    return (size_t)(p - dst);
}

static size_t write_ply(const float *v, size_t nv, const uint32_t *t, size_t nt, char *dst)
{
    char *p = dst + sprintf(dst, PLY_HEADER, nv, nt);
    memcpy(p, v, nv * 12);
    p += nv * 12;
    for (size_t i = 0; i < nt; i++) {
        *p++ = 3;
        memcpy(p, t + 3 * i, 12);
        p += 12;
    }
    return (size_t)(p - dst);
}

static size_t write_stl(const float *v, const uint32_t *t, size_t nt, char *dst)
{
    char *p = dst;
    memset(p, 0, STL_HEADER);
    memcpy(p, "binary STL made by sdfd", 23);
    uint32_t count = (uint32_t)nt;
    memcpy(p + STL_HEADER, &count, 4);
    p += STL_HEADER + 4;
    for (size_t i = 0; i < nt; i++) {
        const float *a = v + 3 * t[3 * i], *b = v + 3 * t[3 * i + 1], *c = v + 3 * t[3 * i + 2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                       u[0] * w[1] - u[1] * w[0]};
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        len = len > 0 ? len : 1; /* a zero-area triangle's normal is 0 */
        float rec[12] = {(float)(n[0] / len), (float)(n[1] / len), (float)(n[2] / len),
                         a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]};
        memcpy(p, rec, 48);
        p[48] = p[49] = 0;
        p += 50;
    }
    return (size_t)(p - dst);
}

size_t sdf_mesh_write(const float *vertices, size_t vertex_count, const uint32_t *triangles,
                      size_t triangle_count, sdf_format format, void *dst, size_t cap)
{
    size_t bound = sdf_mesh_write_bound(vertex_count, triangle_count, format);
    if (!bound || cap < bound || !dst)
        return 0;
    switch (format) {
    case SDF_FORMAT_PLY: return write_ply(vertices, vertex_count, triangles, triangle_count, dst);
    case SDF_FORMAT_STL: return write_stl(vertices, triangles, triangle_count, dst);
    case SDF_FORMAT_OBJ:
    case SDF_FORMAT_OFF:
        return write_text(vertices, vertex_count, triangles, triangle_count,
                          format == SDF_FORMAT_OBJ, dst);
    default: return 0;
    }
}
