/* body.c - query bodies in JSON, octet-stream and npy (see body.h). */
#include "transport/body.h"

#include "core/errors.h"
#include "core/numtext.h"

#include <ctype.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const char *const form_types[] = {"application/json", "application/octet-stream",
                                         "application/x-npy"};

int sdfd_form_from_type(const char *type)
{
    if (!type)
        return -1;
    size_t n = strcspn(type, ";");
    while (n && isspace((unsigned char)type[n - 1]))
        n--;
    for (int f = 0; f < 3; f++)
        if (strlen(form_types[f]) == n && !strncasecmp(type, form_types[f], n))
            return f;
    return -1;
}

const char *sdfd_form_type(sdfd_form form) { return form_types[form]; }

static int fail(char *err, size_t cap, int code, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static int fail(char *err, size_t cap, int code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, cap, fmt, ap);
    va_end(ap);
    return code;
}

/* ---- JSON ------------------------------------------------------------------------------ */

typedef struct json {
    const char *begin, *p, *end;
    float *points;
    size_t count, cap, max_points;
    char *err;
    size_t err_cap;
} json;

#define JSON_MAX_DEPTH 64

static void ws(json *j)
{
    while (j->p < j->end && (*j->p == ' ' || *j->p == '\t' || *j->p == '\n' || *j->p == '\r'))
        j->p++;
}

static int syntax(json *j, const char *what)
{
    return fail(j->err, j->err_cap, SDFD_ESYNTAX, "malformed JSON at byte %ld: %s",
                (long)(j->p - j->begin), what);
}

static int expect(json *j, char c)
{
    ws(j);
    if (j->p >= j->end || *j->p != c) {
        char what[32];
        snprintf(what, sizeof what, "expected '%c'", c);
        return syntax(j, what);
    }
    j->p++;
    return 0;
}

/* After an element of an array or object: 1 if a ',' announces another, 0 if `close` ends
 * it (both consumed), or SDFD_ESYNTAX. */
static int list_next(json *j, char close)
{
    ws(j);
    if (j->p < j->end && *j->p == ',') {
        j->p++;
        return 1;
    }
    return expect(j, close) ? SDFD_ESYNTAX : 0;
}

/* Consume `close` if the list is empty (returns 1), else leave it (returns 0). */
static int list_empty(json *j, char close)
{
    ws(j);
    if (j->p < j->end && *j->p == close) {
        j->p++;
        return 1;
    }
    return 0;
}

/* A JSON string; returns its raw contents (escapes left in place: keys and enum values
 * we compare never contain any). */
static int string(json *j, const char **s, size_t *n)
{
    if (expect(j, '"'))
        return SDFD_ESYNTAX;
    *s = j->p;
    while (j->p < j->end && *j->p != '"') {
        if ((unsigned char)*j->p < 0x20)
            return syntax(j, "control character in a string");
        if (*j->p == '\\' && ++j->p >= j->end)
            break;
        j->p++;
    }
    if (j->p >= j->end)
        return syntax(j, "unterminated string");
    *n = (size_t)(j->p - *s);
    j->p++;
    return 0;
}

/* A JSON number (strict grammar: no NaN, Inf, hex or leading '+'). */
static int number(json *j, double *v)
{
    ws(j);
    const char *s = j->p;
    if (s < j->end && *s == '-')
        s++;
    if (s >= j->end || !isdigit((unsigned char)*s))
        return syntax(j, "expected a number");
    const char *q = sdfd_parse_number(j->p, v);
    if (q == j->p || q > j->end)
        return syntax(j, "malformed number");
    j->p = q;
    return 0;
}

static int literal(json *j, const char *word)
{
    size_t n = strlen(word);
    if ((size_t)(j->end - j->p) < n || memcmp(j->p, word, n))
        return syntax(j, "unexpected token");
    j->p += n;
    return 0;
}

