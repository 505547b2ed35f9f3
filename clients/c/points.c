/* points.c - sdfq's point files in and result files out (points.h). The npy reader takes
 * exactly what the server's own npy bodies take (float32 or float64, C order, shape (N, 3))
 * and checks that the data is exactly N x 3 items long; the CSV reader accepts one x,y,z a
 * line, blank lines, and a first line that is a header. Floats go out as %.9g, which reads
 * back as the same float32. */
#include "points.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sdfq.h"

static int refuse(const char *what, const char *why)
{
    fprintf(stderr, "sdfq: %s: %s\n", what, why);
    return SDFQ_INPUT;
}

/* ---- reading files ----------------------------------------------------------------------- */

static int read_stream(FILE *f, const char *what, unsigned char **data, size_t *size)
{
    size_t cap = 1 << 16, n = 0;
    unsigned char *buf = malloc(cap + 1);
    for (;;) {
        if (buf && n == cap) {
            unsigned char *grown = cap > SIZE_MAX / 4 ? NULL : realloc(buf, 2 * cap + 1);
            if (!grown)
                free(buf);
            buf = grown;
            cap *= 2;
        }
        if (!buf)
            return refuse(what, "out of memory");
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0)
            break;
    }
    if (ferror(f)) {
        free(buf);
        return refuse(what, strerror(errno));
    }
    buf[n] = 0; /* the CSV parser may look one byte past a number */
    *data = buf;
    *size = n;
    return 0;
}

static int read_file(const char *path, unsigned char **data, size_t *size)
{
    if (!strcmp(path, "-"))
        return read_stream(stdin, "standard input", data, size);
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "sdfq: cannot read %s: %s\n", path, strerror(errno));
        return SDFQ_INPUT;
    }
    int rc = read_stream(f, path, data, size);
    fclose(f);
    return rc;
}

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && !strcasecmp(s + n - m, suffix);
}

int sdfq_read_points(const char *path, sdfq_points *out)
{
    unsigned char *data;
    size_t size;
    int rc = read_file(path, &data, &size);
    if (rc)
        return rc;
    const char *what = strcmp(path, "-") ? path : "standard input";
    int npy = ends_with(path, ".npy") ||
              (!ends_with(path, ".csv") && size >= 6 && !memcmp(data, "\x93NUMPY", 6));
    rc = npy ? sdfq_parse_npy(data, size, what, out)
             : sdfq_parse_csv((const char *)data, size, what, out);
    free(data);
    return rc;
}

void sdfq_points_free(sdfq_points *p)
{
    free(p->xyz);
    *p = (sdfq_points){0};
}

/* ---- npy --------------------------------------------------------------------------------- */

/* The text after `'key':` in the header dict, or NULL. */
static const char *dict_value(const char *dict, const char *key)
{
    char quoted[32];
    snprintf(quoted, sizeof quoted, "'%s'", key);
    const char *p = strstr(dict, quoted);
    if (!p)
        return NULL;
    p += strlen(quoted);
    while (*p == ' ')
        p++;
    if (*p++ != ':')
        return NULL;
    while (*p == ' ')
        p++;
    return p;
}

/* shape (N, 3): N, or -1 for any other shape. */
static long long parse_shape(const char *s)
{
    if (!s || *s++ != '(')
        return -1;
    char *end;
    errno = 0;
    long long n = strtoll(s, &end, 10);
    if (errno || end == s || n < 0 || *s == '-')
        return -1;
    s = end;
    while (*s == ' ')
        s++;
    if (*s++ != ',')
        return -1;
    while (*s == ' ')
        s++;
    if (*s++ != '3')
        return -1;
    while (*s == ' ' || *s == ',')
        s++;
    return *s == ')' ? n : -1;
}

/* Header fields: item size (4 or 8) and N; 0 or SDFQ_INPUT. */
static int npy_header(const char *dict, const char *what, size_t *item, size_t *n)
{
    const char *descr = dict_value(dict, "descr");
    const char *fortran = dict_value(dict, "fortran_order");
    if (descr && !strncmp(descr, "'<f4'", 5))
        *item = 4;
    else if (descr && !strncmp(descr, "'<f8'", 5))
        *item = 8;
    else
        return refuse(what, "npy dtype must be little-endian float32 or float64 ('<f4', '<f8')");
    if (!fortran || strncmp(fortran, "False", 5))
        return refuse(what, "npy array must be in C order (fortran_order False)");
    long long rows = parse_shape(dict_value(dict, "shape"));
    if (rows < 0)
        return refuse(what, "npy array must have shape (N, 3)");
    *n = (size_t)rows;
    return 0;
}

