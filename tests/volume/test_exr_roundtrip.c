/* test_exr_roundtrip.c - EXR volume files (lib/volume/exr.c) keep every volume bit for bit,
 * because volumes are stored as EXR:
 *  - round trips through memory and files are exact for random, constant, run-length and
 *    smooth fields, every order and encoding sdf_volume_save_* writes, 16^3 to 256^3 and
 *    uneven sizes whose last chunk is short;
 *  - a sweep of chunks whose ZIP output lands just below, on and just above the raw size:
 *    OpenEXR reads a chunk whose stored size equals its raw size as raw, so every such chunk
 *    in our files must hold the raw pixels (OpenEXRCore 3.1's ZIP step stores a chunk that
 *    packs to exactly its raw size compressed, which then reads back as garbage);
 *  - the case that was reported: a 128^3 zero-order bake of a sphere round-trips;
 *  - exrheader reads what we write; a chunk whose declared size exceeds its raw size or the
 *    file, or whose offset points past the file, and every truncation, is refused with a
 *    message and no volume.
 * The file's chunks are inspected with OpenEXRCore itself (exr_read_chunk gives the stored
 * bytes), independently of the reader under test. */
#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/check.h"
#include "../common/workload.h"

/* ---- what a file's chunks hold ------------------------------------------------------------ */

typedef struct census {
    size_t chunks, compressed, raw; /* stored smaller than raw, stored at the raw size */
    size_t mislabelled;             /* stored at the raw size but not the raw pixels */
    size_t oversize;                /* stored larger than raw (never written by OpenEXR) */
} census;

typedef struct input {
    const unsigned char *data;
    size_t size;
} input;

static int64_t read_input(exr_const_context_t ctxt, void *user, void *buffer, uint64_t sz,
                          uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
    const input *in = user;
    (void)ctxt, (void)error_cb;
    if (offset >= in->size)
        return 0;
    uint64_t n = in->size - offset < sz ? in->size - offset : sz;
    memcpy(buffer, in->data + offset, (size_t)n);
    return (int64_t)n;
}

static int64_t size_input(exr_const_context_t ctxt, void *user)
{
    (void)ctxt;
    return (int64_t)((const input *)user)->size;
}

static exr_context_t open_exr(input *in)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = in;
    init.read_fn = read_input;
    init.size_fn = size_input;
    exr_context_t ctxt = NULL;
    return exr_start_read(&ctxt, "volume.exr", &init) ? NULL : ctxt;
}

/* The raw (uncompressed) bytes of image rows y0 .. y0 + lines - 1 as EXR lays them out: per
 * row, each channel's N values in turn, channels by name - which is the words' order (d;
 * a b c d; packed). Little-endian, as this machine. */
static void raw_rows(const sdf_volume *v, int y0, int lines, unsigned char *out)
{
    sdf_volume_info in;
    sdf_volume_get_info(v, &in);
    int words = sdf_volume_channels(&in);
    const uint32_t *w = sdf_volume_data(v);
    for (int y = y0; y < y0 + lines; y++)
        for (int c = 0; c < words; c++)
            for (size_t x = 0; x < in.dims[0]; x++, out += 4)
                memcpy(out, &w[((size_t)y * in.dims[0] + x) * (size_t)words + (size_t)c], 4);
}

