/* test_mutations.c - every reader of untrusted bytes, fed thousands of damaged copies of
 * valid inputs: mesh files of each format (which then build an index), .npy arrays, EXR
 * volumes, binary protocol payloads and HTTP query bodies.
 *
 * A reader may accept a damaged input (a flipped digit is still a number) or refuse it with
 * an error code; it must do nothing else: no crash, no read or write out of bounds, no leak
 * (the sanitizer build runs this too, which is where those show), no code outside the
 * documented ones, and no diag without a message. The damage is deterministic (a fixed
 * seed for each input), so a failure reproduces, in the whole run or its case alone;
 * MUTATIONS_ROUNDS=N in the environment runs N rounds per seed input instead of the
 * default, for longer hunts, and MUTATIONS_DUMP=FILE writes each damaged input there before
 * it is read (after a crash, FILE holds the culprit). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/files.h"
#include "../common/workload.h"
#include "transport/body.h"
#include "proto.h"

#define DEFAULT_ROUNDS 300

/* ---- damage ------------------------------------------------------------------------------ */

static sdf_rng rng = {0x5eed5eedu};

static uint64_t next_random(void) { return sdf_rng_next(&rng); }

static size_t below(size_t n) { return n ? (size_t)(next_random() % n) : 0; }

/* Byte strings that break readers: limits, signs, exponents, separators. */
static const char *const tokens[] = {
    "0", "-1", "1e39", "-1e39", "1e-46", "nan", "inf", "-0", "4294967295", "4294967296",
    "18446744073709551616", "99999999999999999999999", "0x10", "1.", ".", "-", "e5", "\n",
    " ", "\t", "\r\n", "#", "/", "//", "[", "]", "{", "}", ",", ":", "\"", "\\", "'", "f",
    "vertex", "face", "end_header", "facet normal", "endloop", "format binary_little_endian",
    "element vertex 4294967295", "property list uchar int", "v 1 2 3", "f 1 2 -9", "OFF",
    "points", "\"points\"", "\x80", "\xff\xfe", "\0"};

/* Little-endian words that break length fields. */
static const uint32_t words[] = {0, 1, 2, 3, 0x7f, 0x80, 0xff, 0x100, 0xffff, 0x10000,
                                 0x7fffffff, 0x80000000, 0xfffffff0, 0xffffffff, 12, 255};

/* A damaged copy of in[0..n) in out (room for cap bytes); returns its length. One to four
 * of: bit flips, byte overwrites, words written over length-looking fields, tokens spliced
 * in, truncation, a chunk deleted or repeated. */
static size_t damage(const unsigned char *in, size_t n, unsigned char *out, size_t cap)
{
    size_t len = n < cap ? n : cap;
    memcpy(out, in, len);
    int edits = 1 + (int)below(4);
    for (int e = 0; e < edits && len > 0; e++) {
        size_t at = below(len);
        switch (below(7)) {
        case 0:
            out[at] ^= (unsigned char)(1u << below(8));
            break;
        case 1:
            out[at] = (unsigned char)next_random();
            break;
        case 2: { /* a word, often at an aligned offset (headers are) */
            uint32_t w = words[below(sizeof words / sizeof *words)];
            size_t p = below(2) ? at & ~(size_t)3 : at;
            for (int b = 0; b < 4 && p + (size_t)b < len; b++)
                out[p + (size_t)b] = (unsigned char)(w >> (8 * b));
            break;
        }
        case 3: { /* a token in place of the bytes there, the rest moved along */
            const char *t = tokens[below(sizeof tokens / sizeof *tokens)];
            size_t tl = strlen(t) ? strlen(t) : 1, cut = below(8);
            cut = at + cut > len ? len - at : cut;
            if (len - cut + tl > cap)
                break;
            memmove(out + at + tl, out + at + cut, len - at - cut);
            memcpy(out + at, t, tl);
            len = len - cut + tl;
            break;
        }
        case 4:
            len = at;
            break;
        case 5: { /* delete a chunk */
            size_t cut = 1 + below(64);
            cut = at + cut > len ? len - at : cut;
            memmove(out + at, out + at + cut, len - at - cut);
            len -= cut;
            break;
        }
        default: { /* repeat a chunk */
            size_t chunk = 1 + below(64);
            chunk = at + chunk > len ? len - at : chunk;
            if (len + chunk > cap)
                break;
            memmove(out + at + chunk, out + at, len - at);
            len += chunk;
            break;
        }
        }
    }
    return len;
}

