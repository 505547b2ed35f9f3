/* load.c - sdf_mesh_load_file / _memory / sdf_mesh_create: choose a parser, run it into a
 * builder, and hand the triangle soup to sdf__mesh_build.
 *
 * Inputs are copied into a NUL-terminated buffer once so the text parsers can use strtod
 * safely; a file is read whole after its size is checked against max_file_bytes. */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/diag.h"
#include "mesh/mesh.h"
#include "mesh/parsers.h"

static int starts_with(const char *data, size_t size, const char *prefix)
{
    size_t n = strlen(prefix);
    return size >= n && !memcmp(data, prefix, n);
}

sdf_format sdf__sniff_format(const char *data, size_t size)
{
    if (starts_with(data, size, "ply\n") || starts_with(data, size, "ply\r\n"))
        return SDF_FORMAT_PLY;
    if (sdf__stl_is_binary(data, size))
        return SDF_FORMAT_STL;
    size_t i = 0;
    while (i < size && isspace((unsigned char)data[i]))
        i++;
    if (starts_with(data + i, size - i, "solid"))
        return SDF_FORMAT_STL;
    /* OFF: the keyword (maybe prefixed: COFF, NOFF, STOFF ...) is the first token */
    size_t j = i;
    while (j < size && isupper((unsigned char)data[j]))
        j++;
    if (j - i >= 3 && !memcmp(data + j - 3, "OFF", 3))
        return SDF_FORMAT_OFF;
    /* OBJ: look for a line starting with "v " or "f " in the first 64 KiB */
    for (size_t k = 0; k + 2 < size && k < 65536; k++) {
        if ((k == 0 || data[k - 1] == '\n') && (data[k] == 'v' || data[k] == 'f') &&
            (data[k + 1] == ' ' || data[k + 1] == '\t'))
            return SDF_FORMAT_OBJ;
    }
    return SDF_FORMAT_AUTO;
}

static sdf_format format_from_path(const char *path)
{
    const char *dot = strrchr(path, '.');
    sdf_format f;
    if (dot && !strchr(dot, '/') && sdf_format_from_name(dot + 1, &f) == 0)
        return f;
    return SDF_FORMAT_AUTO;
}

static const char *upper_name(sdf_format f)
{
    static const char *const names[] = {"mesh", "OBJ", "PLY", "STL", "OFF"};
    return names[f];
}

/* Parse `data` (NUL at data[size]) in `format` and build the mesh. */
static int load_buffer(const char *data, size_t size, sdf_format format,
                       const sdf_mesh_options *opts, sdf_mesh **out, sdf_diag *diag)
{
    if (format == SDF_FORMAT_AUTO)
        format = sdf__sniff_format(data, size);
    if (format == SDF_FORMAT_AUTO)
        return sdf__diag_set(diag, SDF_EFORMAT, 0, 0,
                             "cannot tell the mesh format from the content (OBJ, PLY, STL and "
                             "OFF are supported); name it explicitly");
    sdf__builder b;
    sdf__builder_init(&b, upper_name(format), opts ? opts->max_triangles : 0, diag);
    int (*parse[])(const char *, size_t, sdf__builder *) = {
        NULL, sdf__parse_obj, sdf__parse_ply, sdf__parse_stl, sdf__parse_off};
    int rc = parse[format](data, size, &b);
    if (rc) {
        sdf__builder_free(&b);
        return rc;
    }
    if (b.triangle_count == 0) {
        sdf__builder_free(&b);
        return sdf__diag_set(diag, SDF_EEMPTY, 0, -1, "%s: the file holds no triangles",
                             upper_name(format));
    }
    rc = sdf__mesh_build(b.positions, b.vertex_count, b.triangles, b.triangle_count, format, out,
                         diag);
    if (!rc) {
        (*out)->report.warnings = b.warnings;
        memcpy((*out)->report.warning, b.warning, sizeof b.warning);
    }
    return rc;
}

