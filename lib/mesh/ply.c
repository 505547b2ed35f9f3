/* ply.c - PLY (Stanford polygon format): ascii, binary_little_endian, binary_big_endian.
 *
 * The header declares elements (with counts) and their properties: scalars of any of the 8
 * types (char/int8 ... double/float64) and lists with any count and item types. We take x,
 * y, z from the `vertex` element and the `vertex_indices` (or `vertex_index`) list from the
 * `face` element; every other element and property is read past. Before anything is
 * reserved, each element's count times the smallest possible size of one row (binary: the
 * scalars plus an empty list's count; ascii: 2 bytes per value) must fit in the bytes left. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/parsers.h"
#include "mesh/text.h"

#define PLY_MAX_ELEMENTS 32
#define PLY_MAX_PROPERTIES 64

enum ply_type { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };
static const int type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

enum ply_encoding { ASCII, BINARY_LE, BINARY_BE };
enum ply_role { R_OTHER, R_X, R_Y, R_Z, R_INDICES };

typedef struct ply_property {
    enum ply_type type;       /* scalar type, or item type of a list */
    enum ply_type count_type; /* T_NONE for scalars */
    enum ply_role role;
} ply_property;

typedef struct ply_element {
    char name[32];
    unsigned long long count;
    int nprops;
    ply_property props[PLY_MAX_PROPERTIES];
    long line; /* header line, for messages */
} ply_element;

typedef struct ply_header {
    enum ply_encoding encoding;
    int nelems;
    ply_element elems[PLY_MAX_ELEMENTS];
    size_t data_start;
} ply_header;