int sdfq_parse_npy(const unsigned char *data, size_t size, const char *what, sdfq_points *out)
{
    if (size < 10 || memcmp(data, "\x93NUMPY", 6))
        return refuse(what, "not an npy file (no \\x93NUMPY magic)");
    size_t prefix = data[6] == 1 ? 10 : 12;
    if (data[6] < 1 || data[6] > 3 || size < prefix)
        return refuse(what, "unsupported npy version (1, 2 and 3 are read)");
    size_t hl = data[8] | (size_t)data[9] << 8;
    if (prefix == 12)
        hl |= (size_t)data[10] << 16 | (size_t)data[11] << 24;
    if (hl > size - prefix || hl > 65536)
        return refuse(what, "truncated npy: the header runs past the end of the file");
    char *dict = malloc(hl + 1);
    if (!dict)
        return refuse(what, "out of memory");
    memcpy(dict, data + prefix, hl);
    dict[hl] = 0;
    size_t item, n;
    int rc = npy_header(dict, what, &item, &n);
    free(dict);
    if (rc)
        return rc;
    size_t body = size - prefix - hl;
    if (n > body / (3 * item) || body != n * 3 * item) {
        char why[200];
        snprintf(why, sizeof why, "npy data is %zu bytes, but its header says %zu x 3 float%d "
                 "(truncated or padded)", body, n, (int)item * 8);
        return refuse(what, why);
    }
    float *xyz = malloc(n ? n * 12 : 1);
    if (!xyz)
        return refuse(what, "out of memory");
    const unsigned char *p = data + prefix + hl;
    for (size_t i = 0; i < 3 * n; i++) {
        if (item == 4) {
            memcpy(&xyz[i], p + 4 * i, 4);
        } else {
            double d;
            memcpy(&d, p + 8 * i, 8);
            xyz[i] = (float)d;
        }
    }
    *out = (sdfq_points){xyz, n};
    return 0;
}

/* ---- CSV --------------------------------------------------------------------------------- */

/* Parse "x,y,z" (spaces allowed around each number) from [s, end): 0 or -1. */
static int parse_xyz(const char *s, const char *end, float xyz[3])
{
    for (int k = 0; k < 3; k++) {
        while (s < end && (*s == ' ' || *s == '\t'))
            s++;
        if (s == end || *s == ',' || isspace((unsigned char)*s))
            return -1;
        char *stop;
        errno = 0;
        double v = strtod(s, &stop);
        if (stop == s || stop > end || (errno == ERANGE && fabs(v) > 1))
            return -1;
        if (isfinite(v) && fabs(v) > FLT_MAX)
            return -1;
        xyz[k] = (float)v;
        s = stop;
        while (s < end && (*s == ' ' || *s == '\t'))
            s++;
        if (k < 2 && (s == end || *s++ != ','))
            return -1;
    }
    return s == end ? 0 : -1;
}

static int has_letter(const char *s, const char *end)
{
    for (; s < end; s++)
        if (isalpha((unsigned char)*s))
            return 1;
    return 0;
}

static int append(sdfq_points *p, size_t *cap, const float xyz[3])
{
    if (p->count == *cap) {
        size_t grown_cap = *cap ? 2 * *cap : 1024;
        float *grown = grown_cap > SIZE_MAX / 12 ? NULL : realloc(p->xyz, grown_cap * 12);
        if (!grown)
            return -1;
        p->xyz = grown;
        *cap = grown_cap;
    }
    memcpy(p->xyz + 3 * p->count++, xyz, 12);
    return 0;
}