static int rounds(void)
{
    const char *env = getenv("MUTATIONS_ROUNDS");
    return env && atoi(env) > 0 ? atoi(env) : DEFAULT_ROUNDS;
}

static int documented(int rc) { return rc <= 0 && rc >= SDF_ECANCELED; }

/* ---- readers ----------------------------------------------------------------------------- */

typedef void (*reader_fn)(const unsigned char *data, size_t len, void *ctx);

static void read_mesh(const unsigned char *data, size_t len, void *ctx)
{
    sdf_mesh_options o = {.format = *(const sdf_format *)ctx, .max_triangles = 1 << 16};
    sdf_mesh *mesh = NULL;
    sdf_diag diag = {0};
    int rc = sdf_mesh_load_memory(data, len, &o, &mesh, &diag);
    CHECK(documented(rc), "mesh: code %d", rc);
    if (rc) {
        CHECK(!mesh && diag.message[0], "mesh: a refusal without a message (%d)", rc);
        return;
    }
    /* Whatever was accepted must also answer queries: finite points, finite answers. */
    sdf_mesh_report rep;
    sdf_mesh_get_report(mesh, &rep);
    float p[6] = {rep.bbox_min[0], rep.bbox_min[1], rep.bbox_min[2], 0.5f, -0.25f, 2.0f};
    float d[2] = {NAN, NAN};
    sdf_query_result res = {.distance = d};
    sdf_query_options qo = {.threads = 1};
    rc = sdf_query(mesh, p, 2, &qo, &res);
    CHECK(rc == 0 && isfinite(d[0]) && isfinite(d[1]), "mesh: query %d on an accepted mesh", rc);
    sdf_mesh_release(mesh);
}

static void read_npy(const unsigned char *data, size_t len, void *ctx)
{
    (void)ctx;
    sdf_npy_info info;
    sdf_diag diag = {0};
    int rc = sdf_npy_parse(data, len, &info, &diag);
    CHECK(documented(rc) && (rc == 0 || diag.message[0]), "npy: code %d", rc);
}

static void read_exr(const unsigned char *data, size_t len, void *ctx)
{
    (void)ctx;
    sdf_volume *v = NULL;
    sdf_diag diag = {0};
    int rc = sdf_volume_load_exr_memory(data, len, &v, &diag);
    CHECK(documented(rc) && (rc == 0 || (diag.message[0] && !v)), "exr: code %d", rc);
    sdf_volume_destroy(v);
}

static void read_frame(const unsigned char *data, size_t len, void *ctx)
{
    (void)ctx;
    sdf_proto_header h;
    const char *why = NULL;
    int rc = sdf_proto_decode_header(data, len, 1u << 20, &h, &why);
    CHECK(documented(rc) && (rc == 0 || why), "header: code %d", rc);
    const unsigned char *payload = data + SDF_PROTO_HEADER_SIZE;
    size_t size = len > SDF_PROTO_HEADER_SIZE ? len - SDF_PROTO_HEADER_SIZE : 0;
    if (rc == 0 && h.length < size)
        size = h.length;
    /* Every decoder on the payload, whatever the type says: each checks its own lengths. */
    sdf_proto_query q;
    sdf_proto_volume_query vq;
    sdf_proto_result r;
    sdf_proto_error e;
    sdf_proto_hello hello;
    int codes[5] = {sdf_proto_decode_query(payload, size, 1000, &q, &why),
                    sdf_proto_decode_volume_query(payload, size, 1000, &vq, &why),
                    sdf_proto_decode_result(payload, size, &r, &why),
                    sdf_proto_decode_error(payload, size, &e, &why),
                    sdf_proto_decode_hello_ok(payload, size, &hello, &why)};
    for (int i = 0; i < 5; i++)
        CHECK(documented(codes[i]), "decoder %d: code %d", i, codes[i]);
    if (codes[0] == 0) { /* what a decoded query points at lies inside the payload */
        const unsigned char *pts = q.points;
        CHECK(q.count <= 1000 && pts >= payload && pts + 12 * (size_t)q.count <= payload + size,
              "query points outside the payload");
        CHECK((const unsigned char *)q.name >= payload &&
                  (const unsigned char *)q.name + q.name_len <= payload + size,
              "query name outside the payload");
    }
}

