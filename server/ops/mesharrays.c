/* mesharrays.c - meshes as JSON or npz arrays, turned into PLY bytes (mesharrays.h). The JSON
 * reader knows the one shape it reads: an object of "vertices" and "faces", each an array of
 * three-number rows; numbers go straight into growing arrays (cJSON would make a node of each
 * of a big mesh's millions of numbers). */
#include "ops/mesharrays.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/errors.h"
#include "sdf/sdf.h"
#include "ops/npz.h"
#include "core/numtext.h"

typedef struct arrays {
    float *v;       /* 3 per vertex */
    uint32_t *f;    /* 3 per face */
    double *raw_f;  /* JSON faces as read, checked once the vertices are known */
    size_t nv, nf, cap_v, cap_f;
    size_t max_faces;
} arrays;

static int fail(char *err, size_t cap, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, cap, fmt, ap);
    va_end(ap);
    return rc;
}

sdfd_mesh_body sdfd_mesh_body_kind(const char *format, const char *body, size_t len)
{
    if (format && strcasecmp(format, "auto"))
        return !strcasecmp(format, "json") ? SDFD_MESH_BODY_JSON
               : !strcasecmp(format, "npz") ? SDFD_MESH_BODY_NPZ : SDFD_MESH_BODY_FILE;
    if (sdfd_npz_sniff(body, len))
        return SDFD_MESH_BODY_NPZ;
    size_t i = 0;
    while (i < len && (body[i] == ' ' || body[i] == '\t' || body[i] == '\r' || body[i] == '\n'))
        i++;
    return i < len && body[i] == '{' ? SDFD_MESH_BODY_JSON : SDFD_MESH_BODY_FILE;
}

/* Room for one more row of three in *a (elements of `size` bytes, *cap rows). */
static int grow(void **a, size_t *cap, size_t rows, size_t size)
{
    if (rows < *cap)
        return 0;
    size_t n = *cap ? 2 * *cap : 1024;
    void *p = n > SIZE_MAX / (3 * size) ? NULL : realloc(*a, n * 3 * size);
    if (!p)
        return -1;
    *a = p, *cap = n;
    return 0;
}

/* ---- JSON ---------------------------------------------------------------------------- */

typedef struct json {
    const char *s, *start, *end;
    char *err;
    size_t cap;
} json;

static void ws(json *j)
{
    while (j->s < j->end && (*j->s == ' ' || *j->s == '\t' || *j->s == '\r' || *j->s == '\n'))
        j->s++;
}

static int syntax(json *j, const char *what)
{
    return fail(j->err, j->cap, SDFD_ESYNTAX, "malformed JSON at byte %ld: %s",
                (long)(j->s - j->start), what);
}

static int take(json *j, char c)
{
    ws(j);
    if (j->s < j->end && *j->s == c) {
        j->s++;
        return 1;
    }
    return 0;
}

/* One row [a, b, c] of `key` (row `row`) into out[3]. */
static int row(json *j, const char *key, size_t n, double out[3])
{
    if (!take(j, '['))
        return fail(j->err, j->cap, SDF_EINVAL, "%s[%zu] is not an array of three numbers", key,
                    n);
    size_t k = 0;
    if (take(j, ']'))
        return fail(j->err, j->cap, SDF_EINVAL, "%s[%zu] is empty, not three numbers", key, n);
    do {
        ws(j);
        if (j->s >= j->end || !(*j->s == '-' || (*j->s >= '0' && *j->s <= '9')))
            return fail(j->err, j->cap, SDF_EINVAL, "%s[%zu][%zu] is not a number", key, n, k);
        double v;
        const char *after = sdfd_parse_number(j->s, &v);
        if (after == j->s)
            return syntax(j, "a number expected");
        j->s = after;
        if (k < 3)
            out[k] = v;
        k++;
    } while (take(j, ','));
    if (!take(j, ']'))
        return syntax(j, "',' or ']' expected in a row");
    if (k != 3)
        return fail(j->err, j->cap, SDF_EINVAL, "%s[%zu] has %zu numbers, not 3 (rows must all "
                    "be [x, y, z] or [i, j, k])", key, n, k);
    return 0;
}

/* "vertices" or "faces": an array of rows. */
static int rows(json *j, arrays *a, int faces)
{
    const char *key = faces ? "faces" : "vertices";
    if (!take(j, '['))
        return fail(j->err, j->cap, SDF_EINVAL, "\"%s\" must be an array of rows", key);
    if (take(j, ']'))
        return 0;
    do {
        double r[3];
        size_t *n = faces ? &a->nf : &a->nv;
        if (faces && a->nf == a->max_faces)
            return fail(j->err, j->cap, SDF_ELIMIT, "more than the limit of %zu triangles",
                        a->max_faces);
        int rc = row(j, key, *n, r);
        if (rc)
            return rc;
        if (faces ? grow((void **)&a->raw_f, &a->cap_f, a->nf, sizeof(double))
                  : grow((void **)&a->v, &a->cap_v, a->nv, sizeof(float)))
            return fail(j->err, j->cap, SDF_ENOMEM, "out of memory for the %s", key);
        for (int k = 0; k < 3; k++) {
            if (faces) {
                a->raw_f[3 * *n + k] = r[k];
            } else if (!isfinite((float)r[k])) {
                return fail(j->err, j->cap, SDF_EINVAL, "vertices[%zu][%d] = %g is not a finite "
                            "float32", *n, k, r[k]);
            } else {
                a->v[3 * *n + k] = (float)r[k];
            }
        }
        ++*n;
    } while (take(j, ','));
    return take(j, ']') ? 0 : syntax(j, "',' or ']' expected between rows");
}