static census take_census(const void *file, size_t size, const sdf_volume *v)
{
    census s = {0};
    input in = {file, size};
    exr_context_t ctxt = open_exr(&in);
    CHECK(ctxt != NULL, "OpenEXRCore cannot open the file");
    if (!ctxt)
        return s;
    sdf_volume_info info;
    sdf_volume_get_info(v, &info);
    int height = (int)(info.dims[1] * info.dims[2]), lines = 0;
    CHECK(exr_get_scanlines_per_chunk(ctxt, 0, &lines) == 0 && lines > 0, "scanlines per chunk");
    size_t row_bytes = info.dims[0] * (size_t)sdf_volume_channels(&info) * 4;
    size_t chunk_bytes = row_bytes * (size_t)lines;
    unsigned char *stored = malloc(chunk_bytes), *raw = malloc(chunk_bytes);
    for (int y = 0; lines > 0 && y < height; y += lines) {
        exr_chunk_info_t chunk;
        if (exr_read_scanline_chunk_info(ctxt, 0, y, &chunk)) {
            CHECK(0, "chunk info at row %d", y);
            break;
        }
        s.chunks++;
        if (chunk.packed_size > chunk.unpacked_size || chunk.unpacked_size > chunk_bytes) {
            s.oversize++;
            continue;
        }
        if (chunk.packed_size < chunk.unpacked_size) {
            s.compressed++;
            continue;
        }
        s.raw++;
        raw_rows(v, chunk.start_y, chunk.height, raw);
        int ok = !exr_read_chunk(ctxt, 0, &chunk, stored) &&
                 !memcmp(stored, raw, chunk.unpacked_size);
        s.mislabelled += !ok;
    }
    free(stored), free(raw);
    exr_finish(&ctxt);
    return s;
}

/* ---- round trips ---------------------------------------------------------------------------- */

static int same_volume(const sdf_volume *a, const sdf_volume *b)
{
    sdf_volume_info ia, ib;
    sdf_volume_get_info(a, &ia), sdf_volume_get_info(b, &ib);
    return !memcmp(&ia, &ib, sizeof ia) && sdf_volume_data_bytes(a) == sdf_volume_data_bytes(b) &&
           !memcmp(sdf_volume_data(a), sdf_volume_data(b), sdf_volume_data_bytes(a));
}

/* Save to memory, load back, compare; the chunks must be stored as OpenEXR reads them. */
static census round_trip(const sdf_volume *v, const char *name)
{
    census s = {0};
    void *exr = NULL;
    size_t size = 0;
    sdf_diag diag;
    int rc = sdf_volume_save_memory(v, SDF_VOLUME_EXR, &exr, &size, &diag);
    CHECK(rc == 0, "%s: save: %s", name, diag.message);
    if (rc)
        return s;
    sdf_volume *back = NULL;
    rc = sdf_volume_load_exr_memory(exr, size, &back, &diag);
    CHECK(rc == 0, "%s: load: %s", name, diag.message);
    CHECK(back && same_volume(v, back), "%s: the EXR round trip is not exact", name);
    sdf_volume_destroy(back);
    s = take_census(exr, size, v);
    CHECK(s.mislabelled == 0 && s.oversize == 0,
          "%s: %zu of %zu chunks stored at the raw size are not raw, %zu larger than raw", name,
          s.mislabelled, s.raw, s.oversize);
    free(exr);
    return s;
}

/* The same through a file, and OpenEXR's exrheader reads it. */
static void file_round_trip(const sdf_volume *v, const char *name)
{
    char path[] = "/tmp/sdf-exr-XXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0, "mkstemp");
    if (fd < 0)
        return;
    close(fd);
    sdf_diag diag;
    CHECK(sdf_volume_save_file(v, SDF_VOLUME_EXR, path, &diag) == 0, "%s: save file: %s", name,
          diag.message);
    sdf_volume *back = NULL;
    CHECK(sdf_volume_load_exr_file(path, &back, &diag) == 0, "%s: load file: %s", name,
          diag.message);
    CHECK(back && same_volume(v, back), "%s: the file round trip is not exact", name);
    sdf_volume_destroy(back);
    char cmd[128], line[512];
    snprintf(cmd, sizeof cmd, "exrheader %s 2>&1", path);
    FILE *pipe = popen(cmd, "r");
    CHECK(pipe != NULL, "cannot run exrheader");
    int listed = 0;
    while (pipe && fgets(line, sizeof line, pipe))
        listed += strstr(line, "sdf.dims") != NULL || strstr(line, "zip") != NULL;
    int status = pipe ? pclose(pipe) : -1;
    CHECK(status == 0 && listed >= 2, "%s: exrheader failed (status %d, %d lines seen)", name,
          status, listed);
    remove(path);
}

/* ---- volumes -------------------------------------------------------------------------------- */