/* Parse and discard any value (for keys we do not use). */
static int skip_value(json *j, int depth)
{
    ws(j);
    if (depth > JSON_MAX_DEPTH)
        return syntax(j, "nested too deeply");
    if (j->p >= j->end)
        return syntax(j, "expected a value");
    const char *s;
    size_t n;
    double v;
    switch (*j->p) {
    case '"': return string(j, &s, &n);
    case 't': return literal(j, "true");
    case 'f': return literal(j, "false");
    case 'n': return literal(j, "null");
    case '[':
    case '{': {
        char close = *j->p == '[' ? ']' : '}';
        int object = close == '}', more;
        j->p++;
        if (list_empty(j, close))
            return 0;
        do {
            if (object && (string(j, &s, &n) || expect(j, ':')))
                return SDFD_ESYNTAX;
            if (skip_value(j, depth + 1))
                return SDFD_ESYNTAX;
        } while ((more = list_next(j, close)) == 1);
        return more;
    }
    default: return number(j, &v);
    }
}

static int push_coordinate(json *j, double v)
{
    if (j->count == j->cap) {
        if (j->cap >= 3 * j->max_points)
            return fail(j->err, j->err_cap, SDF_ELIMIT, "more than %zu points (limit)", j->max_points);
        size_t cap = j->cap ? 2 * j->cap : 3 * 1024;
        if (cap > 3 * j->max_points)
            cap = 3 * j->max_points;
        float *p = realloc(j->points, cap * sizeof *p);
        if (!p)
            return fail(j->err, j->err_cap, SDF_ENOMEM, "out of memory for points");
        j->points = p, j->cap = cap;
    }
    float f = (float)v;
    if (!isfinite(f)) /* finite JSON (the grammar has no NaN or Inf) beyond float32's range */
        return fail(j->err, j->err_cap, SDF_ENONFINITE,
                    "point %zu: coordinate %g is beyond float32's range (|x| < 3.4e38)",
                    j->count / 3, v);
    j->points[j->count++] = f;
    return 0;
}

/* After a failed number: a type error if another JSON value starts here, else bad syntax. */
static int not_a_number(json *j, const char *what)
{
    ws(j);
    if (j->p < j->end && strchr("\"{[tfn", *j->p))
        return fail(j->err, j->err_cap, SDF_EINVAL, "%s", what);
    return syntax(j, "expected a number");
}

/* The message for a nested point that is not three numbers, in what[64]: formatted only
 * when one fails (once per coordinate, it cost more than parsing the numbers). */
static const char *not_three(const json *j, char what[64])
{
    snprintf(what, 64, "point %zu is not an array of 3 numbers", j->count / 3);
    return what;
}

/* One element of a "points" array: [x, y, z] when nested, else one number. */
static int point_element(json *j, int nested)
{
    double v;
    int rc;
    if (!nested) {
        const char *at = j->p;
        if (number(j, &v)) {
            j->p = at;
            return not_a_number(j, "\"points\" must hold only numbers or only [x, y, z] arrays");
        }
        return push_coordinate(j, v);
    }
    ws(j);
    if (j->p >= j->end || *j->p != '[')
        return not_a_number(j, "\"points\" must hold only [x, y, z] arrays or only numbers");
    j->p++;
    char what[64]; /* the message, formatted only on failure */
    for (int k = 0; k < 3; k++) {
        if (k && expect(j, ','))
            return j->p < j->end && *j->p == ']'
                       ? fail(j->err, j->err_cap, SDF_EINVAL, "%s", not_three(j, what))
                       : SDFD_ESYNTAX;
        const char *at = j->p;
        if (number(j, &v)) {
            j->p = at;
            return not_a_number(j, not_three(j, what));
        }
        if ((rc = push_coordinate(j, v)))
            return rc;
    }
    ws(j);
    if (j->p < j->end && *j->p == ',')
        return fail(j->err, j->err_cap, SDF_EINVAL, "point %zu has more than 3 numbers",
                    j->count / 3 - 1);
    return expect(j, ']') ? SDFD_ESYNTAX : 0;
}

/* The elements from j->p up to and through the array's ']'; stops early, returning 0 with
 * *stopped set, on landing exactly at `stop` after a comma (NULL: never). */
