/* obj.c - Wavefront OBJ: `v` and `f` records; everything else (vt, vn, g, o, s, usemtl,
 * mtllib, l, p, comments) is skipped. Faces accept the `v`, `v/vt`, `v//vn` and `v/vt/vn`
 * corner forms, negative (relative) indices, and polygons, which are fan-triangulated.
 * Lines may end in LF or CRLF and the last one needs no newline. Indices must refer to
 * vertices defined earlier in the file, so every error can name its line. */
#include <stdlib.h>

#include "mesh/parsers.h"
#include "mesh/text.h"

/* Parse one face corner token ("7", "-1", "7/2", "7//3", "7/2/3"); store a 0-based index. */
static int parse_corner(sdf__text *t, sdf__builder *b, uint32_t *out)
{
    long long i;
    if (sdf__text_integer(t, &i, 0, '/') != SDF__TEXT_OK)
        return sdf__builder_fail(b, SDF_EPARSE, "malformed face corner (expected v, v/vt, "
                                                "v//vn or v/vt/vn)");
    /* Texture and normal indices are not needed: skip to the end of the token. */
    while (t->p < t->end && *t->p != ' ' && *t->p != '\t' && *t->p != '\r' && *t->p != '\n')
        t->p++;
    long long resolved = i > 0 ? i - 1 : (long long)b->vertex_count + i;
    if (i == 0 || resolved < 0 || resolved >= (long long)b->vertex_count)
        return sdf__builder_fail(b, SDF_EINDEX,
                                 "face corner index %lld does not name one of the %zu vertices "
                                 "defined so far",
                                 i, b->vertex_count);
    *out = (uint32_t)resolved;
    return 0;
}

static int parse_vertex(sdf__text *t, sdf__builder *b)
{
    double c[3];
    for (int k = 0; k < 3; k++) {
        int rc = sdf__text_double(t, &c[k], 0);
        if (rc == SDF__TEXT_MISSING)
            return sdf__builder_fail(b, SDF_EPARSE, "vertex needs 3 coordinates, found %d", k);
        if (rc != SDF__TEXT_OK)
            return sdf__builder_fail(b, SDF_EPARSE, "malformed number in coordinate %d", k + 1);
    }
    /* An optional w or per-vertex colour may follow; the caller skips the rest of the line. */
    return sdf__builder_add_vertex(b, c[0], c[1], c[2]);
}

static int parse_face(sdf__text *t, sdf__builder *b, sdf__polygon *poly, size_t face_number)
{
    poly->count = 0;
    while (!sdf__text_at_eol(t)) {
        uint32_t index = 0;
        int rc = parse_corner(t, b, &index);
        if (rc)
            return rc;
        if (sdf__polygon_push(poly, index))
            return sdf__builder_fail(b, SDF_ENOMEM, "out of memory for a polygon");
    }
    return sdf__builder_add_polygon(b, poly->idx, poly->count, face_number);
}

int sdf__parse_obj(const char *data, size_t size, sdf__builder *b)
{
    sdf__text t;
    sdf__text_init(&t, data, size);
    sdf__polygon poly = {0};
    size_t faces = 0;
    int rc = 0;
    while (!rc && !sdf__text_eof(&t)) {
        b->line = t.line;
        b->offset = sdf__text_offset(&t);
        const char *tok;
        size_t n = sdf__text_token(&t, &tok);
        if (sdf__text_token_is(tok, n, "v"))
            rc = parse_vertex(&t, b);
        else if (sdf__text_token_is(tok, n, "f"))
            rc = parse_face(&t, b, &poly, faces++);
        sdf__text_next_line(&t);
    }
    sdf__polygon_free(&poly);
    return rc;
}