enum field { RANDOM, CONSTANT, ZEROS, RUNS, SMOOTH, FIELDS };
static const char *const field_names[FIELDS] = {"random", "constant", "zeros", "runs", "smooth"};

static uint32_t finite_bits(uint32_t w, sdf_volume_encoding e)
{
    if (e == SDF_ENCODING_FLOAT32 && (w & 0x7f800000u) == 0x7f800000u)
        w &= ~0x40000000u; /* an exponent of all ones would be Inf or NaN */
    return w;
}

static sdf_volume *make_volume(const size_t dims[3], int order, sdf_volume_encoding e,
                               enum field field, uint64_t seed)
{
    sdf_volume_info in = {.dims = {dims[0], dims[1], dims[2]}, .origin = {-1, -2, 0.5},
                          .spacing = {0.01, 0.02, 0.03}, .order = order, .encoding = e};
    if (order == 1)
        in.fine_half = 1, in.fine_spacing = 0.1;
    if (e == SDF_ENCODING_PACKED32)
        in.packed_center = 0.25, in.packed_range = 2;
    size_t n = dims[0] * dims[1] * dims[2] * (size_t)sdf_volume_channels(&in);
    uint32_t *w = malloc(n * 4);
    sdf_rng rng = {seed};
    uint32_t run_value = 0;
    size_t run_left = 0;
    for (size_t i = 0; i < n; i++) {
        uint32_t r = (uint32_t)(sdf_rng_next(&rng) >> 32);
        if (field == RANDOM)
            w[i] = r;
        else if (field == CONSTANT)
            w[i] = 0x3f9d70a4u; /* 1.23f */
        else if (field == ZEROS)
            w[i] = 0;
        else if (field == RUNS) {
            if (!run_left)
                run_value = r, run_left = 1 + sdf_rng_next(&rng) % 300;
            w[i] = run_value, run_left--;
        } else {
            float f = (float)(sin(0.05 * (double)i) + 0.001 * (double)(i % 97));
            memcpy(&w[i], &f, 4);
        }
        w[i] = finite_bits(w[i], e);
    }
    sdf_volume *v = NULL;
    sdf_diag diag;
    CHECK(sdf_volume_create(&in, w, &v, &diag) == 0, "create: %s", diag.message);
    free(w);
    return v;
}

/* Every field, order and encoding over a range of sizes. */
static void test_fields(void)
{
    static const size_t sizes[][3] = {{16, 16, 16}, {17, 33, 20}, {2, 2, 2}, {64, 64, 64},
                                      {128, 128, 128}, {5, 200, 3}};
    const struct { int order; sdf_volume_encoding e; } kinds[] = {
        {0, SDF_ENCODING_FLOAT32}, {1, SDF_ENCODING_FLOAT32}, {1, SDF_ENCODING_PACKED32}};
    census total = {0};
    size_t volumes = 0;
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
        for (int k = 0; k < 3; k++)
            for (int f = 0; f < FIELDS; f++) {
                /* 128^3 first order is 32 MiB a volume: random and runs only. */
                if (sizes[s][0] == 128 && kinds[k].order == 1 && f != RANDOM && f != RUNS)
                    continue;
                sdf_volume *v = make_volume(sizes[s], kinds[k].order, kinds[k].e, (enum field)f,
                                            100 + s * 10 + (size_t)k);
                char name[96];
                snprintf(name, sizeof name, "%zux%zux%zu order %d %s %s", sizes[s][0],
                         sizes[s][1], sizes[s][2], kinds[k].order, sdf_encoding_name(kinds[k].e),
                         field_names[f]);
                if (v) {
                    census c = round_trip(v, name);
                    total.chunks += c.chunks, total.raw += c.raw, total.compressed += c.compressed;
                    volumes++;
                    if (s == 1)
                        file_round_trip(v, name);
                }
                sdf_volume_destroy(v);
            }
    printf("fields: %zu volumes, %zu chunks, %zu stored raw, %zu compressed\n", volumes,
           total.chunks, total.raw, total.compressed);
    CHECK(total.raw > 0 && total.compressed > 0, "the fields must give both kinds of chunk");
    /* 256^3: a random and a smooth zero-order field. */
    const size_t big[3] = {256, 256, 256};
    for (int f = 0; f < FIELDS; f += SMOOTH) {
        sdf_volume *v = make_volume(big, 0, SDF_ENCODING_FLOAT32, (enum field)f, 7);
        char name[64];
        snprintf(name, sizeof name, "256^3 order 0 %s", field_names[f]);
        if (v)
            round_trip(v, name);
        sdf_volume_destroy(v);
    }
}

