/* stl.c - STL, binary and ASCII, as triangle soup (load.c welds the vertices afterwards).
 *
 * Binary vs ASCII: a file is binary exactly when its size is 84 + 50 * (the count at byte
 * 80), whatever its header says: many binary exporters start the header with "solid".
 * Otherwise a file starting with "solid" is parsed as ASCII; anything else is reported as a
 * binary file whose size does not match its triangle count (truncated or padded).
 * ASCII files may hold several `solid ... endsolid` blocks; facets may be polygons. */
#include <string.h>

#include "mesh/parsers.h"
#include "mesh/text.h"

#define STL_HEADER 84
#define STL_RECORD 50

static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static float lef32(const unsigned char *p)
{
    uint32_t u = le32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static int starts_with_solid(const char *data, size_t size)
{
    size_t i = 0;
    while (i < size && (data[i] == ' ' || data[i] == '\t' || data[i] == '\r' || data[i] == '\n'))
        i++;
    return size - i >= 5 && memcmp(data + i, "solid", 5) == 0;
}

int sdf__stl_is_binary(const char *data, size_t size)
{
    if (size < STL_HEADER)
        return 0;
    uint64_t n = le32((const unsigned char *)data + 80);
    return (uint64_t)size == STL_HEADER + n * STL_RECORD;
}

static int parse_binary(const char *data, sdf__builder *b)
{
    const unsigned char *u = (const unsigned char *)data;
    size_t n = le32(u + 80);
    int rc = sdf__builder_reserve(b, 3 * n, n);
    if (rc)
        return rc;
    for (size_t i = 0; i < n; i++) {
        const unsigned char *rec = u + STL_HEADER + i * STL_RECORD;
        b->offset = (long long)(rec - u);
        uint32_t corner[3];
        for (int k = 0; k < 3; k++) {
            const unsigned char *v = rec + 12 + 12 * k; /* skip the facet normal */
            corner[k] = (uint32_t)b->vertex_count;
            rc = sdf__builder_add_vertex(b, lef32(v), lef32(v + 4), lef32(v + 8));
            if (rc)
                return rc;
        }
        rc = sdf__builder_add_polygon(b, corner, 3, i);
        if (rc)
            return rc;
    }
    return 0;
}

/* ASCII grammar, one state per nesting level. */
enum ascii_state { OUTSIDE, IN_SOLID, IN_FACET, IN_LOOP };

static int ascii_vertex(sdf__text *t, sdf__builder *b, sdf__polygon *poly)
{
    double c[3];
    for (int k = 0; k < 3; k++) {
        int rc = sdf__text_double(t, &c[k], 0);
        if (rc != SDF__TEXT_OK)
            return sdf__builder_fail(b, SDF_EPARSE, "vertex: %s coordinate %d",
                                     rc == SDF__TEXT_MISSING ? "missing" : "malformed", k + 1);
    }
    if (sdf__polygon_push(poly, (uint32_t)b->vertex_count))
        return sdf__builder_fail(b, SDF_ENOMEM, "out of memory for a polygon");
    return sdf__builder_add_vertex(b, c[0], c[1], c[2]);
}

/* Is token `tok` the keyword that is legal in `state`? Moves to the next state. */
static int ascii_step(sdf__text *t, sdf__builder *b, enum ascii_state *state, const char *tok,
                      size_t n, sdf__polygon *poly, size_t *facets)
{
    const char *word;
    size_t m;
    switch (*state) {
    case OUTSIDE:
        if (!sdf__text_token_is(tok, n, "solid"))
            break;
        sdf__text_next_line(t); /* the solid's name */
        *state = IN_SOLID;
        return 0;
    case IN_SOLID:
        if (sdf__text_token_is(tok, n, "endsolid")) {
            sdf__text_next_line(t);
            *state = OUTSIDE;
            return 0;
        }
        if (!sdf__text_token_is(tok, n, "facet"))
            break;
        sdf__text_next_line(t); /* "normal nx ny nz": recomputed from the vertices */
        *state = IN_FACET;
        return 0;
    case IN_FACET:
        if (sdf__text_token_is(tok, n, "endfacet")) {
            *state = IN_SOLID;
            return 0;
        }
        if (!sdf__text_token_is(tok, n, "outer"))
            break;
        m = sdf__text_token(t, &word);
        if (!sdf__text_token_is(word, m, "loop"))
            return sdf__builder_fail(b, SDF_EPARSE, "expected 'outer loop'");
        poly->count = 0;
        *state = IN_LOOP;
        return 0;
    case IN_LOOP:
        if (sdf__text_token_is(tok, n, "vertex"))
            return ascii_vertex(t, b, poly);
        if (!sdf__text_token_is(tok, n, "endloop"))
            break;
        *state = IN_FACET;
        return sdf__builder_add_polygon(b, poly->idx, poly->count, (*facets)++);
    }
    static const char *const expected[] = {"'solid'", "'facet' or 'endsolid'",
                                           "'outer loop' or 'endfacet'", "'vertex' or 'endloop'"};
    return sdf__builder_fail(b, SDF_EPARSE, "unexpected '%.*s', expected %s",
                             (int)(n > 32 ? 32 : n), tok, expected[*state]);
}

static int parse_ascii(const char *data, size_t size, sdf__builder *b)
{
    sdf__text t;
    sdf__text_init(&t, data, size);
    sdf__polygon poly = {0};
    enum ascii_state state = OUTSIDE;
    size_t facets = 0;
    int rc = 0;
    for (;;) {
        const char *tok;
        size_t n = sdf__text_token_any_line(&t, &tok);
        b->line = t.line;
        b->offset = (long long)(tok - data);
        if (n == 0)
            break;
        rc = ascii_step(&t, b, &state, tok, n, &poly, &facets);
        if (rc)
            break;
    }
    sdf__polygon_free(&poly);
    if (!rc && state != OUTSIDE)
        rc = sdf__builder_fail(b, SDF_ETRUNC, "the file ends inside a %s",
                               state == IN_SOLID ? "solid (no endsolid)" : "facet");
    return rc;
}

int sdf__parse_stl(const char *data, size_t size, sdf__builder *b)
{
    if (sdf__stl_is_binary(data, size))
        return parse_binary(data, b);
    if (starts_with_solid(data, size))
        return parse_ascii(data, size, b);
    if (size < STL_HEADER)
        return sdf__builder_fail(b, SDF_ETRUNC, "%zu bytes: too short for a binary STL header "
                                                "(84 bytes) and not ASCII STL", size);
    uint64_t n = le32((const unsigned char *)data + 80);
    b->offset = 80;
    return sdf__builder_fail(b, size < STL_HEADER + n * STL_RECORD ? SDF_ETRUNC : SDF_EPARSE,
                             "binary STL declares %llu triangles (%llu bytes) but the file has "
                             "%zu bytes",
                             (unsigned long long)n,
                             (unsigned long long)(STL_HEADER + n * STL_RECORD), size);
}
