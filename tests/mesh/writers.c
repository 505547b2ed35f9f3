/* writers.c - mesh writers for the parser tests (see writers.h). */
#include "writers.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct buf {
    char *data;
    size_t len, cap;
} buf;

static void put(buf *b, const void *src, size_t n)
{
    if (b->len + n + 1 > b->cap) {
        b->cap = (b->len + n + 1) * 2;
        b->data = realloc(b->data, b->cap);
    }
    memcpy(b->data + b->len, src, n);
    b->len += n;
    b->data[b->len] = '\0';
}

static void putf(buf *b, const char *fmt, ...)
{
    char tmp[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    put(b, tmp, (size_t)n);
}

static void counts(const sdf_mesh *m, size_t *nv, size_t *nt)
{
    sdf_mesh_report r;
    sdf_mesh_get_report(m, &r);
    *nv = r.vertices;
    *nt = r.triangles;
}

static char *finish(buf *b, size_t *size)
{
    *size = b->len;
    return b->data;
}

/* variant 0: plain LF, "f a b c"; 1: CRLF, comments, groups, v/vt/vn corners, no final
 * newline; 2: negative indices, v//vn corners, and quads where two triangles share an edge
 * diagonal in fan order (a b c + a c d -> a b c d). */
char *write_obj(const sdf_mesh *m, int variant, size_t *size)
{
    size_t nv, nt;
    counts(m, &nv, &nt);
    const float *v = sdf_mesh_vertices(m);
    const uint32_t *t = sdf_mesh_triangles(m);
    const char *eol = variant == 1 ? "\r\n" : "\n";
    buf b = {0};
    if (variant == 1)
        putf(&b, "# written by the sdfd tests%smtllib none.mtl%so part%s", eol, eol, eol);
    for (size_t i = 0; i < nv; i++) {
        putf(&b, "v %.9g %.9g %.9g%s", v[3 * i], v[3 * i + 1], v[3 * i + 2], eol);
        if (variant == 1)
            putf(&b, "vt 0.5 0.5%svn 0 0 1%s", eol, eol);
    }
    if (variant == 1)
        putf(&b, "g faces%susemtl none%ss off%s", eol, eol, eol);
    for (size_t i = 0; i < nt; i++) {
        const uint32_t *x = t + 3 * i;
        if (variant == 0)
            putf(&b, "f %u %u %u\n", x[0] + 1, x[1] + 1, x[2] + 1);
        else if (variant == 1)
            putf(&b, "f %u/%u/%u %u/%u/%u %u/%u/%u%s", x[0] + 1, x[0] + 1, x[0] + 1, x[1] + 1,
                 x[1] + 1, x[1] + 1, x[2] + 1, x[2] + 1, x[2] + 1, i + 1 < nt ? eol : "");
        else if (i + 1 < nt && t[3 * i + 3] == x[0] && t[3 * i + 4] == x[2]) {
            long n = (long)nv; /* a b c + a c d  ->  quad a b c d */
            putf(&b, "f %ld//1 %ld//1 %ld//1 %ld//1\n", (long)x[0] - n, (long)x[1] - n,
                 (long)x[2] - n, (long)t[3 * i + 5] - n);
            i++;
        } else {
            long n = (long)nv;
            putf(&b, "f %ld %ld %ld\n", (long)x[0] - n, (long)x[1] - n, (long)x[2] - n);
        }
    }
    return finish(&b, size);
}

char *write_off(const sdf_mesh *m, size_t *size)
{
    size_t nv, nt;
    counts(m, &nv, &nt);
    const float *v = sdf_mesh_vertices(m);
    const uint32_t *t = sdf_mesh_triangles(m);
    buf b = {0};
    putf(&b, "OFF\n# a comment\n%zu %zu 0\n\n", nv, nt);
    for (size_t i = 0; i < nv; i++)
        putf(&b, "%.9g %.9g %.9g\n", v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    for (size_t i = 0; i < nt; i++)
        putf(&b, "3 %u %u %u%s\n", t[3 * i], t[3 * i + 1], t[3 * i + 2], i % 7 ? "" : " 255 0 0");
    return finish(&b, size);
}

char *write_stl_ascii(const sdf_mesh *m, size_t *size)
{
    size_t nv, nt;
    counts(m, &nv, &nt);
    const float *v = sdf_mesh_vertices(m);
    const uint32_t *t = sdf_mesh_triangles(m);
    buf b = {0};
    /* Two solids, to exercise several blocks in one file. */
    for (size_t s = 0; s < 2; s++) {
        putf(&b, "solid part%zu\n", s);
        for (size_t i = s * nt / 2; i < (s + 1) * nt / 2 + (s ? nt % 2 : 0); i++) {
            putf(&b, "  facet normal 0 0 0\n    outer loop\n");
            for (int k = 0; k < 3; k++) {
                const float *p = v + 3 * t[3 * i + k];
                putf(&b, "      vertex %.9g %.9g %.9g\n", p[0], p[1], p[2]);
            }
            putf(&b, "    endloop\n  endfacet\n");
        }
        putf(&b, "endsolid part%zu\n", s);
    }
    return finish(&b, size);
}

static void put_le32(buf *b, uint32_t u)
{
    unsigned char x[4] = {(unsigned char)u, (unsigned char)(u >> 8), (unsigned char)(u >> 16),
                          (unsigned char)(u >> 24)};
    put(b, x, 4);
}

static void put_f32(buf *b, float f, int big_endian)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    unsigned char x[4];
    for (int i = 0; i < 4; i++)
        x[big_endian ? 3 - i : i] = (unsigned char)(u >> (8 * i));
    put(b, x, 4);
}

char *write_stl_binary(const sdf_mesh *m, const char *header, size_t *size)
{
    size_t nv, nt;
    counts(m, &nv, &nt);
    const float *v = sdf_mesh_vertices(m);
    const uint32_t *t = sdf_mesh_triangles(m);
    buf b = {0};
    char h[80] = {0};
    memcpy(h, header, strlen(header) < sizeof h ? strlen(header) : sizeof h);
    put(&b, h, 80);
    put_le32(&b, (uint32_t)nt);
    for (size_t i = 0; i < nt; i++) {
        for (int k = 0; k < 3; k++)
            put_f32(&b, 0, 0);
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++)
                put_f32(&b, v[3 * t[3 * i + k] + c], 0);
        put(&b, "\0\0", 2);
    }
    return finish(&b, size);
}

