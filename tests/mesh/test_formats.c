/* test_formats.c - the parsers: every shared file; one model in every format and variant
 * giving bit-identical distances; every truncated prefix of binary STL and PLY files
 * rejected cleanly; malformed headers, absurd counts, bad indices and bad numbers rejected
 * with the right code and location; limits enforced. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/files.h"
#include "../common/workload.h"
#include "writers.h"

static sdf_mesh *load(const char *file, sdf_mesh_report *r)
{
    sdf_mesh *m = load_data_mesh(file);
    if (m && r)
        sdf_mesh_get_report(m, r);
    return m;
}

/* ---- the shared files ------------------------------------------------------------------- */

static void test_shared_files(void)
{
    static const struct { const char *file; size_t vertices, triangles; int closed; } files[] = {
        {"fandisk.off", 6475, 12946, 1},
        {"knot1.off", 3200, 6400, 1},
        {"cow.off", 2903, 5804, 1},
        {"elephant-with-holes.off", 2733, 4463, 0},
        {"mech-holes-shark.off", 5246, 10192, 0},
        {"spider.obj", 722, 1368, 0},
        {"Spider_ascii.stl", 722, 1368, 0},
        {"Spider_binary.stl", 722, 1368, 0},
        {"box_without_lineending.obj", 8, 12, 1},
        {"triangle_with_two_solids.stl", 6, 2, 0},
        {"cube.ply", 8, 12, 1},
        {"cube_binary.ply", 8, 12, 1},
    };
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        sdf_mesh_report r;
        sdf_mesh *m = load(files[i].file, &r);
        if (!m)
            continue;
        CHECK(r.vertices == files[i].vertices && r.triangles == files[i].triangles &&
                  r.closed == files[i].closed,
              "%s: %zu vertices, %zu triangles, closed %d", files[i].file, r.vertices, r.triangles,
              r.closed);
        /* The packet issue's memory target: BVHs + sign data <= 150 bytes per triangle
         * (small meshes pay Embree's fixed overhead, so only the larger ones are held to it). */
        if (r.triangles >= 5000)
            CHECK((double)r.index_bytes / (double)r.triangles <= 150, "%s: index %.1f B/triangle",
                  files[i].file, (double)r.index_bytes / (double)r.triangles);
        sdf_mesh_release(m);
    }
    /* Welding: STL stores 3 corners per triangle; OBJ/STL of the spider weld alike. */
    sdf_mesh_report r;
    sdf_mesh *m = load("Spider_binary.stl", &r);
    CHECK(r.input_vertices == 3 * 1368 && r.vertices == 722, "STL weld: %zu -> %zu",
          r.input_vertices, r.vertices);
    sdf_mesh_release(m);
}

static void expect_reject(const char *what, const char *data, size_t size, sdf_format format,
                          int code, long line, long long offset, const char *needle)
{
    sdf_mesh_options o = {.format = format};
    sdf_mesh *m = (sdf_mesh *)1;
    sdf_diag diag;
    int rc = sdf_mesh_load_memory(data, size, &o, &m, &diag);
    CHECK(rc == code && m == NULL, "%s: got %s (%s), expected %s", what, sdf_errname(rc),
          diag.message, sdf_errname(code));
    CHECK(diag.code == rc, "%s: diag.code %d != %d", what, diag.code, rc);
    if (line >= 0)
        CHECK(diag.line == line, "%s: line %ld, expected %ld (%s)", what, diag.line, line,
              diag.message);
    if (offset >= 0)
        CHECK(diag.offset == offset, "%s: offset %lld, expected %lld (%s)", what, diag.offset,
              offset, diag.message);
    if (needle)
        CHECK(strstr(diag.message, needle) != NULL, "%s: message '%s' lacks '%s'", what,
              diag.message, needle);
    if (rc == 0)
        sdf_mesh_release(m);
}

static void test_odd_shared_files(void)
{
    size_t size;
    char *data = read_whole_file(data_path("number_formats.obj"), &size);
    /* "v 1e+2 2.e+1 3.1+e2": 3.1+e2 is not a number; strtod would silently read 3.1. */
    expect_reject("number_formats.obj", data, size, SDF_FORMAT_OBJ, SDF_EPARSE, 11, -1,
                  "malformed number");
    free(data);
    data = read_whole_file(data_path("issue623.ply"), &size);
    /* A list property inside the vertex element, no face element: not a mesh. */
    expect_reject("issue623.ply", data, size, SDF_FORMAT_PLY, SDF_EEMPTY, 0, -1, "no face element");
    free(data);
}