int sdfq_parse_csv(const char *data, size_t size, const char *what, sdfq_points *out)
{
    sdfq_points p = {0};
    size_t cap = 0;
    long line = 0;
    int content = 0; /* lines with something on them so far */
    for (const char *s = data, *end = data + size; s < end;) {
        const char *eol = memchr(s, '\n', (size_t)(end - s));
        const char *stop = eol ? eol : end;
        line++;
        const char *e = stop;
        while (e > s && isspace((unsigned char)e[-1]))
            e--;
        const char *b = s;
        while (b < e && isspace((unsigned char)*b))
            b++;
        s = eol ? eol + 1 : end;
        if (b == e)
            continue;
        float xyz[3];
        int header = !content++ && has_letter(b, e);
        if (!header && parse_xyz(b, e, xyz)) {
            fprintf(stderr, "sdfq: %s line %ld: expected three numbers x,y,z, got '%.*s'\n", what,
                    line, (int)(e - b > 60 ? 60 : e - b), b);
            sdfq_points_free(&p);
            return SDFQ_INPUT;
        }
        if (!header && append(&p, &cap, xyz)) {
            sdfq_points_free(&p);
            return refuse(what, "out of memory");
        }
    }
    if (memchr(data, 0, size)) {
        sdfq_points_free(&p);
        return refuse(what, "not a CSV text file (it holds NUL bytes)");
    }
    *out = p;
    return 0;
}

/* ---- results ----------------------------------------------------------------------------- */

sdfq_out_format sdfq_out_format_of(const char *path)
{
    return ends_with(path, ".npy") ? SDFQ_OUT_NPY : SDFQ_OUT_CSV;
}

/* The npy header the server writes for the same answer (server/transport/body.c). */
static size_t npy_result_header(char *dst, size_t cap, int closest, unsigned words, size_t n)
{
    char dict[256];
    int len;
    if (closest)
        len = snprintf(dict, sizeof dict, "{'descr': [('distance', '<f4'), ('closest', '<f4', "
                       "(3,)), ('triangle', '<u4')], 'fortran_order': False, 'shape': (%zu,), }", n);
    else if (words == 1)
        len = snprintf(dict, sizeof dict, "{'descr': '<f4', 'fortran_order': False, 'shape': "
                       "(%zu,), }", n);
    else
        len = snprintf(dict, sizeof dict, "{'descr': '<f4', 'fortran_order': False, 'shape': "
                       "(%zu, %u), }", n, words);
    size_t total = (10 + (size_t)len + 1 + 63) / 64 * 64;
    if (total > cap)
        return 0;
    memcpy(dst, "\x93NUMPY\x01\x00", 8);
    dst[8] = (char)((total - 10) & 0xff);
    dst[9] = (char)((total - 10) >> 8);
    memcpy(dst + 10, dict, (size_t)len);
    memset(dst + 10 + len, ' ', total - 10 - (size_t)len - 1);
    dst[total - 1] = '\n';
    return total;
}

static int write_csv(FILE *f, const char *columns, unsigned words, const uint32_t *data,
                     size_t count)
{
    int closest = strstr(columns, "triangle") != NULL;
    fprintf(f, "%s\n", columns);
    for (size_t i = 0; i < count; i++) {
        for (unsigned w = 0; w < words; w++) {
            uint32_t word = data[i * words + w];
            float v;
            memcpy(&v, &word, 4);
            if (closest && w == 4)
                fprintf(f, ",%u", (unsigned)word);
            else
                fprintf(f, w ? ",%.9g" : "%.9g", (double)v);
        }
        fputc('\n', f);
    }
    return 0;
}

int sdfq_write_results(const char *path, sdfq_out_format format, const char *columns,
                       unsigned words, const uint32_t *data, size_t count)
{
    int to_stdout = !strcmp(path, "-");
    FILE *f = to_stdout ? stdout : fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "sdfq: cannot write %s: %s\n", path, strerror(errno));
        return SDFQ_OUTPUT;
    }
    if (format == SDFQ_OUT_NPY) {
        char header[256];
        size_t h = npy_result_header(header, sizeof header, strstr(columns, "triangle") != NULL,
                                     words, count);
        fwrite(header, 1, h, f);
        fwrite(data, 4 * words, count, f);
    } else {
        write_csv(f, columns, words, data, count);
    }
    int bad = ferror(f) | (to_stdout ? fflush(f) : fclose(f));
    if (bad) {
        fprintf(stderr, "sdfq: cannot write %s: %s\n", to_stdout ? "standard output" : path,
                strerror(errno));
        return SDFQ_OUTPUT;
    }
    return 0;
}