static int parse_json(const char *body, size_t len, arrays *a, char *err, size_t cap)
{
    json j = {body, body, body + len, err, cap};
    if (!take(&j, '{'))
        return syntax(&j, "the body must be a JSON object");
    int seen[2] = {0, 0};
    if (!take(&j, '}'))
        do {
            ws(&j);
            const char *k = j.s;
            if (j.s >= j.end || *j.s != '"')
                return syntax(&j, "a key expected");
            const char *q = memchr(k + 1, '"', (size_t)(j.end - k - 1));
            if (!q)
                return syntax(&j, "an unterminated key");
            j.s = q + 1;
            size_t n = (size_t)(q - k - 1);
            int which = n == 8 && !memcmp(k + 1, "vertices", 8) ? 0
                        : n == 5 && !memcmp(k + 1, "faces", 5) ? 1 : -1;
            if (which < 0)
                return fail(err, cap, SDF_EINVAL, "unknown key \"%.*s\": a mesh is "
                            "{\"vertices\": [[x, y, z], ...], \"faces\": [[i, j, k], ...]}",
                            (int)(n < 40 ? n : 40), k + 1);
            if (seen[which]++)
                return fail(err, cap, SDF_EINVAL, "\"%s\" is given twice",
                            which ? "faces" : "vertices");
            if (!take(&j, ':'))
                return syntax(&j, "':' expected");
            int rc = rows(&j, a, which);
            if (rc)
                return rc;
        } while (take(&j, ','));
    if (!take(&j, '}'))
        return syntax(&j, "',' or '}' expected");
    ws(&j);
    if (j.s != j.end)
        return syntax(&j, "text after the object");
    if (!seen[0] || !seen[1])
        return fail(err, cap, SDF_EINVAL, "\"%s\" is missing", seen[0] ? "faces" : "vertices");
    return 0;
}

/* The JSON faces, once the vertex count is known: integers in [0, nv). */
static int check_json_faces(arrays *a, char *err, size_t cap)
{
    if (!(a->f = malloc((3 * a->nf + 1) * sizeof *a->f)))
        return fail(err, cap, SDF_ENOMEM, "out of memory for the faces");
    for (size_t i = 0; i < 3 * a->nf; i++) {
        double x = a->raw_f[i];
        if (x != floor(x))
            return fail(err, cap, SDF_EINVAL, "faces[%zu][%zu] = %g is not an integer", i / 3,
                        i % 3, x);
        if (x < 0 || x >= (double)a->nv)
            return fail(err, cap, SDF_EINVAL, "faces[%zu][%zu] = %.0f is out of range: there "
                        "are %zu vertices", i / 3, i % 3, x, a->nv);
        a->f[i] = (uint32_t)x;
    }
    return 0;
}

/* ---- npz ----------------------------------------------------------------------------- */

/* The member `name` as an (N, 3) array of the allowed kind. */
static int member(const sdfd_npz *z, const char *name, int want_float, sdf_npy_info *info,
                  const unsigned char **data, char *err, size_t cap)
{
    const sdfd_npz_member *m = sdfd_npz_find(z, name);
    if (!m)
        return fail(err, cap, SDF_EINVAL, "npz: no member '%s' (a mesh has 'vertices' and "
                    "'faces')", name);
    sdf_diag diag;
    int rc = sdf_npy_parse_numeric(m->data, m->size, info, &diag);
    if (rc)
        return fail(err, cap, rc == SDF_ENOMEM ? rc : SDF_EFORMAT, "npz: '%s': %s", name,
                    diag.message);
    if ((info->kind == 'f') != want_float)
        return fail(err, cap, SDF_EINVAL, "npz: '%s' must hold %s", name,
                    want_float ? "float32 or float64 numbers" : "integers");
    if (info->ndim != 2 || info->shape[1] != 3)
        return fail(err, cap, SDF_EINVAL, "npz: '%s' must have shape (N, 3)", name);
    *data = m->data + info->data_offset;
    return 0;
}

/* An integer element of any size and signedness, as a double (exact up to 2^53, and past
 * that out of any vertex range anyway). */