static int point_elements(json *j, int nested, const char *stop, int *stopped)
{
    int rc, more;
    do {
        if ((rc = point_element(j, nested)))
            return rc;
        if ((more = list_next(j, ']')) == 1 && j->p == stop) {
            *stopped = 1;
            return 0;
        }
    } while (more == 1);
    return more;
}

/* Large arrays are parsed in two halves on two threads: number parsing was the larger part of
 * a JSON request's own cost, on one core while the query used both. The second half starts
 * right after a comma near the middle of the body (for nested arrays, one between "]" and
 * "["); it counts only if the first half, parsed here as always, lands exactly there after
 * an element. Otherwise, or if the second half failed or the halves pass the point limit
 * together, this thread just goes on from where it is, so results and error messages are
 * those of one sequential parse. */
#define PARALLEL_JSON_MIN_BYTES ((size_t)1 << 20)

typedef struct half_parse {
    json j;
    int nested, rc;
    char err[256]; /* its own: its messages are never shown (see above) */
} half_parse;

static void *parse_second_half(void *arg)
{
    half_parse *h = arg;
    int stopped = 0;
    h->rc = point_elements(&h->j, h->nested, NULL, &stopped);
    return NULL;
}

/* Where the second half could start: just after a comma at or past the middle of the
 * remaining text, between two points for nested arrays; NULL if none is found nearby. */
static const char *second_half_start(const json *j, int nested)
{
    const char *q = j->p + (j->end - j->p) / 2, *limit = q + 4096 < j->end ? q + 4096 : j->end;
    for (; q < limit; q++) {
        if (*q != ',')
            continue;
        if (!nested)
            return q + 1;
        const char *before = q, *after = q + 1;
        while (before > j->p && isspace((unsigned char)before[-1]))
            before--;
        while (after < j->end && isspace((unsigned char)*after))
            after++;
        if (before > j->p && before[-1] == ']' && after < j->end && *after == '[')
            return q + 1;
    }
    return NULL;
}

/* "points": [x, y, z, ...] or [[x, y, z], ...] */
static int points_array(json *j)
{
    ws(j);
    if (j->p >= j->end || *j->p != '[')
        return not_a_number(j, "\"points\" must be an array");
    j->p++;
    if (list_empty(j, ']'))
        return 0;
    ws(j);
    int nested = j->p < j->end && *j->p == '[', rc, stopped = 0;
    const char *split = (size_t)(j->end - j->p) >= PARALLEL_JSON_MIN_BYTES
                            ? second_half_start(j, nested) : NULL;
    half_parse second = {.j = *j, .nested = nested};
    second.j.p = split, second.j.points = NULL, second.j.count = second.j.cap = 0;
    second.j.err = second.err, second.j.err_cap = sizeof second.err;
    pthread_t helper;
    int apart = split && pthread_create(&helper, NULL, parse_second_half, &second) == 0;
    rc = point_elements(j, nested, apart ? split : NULL, &stopped);
    if (apart) {
        pthread_join(helper, NULL);
        if (!rc && stopped && !second.rc && j->count + second.j.count <= 3 * j->max_points) {
            float *all = realloc(j->points, (j->count + second.j.count + 1) * sizeof *all);
            if (all) { /* the halves joined: go on after the array */
                memcpy(all + j->count, second.j.points, second.j.count * sizeof *all);
                j->points = all, j->count += second.j.count, j->cap = j->count;
                j->p = second.j.p;
            } else {
                rc = fail(j->err, j->err_cap, SDF_ENOMEM, "out of memory for points");
            }
        } else if (!rc && stopped) { /* not joined: on from the split, alone */
            rc = point_elements(j, nested, NULL, &stopped);
        }
        free(second.j.points);
    }
    if (rc)
        return rc;
    if (!nested && j->count % 3)
        return fail(j->err, j->err_cap, SDF_EINVAL,
                    "a flat \"points\" array needs a multiple of 3 numbers, got %zu", j->count);
    return 0;
}