/* PLY with extra vertex properties (a double and a uchar colour before x), a face list with
 * uchar counts and uint indices plus an extra list, and an extra "edge" element. */
char *write_ply(const sdf_mesh *m, const char *encoding, size_t *size)
{
    size_t nv, nt;
    counts(m, &nv, &nt);
    const float *v = sdf_mesh_vertices(m);
    const uint32_t *t = sdf_mesh_triangles(m);
    int ascii = !strcmp(encoding, "ascii"), be = !strcmp(encoding, "binary_big_endian");
    buf b = {0};
    putf(&b, "ply\nformat %s 1.0\ncomment written by the sdfd tests\n", encoding);
    putf(&b, "element vertex %zu\nproperty double quality\nproperty uchar red\n"
             "property float x\nproperty float y\nproperty float z\n", nv);
    putf(&b, "element face %zu\nproperty list uchar uint vertex_indices\n"
             "property list ushort short flags\n", nt);
    putf(&b, "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n");
    for (size_t i = 0; i < nv; i++) {
        if (ascii) {
            putf(&b, "0.5 7 %.9g %.9g %.9g\n", v[3 * i], v[3 * i + 1], v[3 * i + 2]);
            continue;
        }
        double q = 0.5;
        unsigned char qb[8], red = 7;
        memcpy(qb, &q, 8);
        if (be)
            for (int k = 0; k < 4; k++) {
                unsigned char tmp = qb[k];
                qb[k] = qb[7 - k];
                qb[7 - k] = tmp;
            }
        put(&b, qb, 8);
        put(&b, &red, 1);
        for (int c = 0; c < 3; c++)
            put_f32(&b, v[3 * i + c], be);
    }
    for (size_t i = 0; i < nt; i++) {
        if (ascii) {
            putf(&b, "3 %u %u %u 2 -1 1\n", t[3 * i], t[3 * i + 1], t[3 * i + 2]);
            continue;
        }
        unsigned char three = 3;
        put(&b, &three, 1);
        for (int k = 0; k < 3; k++) {
            uint32_t x = t[3 * i + k];
            unsigned char xb[4];
            for (int j = 0; j < 4; j++)
                xb[be ? 3 - j : j] = (unsigned char)(x >> (8 * j));
            put(&b, xb, 4);
        }
        unsigned char flags[2 + 4] = {0, 2, 0xff, 0xff, 0, 1};
        if (!be) {
            flags[0] = 2, flags[1] = 0, flags[4] = 1, flags[5] = 0;
        }
        put(&b, flags, 6);
    }
    if (ascii)
        putf(&b, "0 1\n");
    else
        put(&b, "\0\0\0\0\0\0\0\1", 8);
    return finish(&b, size);
}