/* Chunks whose compressed size crosses their raw size one byte at a time: slice k (one
 * 16-row ZIP chunk of 32 x 16 words) holds 2048 - 160 + k random bytes, then zeros. A chunk
 * can pack to exactly 2048 bytes, the size at which OpenEXR reads a chunk as raw (with this
 * seed two of the packed32 sweep's do). */
static void test_size_sweep(void)
{
    const sdf_volume_encoding encodings[] = {SDF_ENCODING_FLOAT32, SDF_ENCODING_PACKED32};
    for (int e = 0; e < 2; e++) {
        sdf_volume_info in = {.dims = {32, 16, 200}, .origin = {0, 0, 0}, .spacing = {1, 1, 1},
                              .order = e, .encoding = encodings[e], .packed_center = e ? 0.5 : 0,
                              .packed_range = e ? 1 : 0, .fine_half = e,
                              .fine_spacing = e ? 0.1 : 0};
        size_t slice = 32 * 16 * 4, nodes = 32 * 16 * 200;
        unsigned char *bytes = calloc(nodes, 4);
        sdf_rng rng = {11 + (uint64_t)e};
        for (size_t k = 0; k < 200; k++)
            for (size_t b = 0; b < slice - 160 + k && b < slice; b++)
                bytes[k * slice + b] = (unsigned char)(sdf_rng_next(&rng) >> 40);
        uint32_t *w = (uint32_t *)bytes;
        for (size_t i = 0; i < nodes; i++)
            w[i] = finite_bits(w[i], encodings[e]);
        sdf_volume *v = NULL;
        sdf_diag diag;
        CHECK(sdf_volume_create(&in, bytes, &v, &diag) == 0, "create: %s", diag.message);
        free(bytes);
        if (!v)
            continue;
        char name[64];
        snprintf(name, sizeof name, "size sweep %s", sdf_encoding_name(encodings[e]));
        census c = round_trip(v, name);
        printf("%s: %zu chunks, %zu stored raw, %zu compressed\n", name, c.chunks, c.raw,
               c.compressed);
        CHECK(c.raw > 10 && c.compressed > 10, "%s: the sweep must cross the raw size", name);
        sdf_volume_destroy(v);
    }
}

/* ---- the reported case: a sphere's zero-order bake at 128^3 --------------------------------- */