static void read_body(const unsigned char *data, size_t len, void *ctx)
{
    sdfd_form form = *(const sdfd_form *)ctx;
    /* As the server holds a body: its own buffer, NUL after it, float-aligned. */
    char *body = malloc(len + 1);
    CHECK(body != NULL, "out of memory");
    memcpy(body, data, len);
    body[len] = 0;
    sdfd_query_params params = {0};
    float *points = NULL;
    size_t count = 0;
    int owned = 0;
    char err[256] = "";
    int rc = sdfd_parse_points(form, body, len, 1000, &params, &points, &count, &owned, err,
                               sizeof err);
    CHECK(documented(rc) && (rc == 0 || err[0]), "body form %d: code %d", (int)form, rc);
    if (rc == 0) {
        CHECK(count <= 1000, "body: %zu points over the cap", count);
        for (size_t i = 0; i < 3 * count; i++)
            CHECK(isfinite(points[i]) || form != SDFD_FORM_JSON,
                  "body: JSON gave a non-finite coordinate (%s)", body);
    }
    if (rc == 0 && owned)
        free(points);
    free(body);
}

/* Damaged copies of `seed`, each handed to `read`. The damage starts from a state of its
 * own, made from `what`, so a case run alone damages its inputs as the whole run does. */
static void hammer(const char *what, const void *seed, size_t n, reader_fn read, void *ctx)
{
    rng.state = 0x5eed5eedu;
    for (const char *c = what; *c; c++)
        rng.state = (rng.state ^ (unsigned char)*c) * 0x100000001b3u; /* FNV-1a */
    size_t cap = 2 * n + 256;
    unsigned char *buf = malloc(cap);
    CHECK(buf != NULL, "out of memory");
    read(seed, n, ctx); /* the seed itself first */
    int r = rounds();
    const char *dump = getenv("MUTATIONS_DUMP");
    for (int i = 0; i < r; i++) {
        size_t len = damage(seed, n, buf, cap);
        /* Most readers get exact-size buffers from the server: so do they here, so that the
         * sanitizer sees a read one past the end. */
        unsigned char *exact = malloc(len ? len : 1);
        CHECK(exact != NULL, "out of memory");
        memcpy(exact, buf, len);
        FILE *f = dump ? fopen(dump, "wb") : NULL;
        if (f) {
            fwrite(exact, 1, len, f);
            fclose(f);
        }
        read(exact, len, ctx);
        free(exact);
    }
    free(buf);
    printf("%s: %d damaged copies\n", what, r);
}

/* ---- seeds ------------------------------------------------------------------------------- */

static void mesh_file(const char *name, sdf_format format)
{
    size_t n;
    char *data = read_whole_file(data_path(name), &n);
    CHECK(data != NULL, "cannot read %s", name);
    if (!data)
        return;
    hammer(name, data, n, read_mesh, &format);
    if (format != SDF_FORMAT_AUTO) { /* and sniffed */
        sdf_format any = SDF_FORMAT_AUTO;
        hammer(name, data, n, read_mesh, &any);
    }
    free(data);
}

static const char small_off[] = "OFF\n# a tetrahedron\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                                "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

static void test_meshes(void)
{
    mesh_file("cube.ply", SDF_FORMAT_PLY);
    mesh_file("cube_binary.ply", SDF_FORMAT_PLY);
    mesh_file("issue623.ply", SDF_FORMAT_PLY);
    mesh_file("box_without_lineending.obj", SDF_FORMAT_OBJ);
    mesh_file("number_formats.obj", SDF_FORMAT_OBJ);
    mesh_file("triangle_with_two_solids.stl", SDF_FORMAT_STL);
    sdf_format off = SDF_FORMAT_OFF;
    hammer("tetrahedron.off", small_off, sizeof small_off - 1, read_mesh, &off);

    /* A binary STL of two triangles. */
    unsigned char stl[84 + 2 * 50] = {0};
    stl[80] = 2;
    for (int t = 0; t < 2; t++) {
        float tri[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, (float)t};
        memcpy(stl + 84 + 50 * t, tri, sizeof tri);
    }
    sdf_format stl_format = SDF_FORMAT_STL;
    hammer("binary.stl", stl, sizeof stl, read_mesh, &stl_format);
}