static enum ply_type parse_type(const char *s, size_t n)
{
    static const struct { const char *name; enum ply_type type; } names[] = {
        {"char", T_I8},    {"int8", T_I8},     {"uchar", T_U8},    {"uint8", T_U8},
        {"short", T_I16},  {"int16", T_I16},   {"ushort", T_U16},  {"uint16", T_U16},
        {"int", T_I32},    {"int32", T_I32},   {"uint", T_U32},    {"uint32", T_U32},
        {"float", T_F32},  {"float32", T_F32}, {"double", T_F64},  {"float64", T_F64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (sdf__text_token_is(s, n, names[i].name))
            return names[i].type;
    return T_NONE;
}

/* ---- header ---------------------------------------------------------------------------- */

static int header_format(sdf__text *t, sdf__builder *b, ply_header *h)
{
    const char *w;
    size_t n = sdf__text_token(t, &w);
    if (sdf__text_token_is(w, n, "ascii"))
        h->encoding = ASCII;
    else if (sdf__text_token_is(w, n, "binary_little_endian"))
        h->encoding = BINARY_LE;
    else if (sdf__text_token_is(w, n, "binary_big_endian"))
        h->encoding = BINARY_BE;
    else
        return sdf__builder_fail(b, SDF_EFORMAT, "unknown PLY encoding '%.*s'",
                                 (int)(n > 32 ? 32 : n), w);
    return 0;
}

static int header_element(sdf__text *t, sdf__builder *b, ply_header *h)
{
    if (h->nelems == PLY_MAX_ELEMENTS)
        return sdf__builder_fail(b, SDF_ELIMIT, "more than %d elements", PLY_MAX_ELEMENTS);
    ply_element *e = &h->elems[h->nelems];
    memset(e, 0, sizeof *e);
    const char *w;
    size_t n = sdf__text_token(t, &w);
    long long count;
    if (n == 0 || n >= sizeof e->name || sdf__text_integer(t, &count, 0, 0) || count < 0)
        return sdf__builder_fail(b, SDF_EPARSE, "expected 'element <name> <count>'");
    memcpy(e->name, w, n);
    e->count = (unsigned long long)count;
    e->line = t->line;
    h->nelems++;
    return 0;
}

static int header_property(sdf__text *t, sdf__builder *b, ply_header *h)
{
    if (h->nelems == 0)
        return sdf__builder_fail(b, SDF_EPARSE, "property before any element");
    ply_element *e = &h->elems[h->nelems - 1];
    if (e->nprops == PLY_MAX_PROPERTIES)
        return sdf__builder_fail(b, SDF_ELIMIT, "more than %d properties", PLY_MAX_PROPERTIES);
    ply_property *p = &e->props[e->nprops];
    const char *w;
    size_t n = sdf__text_token(t, &w);
    *p = (ply_property){0};
    if (sdf__text_token_is(w, n, "list")) {
        n = sdf__text_token(t, &w);
        p->count_type = parse_type(w, n);
        if (p->count_type == T_NONE || p->count_type == T_F32 || p->count_type == T_F64)
            return sdf__builder_fail(b, SDF_EPARSE, "bad list count type '%.*s'",
                                     (int)(n > 32 ? 32 : n), w);
        n = sdf__text_token(t, &w);
    }
    p->type = parse_type(w, n);
    if (p->type == T_NONE)
        return sdf__builder_fail(b, SDF_EPARSE, "unknown property type '%.*s'",
                                 (int)(n > 32 ? 32 : n), w);
    n = sdf__text_token(t, &w);
    if (n == 0)
        return sdf__builder_fail(b, SDF_EPARSE, "property without a name");
    int is_list = p->count_type != T_NONE;
    if (!strcmp(e->name, "vertex") && !is_list) {
        if (sdf__text_token_is(w, n, "x")) p->role = R_X;
        if (sdf__text_token_is(w, n, "y")) p->role = R_Y;
        if (sdf__text_token_is(w, n, "z")) p->role = R_Z;
    }
    if (!strcmp(e->name, "face") && is_list &&
        (sdf__text_token_is(w, n, "vertex_indices") || sdf__text_token_is(w, n, "vertex_index")))
        p->role = R_INDICES;
    e->nprops++;
    return 0;
}

/* Some exporters write free text into the header without the `comment` keyword (Blender 2.4x:
 * "Created by Blender3D 247 - www.blender.org, source file: ''"). Before the first element
 * nothing can depend on such a line, so it is taken as a comment and reported as a warning;
 * among the elements an unknown keyword may be a property we would misread: refused. */
static int unknown_header_line(sdf__builder *b, const ply_header *h, const char *w, size_t n)
{
    int shown = (int)(n > 32 ? 32 : n);
    if (h->nelems > 0)
        return sdf__builder_fail(b, SDF_EPARSE, "unknown header keyword '%.*s'", shown, w);
    sdf__builder_warn(b, "unknown header keyword '%.*s': the line is taken as a comment", shown,
                      w);
    return 0;
}

static int parse_header(sdf__text *t, sdf__builder *b, ply_header *h)
{
    const char *w;
    size_t n = sdf__text_token(t, &w);
    if (!sdf__text_token_is(w, n, "ply"))
        return sdf__builder_fail(b, SDF_EFORMAT, "missing 'ply' magic");
    int have_format = 0;
    for (;;) {
        sdf__text_next_line(t);
        b->line = t->line;
        b->offset = sdf__text_offset(t);
        if (sdf__text_eof(t))
            return sdf__builder_fail(b, SDF_ETRUNC, "header has no end_header");
        n = sdf__text_token(t, &w);
        int rc = 0;
        if (sdf__text_token_is(w, n, "format")) {
            rc = header_format(t, b, h);
            have_format = 1;
        } else if (sdf__text_token_is(w, n, "element")) {
            rc = header_element(t, b, h);
        } else if (sdf__text_token_is(w, n, "property")) {
            rc = header_property(t, b, h);
        } else if (sdf__text_token_is(w, n, "end_header")) {
            sdf__text_next_line(t);
            h->data_start = (size_t)sdf__text_offset(t);
            break;
        } else if (!sdf__text_token_is(w, n, "comment") && !sdf__text_token_is(w, n, "obj_info") &&
                   n != 0) {
            rc = unknown_header_line(b, h, w, n);
        }
        if (rc)
            return rc;
    }
    if (!have_format)
        return sdf__builder_fail(b, SDF_EFORMAT, "header has no format line");
    return 0;
}

/* Which elements hold the vertices and faces; refuse files we cannot read in one pass. */
static int find_elements(sdf__builder *b, const ply_header *h, int *vi, int *fi)
{
    *vi = *fi = -1;
    b->line = 0; /* whole-file problems: no location */
    b->offset = -1;
    for (int i = 0; i < h->nelems; i++) {
        if (!strcmp(h->elems[i].name, "vertex"))
            *vi = i;
        if (!strcmp(h->elems[i].name, "face"))
            *fi = i;
    }
    if (*vi < 0)
        return sdf__builder_fail(b, SDF_EPARSE, "no vertex element");
    int roles = 0;
    for (int k = 0; k < h->elems[*vi].nprops; k++)
        roles |= 1 << h->elems[*vi].props[k].role;
    if ((roles & 0xE) != 0xE)
        return sdf__builder_fail(b, SDF_EPARSE, "the vertex element lacks scalar x, y and z");
    if (*fi < 0)
        return sdf__builder_fail(b, SDF_EEMPTY, "no face element (a point cloud is not a mesh)");
    roles = 0;
    for (int k = 0; k < h->elems[*fi].nprops; k++)
        roles |= 1 << h->elems[*fi].props[k].role;
    if (!(roles & (1 << R_INDICES)))
        return sdf__builder_fail(b, SDF_EPARSE, "the face element has no vertex_indices list");
    if (*fi < *vi)
        return sdf__builder_fail(b, SDF_EFORMAT, "faces before vertices are not supported");
    return 0;
}

/* Smallest number of bytes one row of `e` can take. */
static size_t min_row_bytes(const ply_element *e, enum ply_encoding enc)
{
    size_t bytes = 0;
    for (int k = 0; k < e->nprops; k++) {
        const ply_property *p = &e->props[k];
        if (enc == ASCII)
            bytes += 2;
        else
            bytes += (size_t)type_size[p->count_type != T_NONE ? p->count_type : p->type];
    }
    return bytes ? bytes : 1;
}

static int check_counts(sdf__builder *b, const ply_header *h, size_t size, int vi, int fi)
{
    size_t room = size - h->data_start + (h->encoding == ASCII); /* no final newline */
    for (int i = 0; i < h->nelems; i++) {
        const ply_element *e = &h->elems[i];
        size_t row = min_row_bytes(e, h->encoding);
        if (e->count > room / row) {
            b->line = e->line;
            return sdf__builder_fail(b, SDF_ETRUNC,
                                     "element '%s' declares %llu rows, more than the %zu data "
                                     "bytes can hold",
                                     e->name, e->count, size - h->data_start);
        }
        room -= (size_t)e->count * row;
    }
    return sdf__builder_reserve(b, (size_t)h->elems[vi].count, (size_t)h->elems[fi].count);
}

/* ---- data ------------------------------------------------------------------------------ */

typedef struct ply_reader {
    const ply_header *h;
    sdf__text text;           /* ascii */
    const unsigned char *bin; /* binary */
    size_t size, pos;
    sdf__builder *b;
} ply_reader;

static double decode(const unsigned char *p, enum ply_type type, int big_endian)
{
    unsigned char le[8];
    int n = type_size[type];
    for (int i = 0; i < n; i++)
        le[i] = big_endian ? p[n - 1 - i] : p[i];
    uint64_t u = 0;
    for (int i = n - 1; i >= 0; i--)
        u = u << 8 | le[i];
    switch (type) {
    case T_I8: return (double)(int8_t)u;
    case T_U8: return (double)(uint8_t)u;
    case T_I16: return (double)(int16_t)u;
    case T_U16: return (double)(uint16_t)u;
    case T_I32: return (double)(int32_t)u;
    case T_U32: return (double)(uint32_t)u;
    case T_F32: { uint32_t w = (uint32_t)u; float f; memcpy(&f, &w, 4); return f; }
    case T_F64: { double d; memcpy(&d, &u, 8); return d; }
    default: return 0;
    }
}

/* Read one value of `type`; errors name the element row. */
static int read_value(ply_reader *r, enum ply_type type, double *out, const char *elem,
                      unsigned long long row)
{
    sdf__builder *b = r->b;
    if (r->h->encoding == ASCII) {
        b->line = r->text.line;
        b->offset = sdf__text_offset(&r->text);
        int rc = sdf__text_double(&r->text, out, 1);
        if (rc == SDF__TEXT_OK)
            return 0;
        return sdf__builder_fail(b, rc == SDF__TEXT_MISSING ? SDF_ETRUNC : SDF_EPARSE,
                                 "%s %llu: %s value", elem, row,
                                 rc == SDF__TEXT_MISSING ? "missing" : "malformed");
    }
    b->line = 0;
    b->offset = (long long)r->pos;
    if ((size_t)type_size[type] > r->size - r->pos)
        return sdf__builder_fail(b, SDF_ETRUNC, "%s %llu ends past the end of the file", elem, row);
    *out = decode(r->bin + r->pos, type, r->h->encoding == BINARY_BE);
    r->pos += (size_t)type_size[type];
    return 0;
}

static int read_row(ply_reader *r, const ply_element *e, unsigned long long row, double xyz[3],
                    sdf__polygon *poly)
{
    sdf__builder *b = r->b;
    for (int k = 0; k < e->nprops; k++) {
        const ply_property *p = &e->props[k];
        double v;
        int rc;
        if (p->count_type == T_NONE) {
            if ((rc = read_value(r, p->type, &v, e->name, row)))
                return rc;
            if (p->role >= R_X && p->role <= R_Z)
                xyz[p->role - R_X] = v;
            continue;
        }
        if ((rc = read_value(r, p->count_type, &v, e->name, row)))
            return rc;
        size_t left = r->h->encoding == ASCII ? (size_t)(r->text.end - r->text.p) / 2 + 1
                                              : (r->size - r->pos) / (size_t)type_size[p->type];
        if (v < 0 || v != floor(v) || v > (double)left)
            return sdf__builder_fail(b, v > (double)left ? SDF_ETRUNC : SDF_EPARSE,
                                     "%s %llu: list count %g is %s", e->name, row, v,
                                     v > (double)left ? "more than the file can hold" : "invalid");
        if (p->role == R_INDICES)
            poly->count = 0;
        for (size_t i = 0, n = (size_t)v; i < n; i++) {
            if ((rc = read_value(r, p->type, &v, e->name, row)))
                return rc;
            if (p->role != R_INDICES)
                continue;
            if (v < 0 || v != floor(v) || v >= (double)b->vertex_count)
                return sdf__builder_fail(b, SDF_EINDEX,
                                         "face %llu uses vertex index %g, but the file has %zu "
                                         "vertices", row, v, b->vertex_count);
            if (sdf__polygon_push(poly, (uint32_t)v))
                return sdf__builder_fail(b, SDF_ENOMEM, "out of memory for a polygon");
        }
    }
    return 0;
}

static int read_elements(ply_reader *r, int vi, int fi)
{
    sdf__polygon poly = {0};
    int rc = 0;
    for (int i = 0; !rc && i < r->h->nelems; i++) {
        const ply_element *e = &r->h->elems[i];
        for (unsigned long long row = 0; !rc && row < e->count; row++) {
            double xyz[3] = {0, 0, 0};
            rc = read_row(r, e, row, xyz, &poly);
            if (rc)
                break;
            if (i == vi)
                rc = sdf__builder_add_vertex(r->b, xyz[0], xyz[1], xyz[2]);
            else if (i == fi)
                rc = sdf__builder_add_polygon(r->b, poly.idx, poly.count, (size_t)row);
        }
    }
    sdf__polygon_free(&poly);
    return rc;
}

int sdf__parse_ply(const char *data, size_t size, sdf__builder *b)
{
    ply_header *h = calloc(1, sizeof *h);
    if (!h)
        return sdf__builder_fail(b, SDF_ENOMEM, "out of memory");
    ply_reader r = {.h = h, .bin = (const unsigned char *)data, .size = size, .b = b};
    sdf__text_init(&r.text, data, size);
    b->line = 1;
    b->offset = 0;
    int vi, fi;
    int rc = parse_header(&r.text, b, h);
    if (!rc)
        rc = find_elements(b, h, &vi, &fi);
    if (!rc)
        rc = check_counts(b, h, size, vi, fi);
    if (!rc) {
        r.pos = h->data_start;
        rc = read_elements(&r, vi, fi);
    }
    free(h);
    return rc;
}