static sdf_mesh *icosphere(int subdivisions)
{
    const double t = (1 + sqrt(5)) / 2;
    double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                          {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    static const uint32_t faces[20][3] = {
        {0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
        {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    size_t tris = 20, verts = 12;
    for (int s = 0; s < subdivisions; s++)
        tris *= 4, verts += tris / 4 * 3; /* midpoints are not shared: the mesh welds them */
    double (*v)[3] = malloc(verts * sizeof *v);
    uint32_t (*f)[3] = malloc(tris * sizeof *f);
    memcpy(v, base, sizeof base), memcpy(f, faces, sizeof faces);
    size_t nv = 12, nf = 20;
    for (int s = 0; s < subdivisions; s++) {
        size_t old = nf;
        for (size_t i = 0; i < old; i++) {
            uint32_t a = f[i][0], b = f[i][1], c = f[i][2], m[3];
            uint32_t ends[3][2] = {{a, b}, {b, c}, {c, a}};
            for (int e = 0; e < 3; e++) {
                for (int d = 0; d < 3; d++)
                    v[nv][d] = (v[ends[e][0]][d] + v[ends[e][1]][d]) / 2;
                m[e] = (uint32_t)nv++;
            }
            uint32_t sub[4][3] = {
                {a, m[0], m[2]}, {b, m[1], m[0]}, {c, m[2], m[1]}, {m[0], m[1], m[2]}};
            memcpy(f[i], sub[0], sizeof sub[0]);
            for (int q = 1; q < 4; q++)
                memcpy(f[nf++], sub[q], sizeof sub[q]);
        }
    }
    float *xyz = malloc(nv * 3 * sizeof *xyz);
    for (size_t i = 0; i < nv; i++) {
        double len = sqrt(v[i][0] * v[i][0] + v[i][1] * v[i][1] + v[i][2] * v[i][2]);
        for (int d = 0; d < 3; d++)
            xyz[3 * i + d] = (float)(v[i][d] / len);
    }
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    CHECK(sdf_mesh_create(xyz, nv, &f[0][0], nf, NULL, &mesh, &diag) == 0, "sphere: %s",
          diag.message);
    free(v), free(f), free(xyz);
    return mesh;
}

static void test_sphere_bake(void)
{
    sdf_mesh *sphere = icosphere(4);
    if (!sphere)
        return;
    const struct { size_t dim; int order; sdf_volume_encoding e; } bakes[] = {
        {128, 0, SDF_ENCODING_FLOAT32}, {48, 1, SDF_ENCODING_FLOAT32},
        {48, 1, SDF_ENCODING_PACKED32}};
    for (size_t b = 0; b < sizeof bakes / sizeof bakes[0]; b++) {
        sdf_bake_options o = {.dims = {bakes[b].dim, bakes[b].dim, bakes[b].dim},
                              .order = bakes[b].order, .encoding = bakes[b].e};
        sdf_volume *v = NULL;
        sdf_diag diag;
        CHECK(sdf_volume_bake(sphere, &o, &v, &diag) == 0, "sphere bake: %s", diag.message);
        if (!v)
            continue;
        char name[64];
        snprintf(name, sizeof name, "sphere %zu^3 order %d %s", bakes[b].dim, bakes[b].order,
                 sdf_encoding_name(bakes[b].e));
        census c = round_trip(v, name);
        printf("%s: %zu chunks, %zu stored raw, %zu compressed\n", name, c.chunks, c.raw,
               c.compressed);
        if (b == 0)
            file_round_trip(v, name);
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(sphere);
}

/* ---- damaged files -------------------------------------------------------------------------- */

static uint32_t get32(const unsigned char *p)
{
    return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (unsigned char)(v >> 8 * i);
}
static void put64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (unsigned char)(v >> 8 * i);
}

/* Load a damaged copy: refused with a message and no volume, or (`may_recover`) the volume
 * unchanged - OpenEXR may rebuild a damaged offset table from the chunks themselves. */
static void expect_refused(const unsigned char *copy, size_t size, const sdf_volume *v,
                           const char *what, int may_recover)
{
    sdf_volume *out = (sdf_volume *)&out; /* must be cleared */
    sdf_diag diag = {0};
    int rc = sdf_volume_load_exr_memory(copy, size, &out, &diag);
    if (rc == 0 && may_recover) {
        CHECK(out && same_volume(out, v), "%s: accepted, but not the volume", what);
        printf("damaged: %s: recovered the volume\n", what);
    } else {
        CHECK(rc != 0 && out == NULL && diag.code == rc && diag.message[0],
              "%s: must be refused with a message (rc %d, %s)", what, rc, diag.message);
        printf("damaged: %s: %s\n", what, diag.message);
    }
    if (rc == 0)
        sdf_volume_destroy(out);
}

/* Chunk sizes and offsets that lie: larger than the chunk's raw size, past the file's end,
 * negative; offsets past the end; every truncation of the file. */
static void test_damaged(void)
{
    const size_t dims[3] = {32, 32, 24};
    sdf_volume *v = make_volume(dims, 0, SDF_ENCODING_FLOAT32, RUNS, 5);
    void *file = NULL;
    size_t size = 0;
    if (!v || sdf_volume_save_memory(v, SDF_VOLUME_EXR, &file, &size, NULL)) {
        CHECK(0, "damaged: no file to damage");
        sdf_volume_destroy(v);
        return;
    }
    input in = {file, size};
    exr_context_t ctxt = open_exr(&in);
    exr_chunk_info_t first = {0}, last = {0};
    int height = 32 * 24, lines = 0;
    int ok = ctxt && !exr_get_scanlines_per_chunk(ctxt, 0, &lines) && lines > 0 &&
             !exr_read_scanline_chunk_info(ctxt, 0, 0, &first) &&
             !exr_read_scanline_chunk_info(ctxt, 0, height - 1, &last);
    if (ctxt)
        exr_finish(&ctxt);
    const unsigned char *bytes = file;
    size_t chunks = (size_t)((height + lines - 1) / (lines ? lines : 1));
    /* A scanline chunk is (int32 y, int32 packed size, data); the offset table, one uint64 a
     * chunk pointing at those headers, comes just before the first. */
    ok = ok && first.data_offset >= 8 + 8 * chunks && last.data_offset + last.packed_size == size &&
         get32(bytes + first.data_offset - 4) == first.packed_size &&
         get32(bytes + last.data_offset - 4) == last.packed_size;
    size_t table = ok ? (size_t)first.data_offset - 8 - 8 * chunks : 0;
    ok = ok && first.packed_size < first.unpacked_size && last.packed_size + 1 < last.unpacked_size;
    CHECK(ok, "damaged: the file's layout is not as expected");
    if (ok) {
        unsigned char *copy = malloc(size);
        const struct {
            const exr_chunk_info_t *chunk;
            uint32_t packed;
            const char *what;
        } sizes[] = {
            {&first, (uint32_t)first.unpacked_size + 1, "first chunk one byte over its raw size"},
            {&first, (uint32_t)first.unpacked_size * 2, "first chunk twice its raw size"},
            {&first, 0x7fffffffu, "first chunk 2 GiB"},
            {&first, 0xffffffffu, "first chunk size -1"},
            {&first, 0, "first chunk size 0"},
            {&last, (uint32_t)last.packed_size + 1, "last chunk one byte past the file"},
        };
        for (size_t t = 0; t < sizeof sizes / sizeof sizes[0]; t++) {
            memcpy(copy, file, size);
            put32(copy + sizes[t].chunk->data_offset - 4, sizes[t].packed);
            expect_refused(copy, size, v, sizes[t].what, 0);
        }
        const struct { size_t chunk; uint64_t offset; const char *what; } offsets[] = {
            {0, size + 100, "first offset past the file"},
            {chunks - 1, size - 4, "last offset 4 bytes before the end"},
            {chunks - 1, UINT64_MAX, "last offset 2^64 - 1"},
            {1, 0, "second offset 0"},
        };
        for (size_t t = 0; t < sizeof offsets / sizeof offsets[0]; t++) {
            memcpy(copy, file, size);
            put64(copy + table + 8 * offsets[t].chunk, offsets[t].offset);
            expect_refused(copy, size, v, offsets[t].what, 1);
        }
        size_t refused = 0, tried = 0;
        for (size_t cut = 0; cut < size; cut += cut < 600 ? 1 : 97, tried++) {
            sdf_volume *t = NULL;
            refused += sdf_volume_load_exr_memory(file, cut, &t, NULL) != 0 && !t;
            sdf_volume_destroy(t);
        }
        CHECK(refused == tried, "damaged: %zu of %zu truncations accepted", tried - refused, tried);
        free(copy);
    }
    free(file);
    sdf_volume_destroy(v);
}

static const check_case cases[] = {
    {"size_sweep", test_size_sweep},
    {"sphere_bake", test_sphere_bake},
    {"fields", test_fields},
    {"damaged", test_damaged},
};

int main(int argc, char **argv)
{
    return check_main("exr_roundtrip", cases, CHECK_COUNT_OF(cases), argc, argv);
}