/* Blender 2.4x writes a header line without the `comment` keyword: before the first element
 * it is taken as a comment with a warning in the report; among the elements it is refused. */
static void test_ply_free_text_header(void)
{
    static const char blender[] = "ply\nformat ascii 1.0\nCreated by Blender3D 247 - "
                                  "www.blender.org, source file: ''\nelement vertex 3\n"
                                  "property float x\nproperty float y\nproperty float z\n"
                                  "element face 1\nproperty list uchar uint vertex_indices\n"
                                  "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    sdf_mesh_options o = {.format = SDF_FORMAT_PLY};
    sdf_mesh *m = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_load_memory(blender, sizeof blender - 1, &o, &m, &diag);
    CHECK(rc == 0, "Blender PLY refused: %s", diag.message);
    if (rc == 0) {
        sdf_mesh_report r;
        sdf_mesh_get_report(m, &r);
        CHECK(r.triangles == 1 && r.warnings == 1 &&
                  !strcmp(r.warning, "PLY line 3: unknown header keyword 'Created': the line is "
                                     "taken as a comment"),
              "Blender PLY report: %zu triangles, %zu warnings '%s'", r.triangles, r.warnings,
              r.warning);
        sdf_mesh_release(m);
    }
    static const char among[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                "property float y\nproperty float z\nMade by hand\n"
                                "element face 1\nproperty list uchar uint vertex_indices\n"
                                "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    expect_reject("free text among elements", among, sizeof among - 1, SDF_FORMAT_PLY, SDF_EPARSE,
                  7, -1, "unknown header keyword 'Made'");
    /* the reports of files with nothing doubtful say so */
    sdf_mesh_report r;
    sdf_mesh *cube = load("cube.ply", &r);
    CHECK(r.warnings == 0 && r.warning[0] == '\0', "cube.ply has a warning: %s", r.warning);
    sdf_mesh_release(cube);
}

/* ---- one model, every encoding ---------------------------------------------------------- */

static void same_distances(const char *what, const sdf_mesh *ref, const char *data, size_t size,
                           sdf_format format, const float *points, size_t n, const float *expect)
{
    sdf_mesh_options o = {.format = format};
    sdf_mesh *m = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_load_memory(data, size, &o, &m, &diag);
    CHECK(rc == 0, "%s: %s", what, diag.message);
    if (rc)
        return;
    sdf_mesh_report a, b;
    sdf_mesh_get_report(ref, &a);
    sdf_mesh_get_report(m, &b);
    CHECK(a.vertices == b.vertices && a.triangles == b.triangles && a.closed == b.closed,
          "%s: %zu/%zu vertices, %zu/%zu triangles", what, b.vertices, a.vertices, b.triangles,
          a.triangles);
    float *d = malloc(n * sizeof *d);
    sdf_query_result res = {.distance = d};
    CHECK(sdf_query(m, points, n, NULL, &res) == 0, "%s: query", what);
    CHECK(!memcmp(d, expect, n * sizeof *d), "%s: distances differ from the OFF original", what);
    free(d);
    sdf_mesh_release(m);
}

