/* off.c - Object File Format (OFF): an `OFF` keyword (optionally C/N/ST prefixed, which add
 * per-vertex colour, normal or texture columns that are skipped), the counts
 * `vertices faces [edges]`, one vertex per line and one polygon per line (`n i0 .. in-1`,
 * optionally followed by a colour). `#` comments may appear anywhere. Binary OFF and
 * 4D/nD variants are refused. The counts are checked against the file's size before any
 * room is reserved: each vertex needs at least 6 bytes ("0 0 0\n") and each face 8. */
#include <string.h>

#include "mesh/parsers.h"
#include "mesh/text.h"

/* Skip whitespace, blank lines and # comments. */
static void skip_filler(sdf__text *t)
{
    for (;;) {
        sdf__text_skip_space(t);
        if (t->p < t->end && *t->p == '#')
            sdf__text_next_line(t);
        else
            return;
    }
}

static void locate(sdf__builder *b, const sdf__text *t)
{
    b->line = t->line;
    b->offset = sdf__text_offset(t);
}

static int parse_keyword(sdf__text *t, sdf__builder *b)
{
    skip_filler(t);
    locate(b, t);
    const char *tok;
    size_t n = sdf__text_token(t, &tok);
    if (n < 3 || memcmp(tok + n - 3, "OFF", 3) != 0)
        return sdf__builder_fail(b, SDF_EFORMAT, "expected the OFF keyword");
    for (size_t i = 0; i + 3 < n; i++) {
        if (!strchr("CNST", tok[i]))
            return sdf__builder_fail(b, SDF_EFORMAT, "unsupported OFF variant '%.*s' (only "
                                                     "3D [ST][C][N]OFF)", (int)n, tok);
    }
    if (!sdf__text_at_eol(t)) {
        const char *word;
        size_t m = sdf__text_token(t, &word);
        if (sdf__text_token_is(word, m, "BINARY"))
            return sdf__builder_fail(b, SDF_EFORMAT, "binary OFF is not supported");
        t->p = word; /* the counts share the keyword's line */
    }
    return 0;
}

static int parse_count(sdf__text *t, sdf__builder *b, const char *what, long long *out)
{
    skip_filler(t);
    locate(b, t);
    if (sdf__text_integer(t, out, 0, 0) != SDF__TEXT_OK || *out < 0)
        return sdf__builder_fail(b, SDF_EPARSE, "expected the %s count", what);
    return 0;
}

static int parse_vertices(sdf__text *t, sdf__builder *b, long long count)
{
    for (long long v = 0; v < count; v++) {
        skip_filler(t);
        locate(b, t);
        double c[3];
        for (int k = 0; k < 3; k++) {
            int rc = sdf__text_double(t, &c[k], 0);
            if (rc != SDF__TEXT_OK)
                return sdf__builder_fail(b, sdf__text_eof(t) ? SDF_ETRUNC : SDF_EPARSE,
                                         "vertex %lld: %s coordinate %d", v,
                                         rc == SDF__TEXT_MISSING ? "missing" : "malformed", k + 1);
        }
        int rc = sdf__builder_add_vertex(b, c[0], c[1], c[2]);
        if (rc)
            return rc;
        sdf__text_next_line(t); /* colour, normal or texture columns */
    }
    return 0;
}

static int parse_faces(sdf__text *t, sdf__builder *b, long long count)
{
    sdf__polygon poly = {0};
    int rc = 0;
    for (long long f = 0; !rc && f < count; f++) {
        skip_filler(t);
        locate(b, t);
        long long n;
        if (sdf__text_integer(t, &n, 0, 0) != SDF__TEXT_OK) {
            rc = sdf__builder_fail(b, sdf__text_eof(t) ? SDF_ETRUNC : SDF_EPARSE,
                                   "face %lld: expected its vertex count", f);
            break;
        }
        /* Each corner needs at least 2 bytes: a count the rest of the file cannot hold is
         * refused before the polygon grows. */
        if (n < 3 || n > (long long)(t->end - t->p) / 2 + 1) {
            rc = sdf__builder_fail(b, n < 3 ? SDF_EPARSE : SDF_ETRUNC,
                                   "face %lld: vertex count %lld is %s", f, n,
                                   n < 3 ? "below 3" : "more than the file can hold");
            break;
        }
        poly.count = 0;
        for (long long k = 0; !rc && k < n; k++) {
            long long i;
            if (sdf__text_integer(t, &i, 1, 0) != SDF__TEXT_OK)
                rc = sdf__builder_fail(b, sdf__text_eof(t) ? SDF_ETRUNC : SDF_EPARSE,
                                       "face %lld: malformed or missing vertex index %lld", f, k);
            else if (i < 0 || i >= (long long)b->vertex_count)
                rc = sdf__builder_fail(b, SDF_EINDEX,
                                       "face %lld uses vertex index %lld, but the file declares "
                                       "%zu vertices", f, i, b->vertex_count);
            else if (sdf__polygon_push(&poly, (uint32_t)i))
                rc = sdf__builder_fail(b, SDF_ENOMEM, "out of memory for a polygon");
        }
        if (!rc)
            rc = sdf__builder_add_polygon(b, poly.idx, poly.count, (size_t)f);
        sdf__text_next_line(t); /* optional face colour */
    }
    sdf__polygon_free(&poly);
    return rc;
}

int sdf__parse_off(const char *data, size_t size, sdf__builder *b)
{
    sdf__text t;
    sdf__text_init(&t, data, size);
    long long nv, nf, ne;
    int rc = parse_keyword(&t, b);
    if (!rc)
        rc = parse_count(&t, b, "vertex", &nv);
    if (!rc)
        rc = parse_count(&t, b, "face", &nf);
    if (rc)
        return rc;
    if (!sdf__text_at_eol(&t) && sdf__text_integer(&t, &ne, 0, 0) != SDF__TEXT_OK)
        return sdf__builder_fail(b, SDF_EPARSE, "malformed edge count");
    long long room = (long long)(t.end - t.p) + 1;
    if (nv > room / 6 || nf > (room - nv * 6) / 8)
        return sdf__builder_fail(b, SDF_ETRUNC,
                                 "the header declares %lld vertices and %lld faces, more than "
                                 "the remaining %lld bytes can hold",
                                 nv, nf, room - 1);
    rc = sdf__builder_reserve(b, (size_t)nv, (size_t)nf);
    if (!rc)
        rc = parse_vertices(&t, b, nv);
    if (!rc)
        rc = parse_faces(&t, b, nf);
    return rc;
}