static void test_npy(void)
{
    /* A (5, 3) float32 .npy. */
    char npy[256];
    size_t shape[2] = {5, 3};
    long head = sdf_npy_write_header(npy, sizeof npy, 2, shape);
    CHECK(head > 0 && (size_t)head + 60 <= sizeof npy, "npy header");
    for (int i = 0; i < 15; i++) {
        float v = 0.25f * (float)i;
        memcpy(npy + head + 4 * i, &v, 4);
    }
    hammer("points.npy", npy, (size_t)head + 60, read_npy, NULL);
    sdfd_form npy_form = SDFD_FORM_NPY;
    hammer("points.npy as a body", npy, (size_t)head + 60, read_body, &npy_form);
}

static void test_exr(void)
{
    /* EXR volumes: a zero-order and a packed first-order bake of the demo mesh. */
    sdf_mesh *demo = NULL;
    CHECK(sdf_mesh_create_demo(&demo) == 0, "demo mesh");
    for (int order = 0; order <= 1; order++) {
        sdf_bake_options bo = {.dims = {4, 3, 2}, .order = order, .query.threads = 1,
                               .encoding = order ? SDF_ENCODING_PACKED32 : SDF_ENCODING_FLOAT32};
        sdf_volume *v = NULL;
        sdf_diag diag;
        CHECK(sdf_volume_bake(demo, &bo, &v, &diag) == 0, "bake: %s", diag.message);
        void *exr = NULL;
        size_t exr_len = 0;
        CHECK(sdf_volume_save_memory(v, SDF_VOLUME_EXR, &exr, &exr_len, &diag) == 0, "save");
        hammer(order ? "packed first order.exr" : "zero order.exr", exr, exr_len, read_exr,
               NULL);
        free(exr);
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(demo);
}

static void test_frames(void)
{
    /* Binary protocol frames: a filtered QUERY and a VOLUME_QUERY. */
    float pts[9] = {0, 0, 0, 1, 2, 3, -1, 0.5f, 4};
    unsigned char frame[512];
    sdf_proto_query q = {.mode = SDF_MODE_FILTERED, .sign = SDF_SIGN_AUTO, .name = "demo",
                         .name_len = 4, .count = 3, .points = pts,
                         .filter = {.samples = 16, .seed = 7}};
    size_t fl = sdf_proto_encode_query(frame, sizeof frame, 9, &q);
    CHECK(fl > 0, "encode query");
    hammer("QUERY frame", frame, fl, read_frame, NULL);
    sdf_proto_volume_query vq = {.gradient = 1, .name = "vol", .name_len = 3, .count = 3,
                                 .points = pts};
    fl = sdf_proto_encode_volume_query(frame, sizeof frame, 10, &vq);
    CHECK(fl > 0, "encode volume query");
    hammer("VOLUME_QUERY frame", frame, fl, read_frame, NULL);
}

static void test_bodies(void)
{
    /* HTTP query bodies. */
    static const char json[] =
        "{\"points\": [[0, 0, 0], [1.5e-3, -2, 3E2], [0.1, 0.2, 0.3]], \"mode\": \"filtered\", "
        "\"sign\": \"auto\", \"filter\": {\"samples\": 8, \"kernel\": \"bump\"}}";
    sdfd_form json_form = SDFD_FORM_JSON, octet_form = SDFD_FORM_OCTET;
    hammer("JSON body", json, sizeof json - 1, read_body, &json_form);
    static const char flat[] = "{\"points\": [0.5, 1, -2.25e1, 3, 4, 5], \"mode\": \"closest\"}";
    hammer("flat JSON body", flat, sizeof flat - 1, read_body, &json_form);
    float pts[9] = {0, 0, 0, 1, 2, 3, -1, 0.5f, 4};
    hammer("octet body", pts, sizeof pts, read_body, &octet_form);
}

static const check_case cases[] = {
    {"meshes", test_meshes},
    {"npy", test_npy},
    {"exr", test_exr},
    {"frames", test_frames},
    {"bodies", test_bodies},
};

int main(int argc, char **argv)
{
    return check_main("mutations", cases, CHECK_COUNT_OF(cases), argc, argv);
}