int sdf_mesh_load_memory(const void *data, size_t size, const sdf_mesh_options *opts,
                         sdf_mesh **out, sdf_diag *diag)
{
    sdf__diag_clear(diag);
    if (!out || (!data && size))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "invalid argument");
    *out = NULL;
    char *copy = malloc(size + 1);
    if (!copy)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "out of memory for a %zu-byte copy", size);
    if (size)
        memcpy(copy, data, size);
    copy[size] = '\0';
    int rc = load_buffer(copy, size, opts ? opts->format : SDF_FORMAT_AUTO, opts, out, diag);
    free(copy);
    return rc;
}

static int read_file(const char *path, size_t max_bytes, char **data, size_t *size,
                     sdf_diag *diag)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return sdf__diag_set(diag, SDF_EIO, 0, -1, "%s: %s", path, strerror(errno));
    long long len = -1;
    if (fseek(f, 0, SEEK_END) == 0)
        len = ftell(f);
    if (len < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        return sdf__diag_set(diag, SDF_EIO, 0, -1, "%s: not a regular, seekable file", path);
    }
    if ((unsigned long long)len > max_bytes) {
        fclose(f);
        return sdf__diag_set(diag, SDF_ELIMIT, 0, -1, "%s: %lld bytes is over the %zu-byte limit",
                             path, len, max_bytes);
    }
    char *buf = malloc((size_t)len + 1);
    if (!buf) {
        fclose(f);
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "%s: out of memory", path);
    }
    size_t got = fread(buf, 1, (size_t)len, f);
    fclose(f);
    if (got != (size_t)len) {
        free(buf);
        return sdf__diag_set(diag, SDF_EIO, 0, -1, "%s: short read", path);
    }
    buf[len] = '\0';
    *data = buf;
    *size = (size_t)len;
    return 0;
}

int sdf_mesh_load_file(const char *path, const sdf_mesh_options *opts, sdf_mesh **out,
                       sdf_diag *diag)
{
    sdf__diag_clear(diag);
    if (!out || !path)
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "invalid argument");
    *out = NULL;
    size_t max_bytes = opts && opts->max_file_bytes ? opts->max_file_bytes
                                                    : SDF_DEFAULT_MAX_FILE_BYTES;
    char *data = NULL;
    size_t size = 0;
    int rc = read_file(path, max_bytes, &data, &size, diag);
    if (rc)
        return rc;
    sdf_format format = opts ? opts->format : SDF_FORMAT_AUTO;
    if (format == SDF_FORMAT_AUTO)
        format = format_from_path(path);
    rc = load_buffer(data, size, format, opts, out, diag);
    free(data);
    return rc;
}

int sdf_mesh_create(const float *vertices, size_t vertex_count, const uint32_t *triangles,
                    size_t triangle_count, const sdf_mesh_options *opts, sdf_mesh **out,
                    sdf_diag *diag)
{
    sdf__diag_clear(diag);
    if (!out || (!vertices && vertex_count) || (!triangles && triangle_count))
        return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "invalid argument");
    *out = NULL;
    sdf__builder b;
    sdf__builder_init(&b, "mesh", opts ? opts->max_triangles : 0, diag);
    int rc = sdf__builder_reserve(&b, vertex_count, triangle_count);
    for (size_t v = 0; !rc && v < vertex_count; v++)
        rc = sdf__builder_add_vertex(&b, vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]);
    for (size_t t = 0; !rc && t < triangle_count; t++)
        rc = sdf__builder_add_polygon(&b, triangles + 3 * t, 3, t);
    if (!rc && triangle_count == 0)
        rc = sdf__diag_set(diag, SDF_EEMPTY, 0, -1, "mesh: no triangles");
    if (rc) {
        sdf__builder_free(&b);
        return rc;
    }
    return sdf__mesh_build(b.positions, b.vertex_count, b.triangles, b.triangle_count,
                           SDF_FORMAT_AUTO, out, diag);
}