static int json_object(json *j, sdfd_query_params *params, int *have_points)
{
    if (expect(j, '{'))
        return fail(j->err, j->err_cap, SDFD_ESYNTAX, "the body must be a JSON object");
    int more = list_empty(j, '}') ? 0 : 1;
    /* The keys we read, each at most once: JSON leaves duplicates undefined, and taking one
     * of two "points" (or both) would answer a question nobody asked. */
    static const char *const read_keys[] = {"points", "mode", "sign", "interpolation", "filter"};
    unsigned seen = 0;
    while (more == 1) {
        const char *key, *s;
        size_t n, sn;
        int rc;
        if (string(j, &key, &n) || expect(j, ':'))
            return SDFD_ESYNTAX;
        for (unsigned k = 0; k < sizeof read_keys / sizeof read_keys[0]; k++) {
            if (strlen(read_keys[k]) != n || memcmp(key, read_keys[k], n))
                continue;
            if (seen >> k & 1)
                return fail(j->err, j->err_cap, SDF_EINVAL, "\"%s\" is given twice",
                            read_keys[k]);
            seen |= 1u << k;
        }
        if (n == 6 && !memcmp(key, "points", 6)) {
            if ((rc = points_array(j)))
                return rc;
            *have_points = 1;
        } else if ((n == 4 && !memcmp(key, "mode", 4)) || (n == 4 && !memcmp(key, "sign", 4)) ||
                   (n == 13 && !memcmp(key, "interpolation", 13))) {
            ws(j);
            if (j->p >= j->end || *j->p != '"')
                return fail(j->err, j->err_cap, SDF_EINVAL, "\"%.*s\" must be a string", (int)n, key);
            if ((rc = string(j, &s, &sn)))
                return rc;
            if (key[0] == 'm')
                params->mode = s, params->mode_len = sn;
            else if (key[0] == 's')
                params->sign = s, params->sign_len = sn;
            else
                params->interpolation = s, params->interpolation_len = sn;
        } else if (n == 6 && !memcmp(key, "filter", 6)) { /* kept as text: filterparams.c */
            ws(j);
            const char *start = j->p;
            if (j->p >= j->end || *j->p != '{')
                return fail(j->err, j->err_cap, SDF_EINVAL, "\"filter\" must be an object");
            if ((rc = skip_value(j, 1)))
                return rc;
            params->filter = start, params->filter_len = (size_t)(j->p - start);
        } else if ((rc = skip_value(j, 1))) {
            return rc;
        }
        more = list_next(j, '}');
    }
    if (more)
        return more;
    ws(j);
    return j->p == j->end ? 0 : syntax(j, "trailing characters after the object");
}

static int parse_json(char *body, size_t len, size_t max_points, sdfd_query_params *params,
                      float **points, size_t *count, int *owned, char *err, size_t cap)
{
    json j = {body, body, body + len, NULL, 0, 0, max_points, err, cap};
    int have_points = 0;
    int rc = json_object(&j, params, &have_points);
    if (!rc && !have_points)
        rc = fail(err, cap, SDF_EINVAL, "the body has no \"points\"");
    if (rc) {
        free(j.points);
        return rc;
    }
    *points = j.points;
    *count = j.count / 3;
    *owned = 1;
    return 0;
}

/* ---- octet-stream and npy ----------------------------------------------------------------- */