static void test_round_trips(void)
{
    sdf_mesh *ref = load("fandisk.off", NULL);
    size_t n = 2000;
    float *p = malloc(3 * n * sizeof *p), *d = malloc(n * sizeof *d);
    sdf_workload(ref, "band", &n, 3, p);
    sdf_query_result res = {.distance = d};
    CHECK(sdf_query(ref, p, n, NULL, &res) == 0, "query");
    size_t size;
    char *data;
    for (int variant = 0; variant < 3; variant++) {
        char what[32];
        snprintf(what, sizeof what, "OBJ variant %d", variant);
        data = write_obj(ref, variant, &size);
        same_distances(what, ref, data, size, SDF_FORMAT_AUTO, p, n, d);
        free(data);
    }
    data = write_off(ref, &size);
    same_distances("OFF", ref, data, size, SDF_FORMAT_AUTO, p, n, d);
    free(data);
    data = write_stl_ascii(ref, &size);
    same_distances("ASCII STL, two solids", ref, data, size, SDF_FORMAT_AUTO, p, n, d);
    free(data);
    data = write_stl_binary(ref, "binary", &size);
    same_distances("binary STL", ref, data, size, SDF_FORMAT_AUTO, p, n, d);
    free(data);
    data = write_stl_binary(ref, "solid but binary", &size);
    same_distances("binary STL with a 'solid' header", ref, data, size, SDF_FORMAT_AUTO, p, n, d);
    free(data);
    const char *enc[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    for (int i = 0; i < 3; i++) {
        data = write_ply(ref, enc[i], &size);
        same_distances(enc[i], ref, data, size, SDF_FORMAT_AUTO, p, n, d);
        free(data);
    }
    free(p), free(d);
    sdf_mesh_release(ref);

    /* Real files from another exporter: the spider in both STL encodings (its OBJ is a
     * different export, scaled and rotated, so only its counts are compared above). */
    sdf_mesh *stl = load("Spider_ascii.stl", NULL), *bin = load("Spider_binary.stl", NULL);
    n = 1000;
    float *q = malloc(3 * n * sizeof *q), *d2 = malloc(n * 4), *d3 = malloc(n * 4);
    sdf_workload(bin, "band", &n, 4, q);
    sdf_query_options o = {.sign = SDF_SIGN_NONE};
    sdf_query_result r2 = {.distance = d2}, r3 = {.distance = d3};
    sdf_query(stl, q, n, &o, &r2);
    sdf_query(bin, q, n, &o, &r3);
    sdf_mesh_report r;
    sdf_mesh_get_report(bin, &r);
    double worst = 0;
    for (size_t i = 0; i < n; i++)
        worst = fmax(worst, fabs(d2[i] - d3[i]));
    /* The ASCII file holds 6 significant digits, the binary floats: equal to 1e-5 diagonal. */
    CHECK(worst <= 1e-5 * r.diagonal, "spider: ASCII and binary STL distances differ by %g", worst);
    printf("spider: ASCII vs binary STL distances differ by at most %.2e (diagonal %.3g)\n", worst,
           r.diagonal);
    free(q), free(d2), free(d3);
    sdf_mesh_release(stl), sdf_mesh_release(bin);
}

/* ---- truncation ------------------------------------------------------------------------- */

static void every_prefix_fails(const char *what, const char *data, size_t size, sdf_format format)
{
    sdf_mesh_options o = {.format = format};
    size_t accepted = 0, unexplained = 0;
    for (size_t len = 0; len < size; len++) {
        sdf_mesh *m = NULL;
        sdf_diag diag;
        int rc = sdf_mesh_load_memory(data, len, &o, &m, &diag);
        if (rc == 0) {
            accepted++;
            sdf_mesh_release(m);
        } else if (diag.code != rc || !diag.message[0]) {
            unexplained++;
        }
    }
    CHECK(accepted == 0, "%s: %zu truncated prefixes were accepted", what, accepted);
    CHECK(unexplained == 0, "%s: %zu rejections without a message", what, unexplained);
    sdf_mesh *m = NULL;
    CHECK(sdf_mesh_load_memory(data, size, &o, &m, NULL) == 0, "%s: the whole file fails", what);
    sdf_mesh_release(m);
}

static void test_truncation(void)
{
    size_t size;
    char *data = read_whole_file(data_path("Spider_binary.stl"), &size);
    every_prefix_fails("Spider_binary.stl", data, size, SDF_FORMAT_STL);
    every_prefix_fails("Spider_binary.stl (sniffed)", data, size, SDF_FORMAT_AUTO);
    free(data);
    data = read_whole_file(data_path("cube_binary.ply"), &size);
    every_prefix_fails("cube_binary.ply", data, size, SDF_FORMAT_PLY);
    free(data);
    /* A binary PLY with lists and extra elements, both byte orders. */
    sdf_mesh *knot = load("knot1.off", NULL);
    const float *v = sdf_mesh_vertices(knot);
    const uint32_t *t = sdf_mesh_triangles(knot);
    sdf_mesh *small;
    CHECK(sdf_mesh_create(v, 3200, t, 60, NULL, &small, NULL) == 0, "small mesh");
    const char *enc[] = {"binary_little_endian", "binary_big_endian"};
    for (int i = 0; i < 2; i++) {
        data = write_ply(small, enc[i], &size);
        every_prefix_fails(enc[i], data, size, SDF_FORMAT_PLY);
        free(data);
    }
    sdf_mesh_release(small);
    sdf_mesh_release(knot);
}

/* ---- malformed input -------------------------------------------------------------------- */

#define REJECT(what, text, fmt, code, line, offset, needle) \
    expect_reject(what, text, sizeof(text) - 1, fmt, code, line, offset, needle)

static const char tri_off[] = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";

static void test_malformed(void)
{
    /* OBJ */
    REJECT("OBJ index past the end", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", SDF_FORMAT_OBJ,
           SDF_EINDEX, 4, -1, "index 4");
    REJECT("OBJ index 0", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", SDF_FORMAT_OBJ, SDF_EINDEX, 4,
           -1, NULL);
    REJECT("OBJ negative index too far back", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n",
           SDF_FORMAT_OBJ, SDF_EINDEX, 4, -1, NULL);
    REJECT("OBJ NaN", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", SDF_FORMAT_OBJ, SDF_ENONFINITE, 2,
           -1, "finite");
    REJECT("OBJ beyond float", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", SDF_FORMAT_OBJ,
           SDF_ENONFINITE, 2, -1, NULL);
    /* Within float, but past SDF_MAX_COORDINATE, where Embree's builder fails its asserts. */
    REJECT("OBJ beyond 1e18", "v 0 0 0\nv 0 -2e18 0\nv 0 1 0\nf 1 2 3\n", SDF_FORMAT_OBJ,
           SDF_ENONFINITE, 2, -1, "beyond +-1e18 (-2e+18)");
    REJECT("OBJ two-corner face", "v 0 0 0\nv 1 0 0\nf 1 2\n", SDF_FORMAT_OBJ, SDF_EPARSE, 3, -1,
           "at least 3");
    REJECT("OBJ short vertex", "v 0 0\n", SDF_FORMAT_OBJ, SDF_EPARSE, 1, -1, "3 coordinates");
    REJECT("OBJ garbage corner", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", SDF_FORMAT_OBJ,
           SDF_EPARSE, 4, -1, NULL);
    REJECT("OBJ without faces", "v 0 0 0\n", SDF_FORMAT_OBJ, SDF_EEMPTY, -1, -1, NULL);
    REJECT("empty input", "", SDF_FORMAT_AUTO, SDF_EFORMAT, -1, -1, NULL);
    REJECT("unknown format", "hello world\n", SDF_FORMAT_AUTO, SDF_EFORMAT, -1, -1, NULL);
    /* OFF */
    REJECT("OFF bad index", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n", SDF_FORMAT_OFF,
           SDF_EINDEX, 6, -1, "index 5");
    REJECT("OFF absurd counts", "OFF\n1000000000 1 0\n0 0 0\n", SDF_FORMAT_OFF, SDF_ETRUNC, 2, -1,
           "more than");
    REJECT("OFF negative count", "OFF\n-3 1 0\n", SDF_FORMAT_OFF, SDF_EPARSE, 2, -1, NULL);
    REJECT("OFF missing faces", tri_off, SDF_FORMAT_OFF, SDF_ETRUNC, -1, -1, NULL);
    REJECT("OFF huge polygon", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2000000000 0 1 2\n",
           SDF_FORMAT_OFF, SDF_ETRUNC, 6, -1, "more than the file");
    REJECT("OFF inf", "OFF\n3 1 0\n0 0 0\ninf 0 0\n0 1 0\n3 0 1 2\n", SDF_FORMAT_OFF,
           SDF_ENONFINITE, 4, -1, NULL);
    REJECT("OFF nD", "4OFF\n", SDF_FORMAT_OFF, SDF_EFORMAT, 1, -1, "variant");
    REJECT("OFF binary", "OFF BINARY\n", SDF_FORMAT_OFF, SDF_EFORMAT, 1, -1, "binary");
    /* PLY */
    REJECT("PLY absurd vertex count",
           "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
           "property float y\nproperty float z\nelement face 1\n"
           "property list uchar int vertex_indices\nend_header\n",
           SDF_FORMAT_PLY, SDF_ETRUNC, 3, -1, "4000000000");
    REJECT("PLY unknown encoding", "ply\nformat binary_middle_endian 1.0\nend_header\n",
           SDF_FORMAT_PLY, SDF_EFORMAT, 2, -1, "encoding");
    REJECT("PLY unknown type",
           "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
           SDF_FORMAT_PLY, SDF_EPARSE, 4, -1, "float128");
    REJECT("PLY no end_header", "ply\nformat ascii 1.0\nelement vertex 1\n", SDF_FORMAT_PLY,
           SDF_ETRUNC, -1, -1, "end_header");
    REJECT("PLY bad ascii index",
           "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
           "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
           SDF_FORMAT_PLY, SDF_EINDEX, 13, -1, "index 3");
    static const char bin_ply_head[] =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n";
    char bin_ply[sizeof bin_ply_head - 1 + 36 + 13];
    size_t h = sizeof bin_ply_head - 1;
    memcpy(bin_ply, bin_ply_head, h);
    float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    memcpy(bin_ply + h, xyz, 36);
    int32_t idx[3] = {0, 1, 7};
    bin_ply[h + 36] = 3;
    memcpy(bin_ply + h + 37, idx, 12);
    expect_reject("PLY binary bad index", bin_ply, sizeof bin_ply, SDF_FORMAT_PLY, SDF_EINDEX, 0,
                  (long long)(h + 37 + 8), "index 7");
    bin_ply[h + 36] = (char)200; /* a list count past the end */
    expect_reject("PLY binary list count", bin_ply, sizeof bin_ply, SDF_FORMAT_PLY, SDF_ETRUNC, 0,
                  (long long)h + 36, "list count");
    /* STL */
    char stl[84 + 50] = "binary";
    uint32_t one = 2; /* declares 2 facets, holds 1 */
    memcpy(stl + 80, &one, 4);
    expect_reject("STL count/size mismatch", stl, sizeof stl, SDF_FORMAT_STL, SDF_ETRUNC, 0, 80,
                  "declares 2");
    one = 1;
    memcpy(stl + 80, &one, 4);
    float bad[12] = {0, 0, 0, 0, 0, 0, 1, INFINITY, 0, 0, 1, 0};
    memcpy(stl + 84, bad, 48);
    expect_reject("STL binary Inf", stl, sizeof stl, SDF_FORMAT_STL, SDF_ENONFINITE, 0, 84, NULL);
    REJECT("STL ascii unexpected token", "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vortex 1 0 0\n",
           SDF_FORMAT_STL, SDF_EPARSE, 5, -1, "vortex");
    REJECT("STL ascii truncated", "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n",
           SDF_FORMAT_STL, SDF_ETRUNC, -1, -1, "ends inside");
    REJECT("STL too short", "abc", SDF_FORMAT_STL, SDF_ETRUNC, -1, -1, "too short");
}

/* ---- limits ----------------------------------------------------------------------------- */

static void test_limits(void)
{
    sdf_mesh_options o = {.max_triangles = 1000};
    sdf_mesh *m = NULL;
    sdf_diag diag;
    CHECK(sdf_mesh_load_file(data_path("fandisk.off"), &o, &m, &diag) == SDF_ELIMIT && !m,
          "triangle limit not enforced: %s", diag.message);
    CHECK(strstr(diag.message, "limit") != NULL, "limit message: %s", diag.message);
    o = (sdf_mesh_options){.max_file_bytes = 1000};
    CHECK(sdf_mesh_load_file(data_path("fandisk.off"), &o, &m, &diag) == SDF_ELIMIT,
          "file size limit not enforced");
    CHECK(sdf_mesh_load_file(data_path("no-such-file.off"), NULL, &m, &diag) == SDF_EIO &&
              strstr(diag.message, "no-such-file"),
          "missing file: %s", diag.message);
    o = (sdf_mesh_options){.format = SDF_FORMAT_STL};
    size_t size;
    char *data = read_whole_file(data_path("fandisk.off"), &size);
    CHECK(sdf_mesh_load_memory(data, size, &o, &m, &diag) != 0,
          "an OFF file parsed as STL was accepted");
    free(data);
    sdf_format f;
    CHECK(sdf_format_from_name("PLY", &f) == 0 && f == SDF_FORMAT_PLY, "format names");
    CHECK(sdf_format_from_name("3ds", &f) == SDF_EINVAL, "unknown format name accepted");
}

static const check_case cases[] = {
    {"shared_files", test_shared_files},
    {"odd_shared_files", test_odd_shared_files},
    {"ply_free_text_header", test_ply_free_text_header},
    {"round_trips", test_round_trips},
    {"truncation", test_truncation},
    {"malformed", test_malformed},
    {"limits", test_limits},
};

int main(int argc, char **argv)
{
    return check_main("formats", cases, CHECK_COUNT_OF(cases), argc, argv);
}