static double int_at(const unsigned char *p, const sdf_npy_info *info)
{
    uint64_t u = 0;
    for (size_t b = 0; b < info->itemsize; b++)
        u |= (uint64_t)p[b] << (8 * b);
    if (info->kind == 'u' || !(u >> (8 * info->itemsize - 1) & 1))
        return (double)u;
    return -(double)((~u + 1) & (info->itemsize == 8 ? UINT64_MAX
                                                    : (UINT64_C(1) << (8 * info->itemsize)) - 1));
}

/* Inflated bytes an npz may hold per triangle allowed: float64 vertices and int64 faces of a
 * mesh with up to ~1.6 vertices per triangle (closed meshes have ~0.5), so a small archive
 * that inflates past any mesh the server takes is refused before it is inflated. */
#define NPZ_BYTES_PER_TRIANGLE 64
/* ... and at most this many times the body's bytes: arrays of a mesh deflate by a few times,
 * not the ~1000 a run of zeros does, so a small body cannot make the server fill gigabytes. */
#define NPZ_MAX_RATIO 32

static int parse_npz(const char *body, size_t len, size_t max_triangles, arrays *a, char *err,
                     size_t cap)
{
    sdfd_npz z;
    sdf_npy_info vi, fi;
    const unsigned char *vd, *fd;
    size_t most = max_triangles > (SIZE_MAX >> 21) / NPZ_BYTES_PER_TRIANGLE
                      ? SIZE_MAX >> 20 : NPZ_BYTES_PER_TRIANGLE * max_triangles + (1u << 20);
    if (len < (SIZE_MAX >> 21) / NPZ_MAX_RATIO && NPZ_MAX_RATIO * len + (1u << 20) < most)
        most = NPZ_MAX_RATIO * len + (1u << 20);
    static const char *const wanted[] = {"vertices", "faces", NULL};
    int rc = sdfd_npz_read(body, len, wanted, most, &z, err, cap);
    if (!rc)
        rc = member(&z, "vertices", 1, &vi, &vd, err, cap);
    if (!rc)
        rc = member(&z, "faces", 0, &fi, &fd, err, cap);
    if (!rc) {
        a->nv = vi.shape[0], a->nf = fi.shape[0];
        a->v = malloc((3 * a->nv + 1) * sizeof *a->v);
        a->f = malloc((3 * a->nf + 1) * sizeof *a->f);
        if (!a->v || !a->f)
            rc = fail(err, cap, SDF_ENOMEM, "out of memory for the arrays");
    }
    for (size_t i = 0; !rc && i < 3 * a->nv; i++) {
        double x;
        if (vi.itemsize == 4) {
            float f;
            memcpy(&f, vd + 4 * i, 4);
            x = f;
        } else {
            memcpy(&x, vd + 8 * i, 8);
        }
        if (!isfinite((float)x))
            rc = fail(err, cap, SDF_EINVAL, "vertices[%zu][%zu] = %g is not a finite float32",
                      i / 3, i % 3, x);
        a->v[i] = (float)x;
    }
    for (size_t i = 0; !rc && i < 3 * a->nf; i++) {
        double x = int_at(fd + fi.itemsize * i, &fi);
        if (x < 0 || x >= (double)a->nv)
            rc = fail(err, cap, SDF_EINVAL, "faces[%zu][%zu] = %.0f is out of range: there are "
                      "%zu vertices", i / 3, i % 3, x, a->nv);
        else
            a->f[i] = (uint32_t)x;
    }
    sdfd_npz_free(&z);
    return rc;
}

/* ---- both ---------------------------------------------------------------------------- */

int sdfd_mesh_arrays_to_ply(sdfd_mesh_body kind, const char *body, size_t len,
                            size_t max_triangles, void **ply, size_t *ply_len, char *err,
                            size_t cap)
{
    arrays a = {.max_faces = max_triangles};
    *ply = NULL, *ply_len = 0;
    int rc = kind == SDFD_MESH_BODY_NPZ ? parse_npz(body, len, max_triangles, &a, err, cap)
                                        : parse_json(body, len, &a, err, cap);
    if (!rc && kind == SDFD_MESH_BODY_JSON)
        rc = check_json_faces(&a, err, cap);
    if (!rc && !a.nf)
        rc = fail(err, cap, SDF_EINVAL, "the mesh has no faces");
    if (!rc && a.nf > max_triangles)
        rc = fail(err, cap, SDF_ELIMIT, "%zu triangles, more than the limit of %zu", a.nf,
                  max_triangles);
    size_t bound = rc ? 0 : sdf_mesh_write_bound(a.nv, a.nf, SDF_FORMAT_PLY);
    if (!rc && (!bound || !(*ply = malloc(bound))))
        rc = fail(err, cap, SDF_ENOMEM, "out of memory for the mesh");
    if (!rc && !(*ply_len = sdf_mesh_write(a.v, a.nv, a.f, a.nf, SDF_FORMAT_PLY, *ply, bound)))
        rc = fail(err, cap, SDF_ENOMEM, "the mesh could not be written");
    if (rc) {
        free(*ply);
        *ply = NULL;
    }
    free(a.v), free(a.f), free(a.raw_f);
    return rc;
}