static int parse_npy(char *body, size_t len, size_t max_points, sdfd_query_params *params,
                     float **points, size_t *count, int *owned, char *err, size_t cap)
{
    sdf_npy_info info;
    sdf_diag diag;
    int rc = sdf_npy_parse(body, len, &info, &diag);
    if (rc)
        return fail(err, cap, rc == SDF_ETRUNC || rc == SDF_EPARSE ? SDFD_ESYNTAX : rc, "npy: %s",
                    diag.message);
    if (info.ndim < 2 || info.shape[info.ndim - 1] != 3)
        return fail(err, cap, SDF_EINVAL, "npy: points must have shape (N, 3) or (..., 3)");
    size_t n = 1; /* sdf_npy_parse checked the product against the bytes present */
    for (int i = 0; i + 1 < info.ndim; i++)
        n *= info.shape[i];
    if (n > max_points)
        return fail(err, cap, SDF_ELIMIT, "%zu points, more than the limit of %zu", n,
                    max_points);
    if (info.ndim > 2) {
        params->lead_ndim = info.ndim - 1;
        memcpy(params->lead, info.shape, (size_t)params->lead_ndim * sizeof *params->lead);
    }
    *count = n;
    /* NumPy pads its headers to 64 bytes, so float32 data is used in place; a header of
     * another length leaves it unaligned, and it is copied like float64 data. */
    if (info.dtype == SDF_NPY_F32 && info.data_offset % sizeof(float) == 0) {
        *points = (float *)(body + info.data_offset);
        *owned = 0;
        return 0;
    }
    float *p = malloc((3 * *count + 1) * sizeof *p);
    if (!p)
        return fail(err, cap, SDF_ENOMEM, "out of memory");
    for (size_t i = 0; i < 3 * *count; i++) {
        if (info.dtype == SDF_NPY_F32) {
            memcpy(&p[i], body + info.data_offset + 4 * i, 4);
            continue;
        }
        double d;
        memcpy(&d, body + info.data_offset + 8 * i, 8);
        p[i] = (float)d;
    }
    *points = p;
    *owned = 1;
    return 0;
}

int sdfd_parse_points(sdfd_form form, char *body, size_t len, size_t max_points,
                      sdfd_query_params *params, float **points, size_t *count, int *owned,
                      char *err, size_t err_cap)
{
    *owned = 0;
    if (form == SDFD_FORM_JSON)
        return parse_json(body, len, max_points, params, points, count, owned, err, err_cap);
    if (form == SDFD_FORM_NPY)
        return parse_npy(body, len, max_points, params, points, count, owned, err, err_cap);
    if (len % 12)
        return fail(err, err_cap, SDFD_ESYNTAX,
                    "octet-stream body of %zu bytes is not a whole number of 12-byte points", len);
    if (len / 12 > max_points)
        return fail(err, err_cap, SDF_ELIMIT, "%zu points, more than the limit of %zu", len / 12,
                    max_points);
    *points = (float *)body; /* malloc'd body: aligned */
    *count = len / 12;
    return 0;
}

/* ---- replies ----------------------------------------------------------------------------- */

static long npy_header(char *dst, size_t cap, sdf_proto_mode mode, size_t count,
                       const size_t *lead, int lead_ndim)
{
    size_t shape[SDFD_MAX_LEAD + 1] = {count};
    int n = lead_ndim ? lead_ndim : 1;
    if (lead_ndim)
        memcpy(shape, lead, (size_t)lead_ndim * sizeof *shape);
    if (mode == SDF_MODE_CLOSEST)
        return sdf_npy_write_header_descr(
            dst, cap, "[('distance', '<f4'), ('closest', '<f4', (3,)), ('triangle', '<u4')]", n,
            shape);
    shape[n] = sdf_proto_words(mode);
    return sdf_npy_write_header(dst, cap, shape[n] == 1 ? n : n + 1, shape);
}

int sdfd_reply_init(sdfd_reply *r, sdfd_form form, sdf_proto_mode mode, size_t count,
                    const size_t *lead, int lead_ndim)
{
    char header[512];
    long h = form == SDFD_FORM_NPY ? npy_header(header, sizeof header, mode, count, lead,
                                                lead_ndim)
                                   : 0;
    if (h < 0)
        return SDF_ENOMEM;
    size_t bytes = (size_t)h + 4 * sdf_proto_words(mode) * count;
    r->buffer = malloc(bytes + 1);
    if (!r->buffer)
        return SDF_ENOMEM;
    memcpy(r->buffer, header, (size_t)h);
    r->header = (size_t)h;
    r->words = (uint32_t *)(r->buffer + h);
    r->count = count;
    r->mode = mode;
    return 0;
}

typedef struct text {
    char *s;
    size_t len, cap;
} text;

static int reserve(text *t, size_t more)
{
    if (t->len + more <= t->cap)
        return 0;
    size_t cap = (t->len + more) * 2;
    char *s = realloc(t->s, cap);
    if (!s)
        return -1;
    t->s = s, t->cap = cap;
    return 0;
}

/* Entries [from, to) of a field, each after a ',' but the very first, into dst; returns
 * the bytes written (at most (to - from) * (width * 17 + 4)). */
typedef struct entries_job {
    const sdfd_reply *r;
    int word, width, is_uint;
    size_t from, to;
    char *dst;
    size_t len;
} entries_job;

static void *format_entries(void *arg)
{
    entries_job *e = arg;
    const sdfd_reply *r = e->r;
    unsigned w = sdf_proto_words(r->mode);
    char *o = e->dst;
    for (size_t i = e->from; i < e->to; i++) {
        const uint32_t *src = r->words + (size_t)w * i + e->word;
        if (i)
            *o++ = ',';
        if (e->width > 1)
            *o++ = '[';
        for (int k = 0; k < e->width; k++) {
            float f;
            memcpy(&f, &src[k], 4);
            if (k)
                *o++ = ',';
            if (e->is_uint)
                o += sprintf(o, "%u", src[k]);
            else
                o += sdfd_format_float(f, o);
        }
        if (e->width > 1)
            *o++ = ']';
    }
    e->len = (size_t)(o - e->dst);
    return NULL;
}

/* Fields of this many entries or more are printed in two halves on two threads (as large
 * bodies are parsed: body.c above); the text is the same. */
#define PARALLEL_JSON_MIN_ENTRIES ((size_t)1 << 16)

/* Append a float array field: "name":[v,...] or "name":[[x,y,z],...] */
static int json_field(text *t, const char *name, const sdfd_reply *r, int word, int width,
                      int is_uint)
{
    size_t per_entry = (size_t)width * 17 + 4;
    if (reserve(t, strlen(name) + 8 + r->count * per_entry))
        return -1;
    t->len += (size_t)sprintf(t->s + t->len, "%s\"%s\":[", t->len > 1 ? "," : "", name);
    size_t half = r->count >= PARALLEL_JSON_MIN_ENTRIES ? r->count / 2 : r->count;
    entries_job first = {r, word, width, is_uint, 0, half, t->s + t->len, 0};
    entries_job second = {r, word, width, is_uint, half, r->count, NULL, 0};
    pthread_t helper;
    int apart = half < r->count && (second.dst = malloc((r->count - half) * per_entry + 1)) &&
                pthread_create(&helper, NULL, format_entries, &second) == 0;
    if (!apart) /* one thread for all of it */
        first.to = r->count;
    format_entries(&first);
    t->len += first.len;
    if (apart) {
        pthread_join(helper, NULL);
        memcpy(t->s + t->len, second.dst, second.len);
        t->len += second.len;
    }
    free(second.dst);
    t->s[t->len++] = ']';
    return 0;
}

char *sdfd_reply_render(sdfd_reply *r, sdfd_form form, size_t *len)
{
    if (form != SDFD_FORM_JSON) {
        *len = r->header + 4 * sdf_proto_words(r->mode) * r->count;
        char *out = r->buffer;
        r->buffer = NULL;
        return out;
    }
    text t = {0};
    if (reserve(&t, 2))
        return NULL;
    t.s[t.len++] = '{';
    int rc = json_field(&t, "distance", r, 0, 1, 0);
    if (!rc && (r->mode == SDF_MODE_GRADIENT || r->mode == SDF_MODE_FILTERED_GRADIENT))
        rc = json_field(&t, "gradient", r, 1, 3, 0);
    if (!rc && r->mode == SDF_MODE_CLOSEST)
        rc = json_field(&t, "closest", r, 1, 3, 0) || json_field(&t, "triangle", r, 4, 1, 1);
    if (rc || reserve(&t, 2)) {
        free(t.s);
        return NULL;
    }
    t.s[t.len++] = '}';
    t.s[t.len] = '\0';
    *len = t.len;
    return t.s;
}
