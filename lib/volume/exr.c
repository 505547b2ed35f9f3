/* exr.c - a volume as one OpenEXR scanline image (OpenEXRCore, the C API of OpenEXR 3.1).
 *
 * The image is N pixels wide and M K high: z-slice k occupies rows k M .. k M + M - 1, row j
 * of a slice holds nodes (0..N-1, j, k). One channel per word of a node: FLOAT "d" (order 0),
 * FLOAT "a" "b" "c" "d" (order 1), or UINT "packed" (PACKED32), ZIP-compressed (lossless, so
 * a round trip is exact; a chunk ZIP does not shrink is stored raw). The volume's description
 * rides in sdf.* attributes that any EXR tool (exrheader) lists. All I/O goes through memory
 * callbacks: the server sends the bytes and the reader never trusts a length it has not
 * checked against the buffer. */
#include "volume/exr.h"

#include <math.h>
#include <openexr.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/diag.h"
#include "volume/volume.h"

typedef struct memory_stream {
    unsigned char *data;
    size_t size, cap;  /* writing: bytes written and allocated */
    const unsigned char *in;
    size_t in_size;    /* reading */
    char error[200];   /* the library's last message */
} memory_stream;

static void on_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    void *user = NULL;
    (void)code;
    if (exr_get_user_data(ctxt, &user) == EXR_ERR_SUCCESS && user)
        snprintf(((memory_stream *)user)->error, sizeof ((memory_stream *)user)->error, "%s", msg);
}

static int64_t write_memory(exr_const_context_t ctxt, void *user, const void *buffer, uint64_t sz,
                            uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
    memory_stream *m = user;
    if (offset > SIZE_MAX / 2 || sz > SIZE_MAX / 2 - offset)
        return error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "write past any buffer"), -1;
    size_t end = (size_t)(offset + sz);
    if (end > m->cap) {
        size_t cap = m->cap ? m->cap : 1 << 16;
        while (cap < end)
            cap *= 2;
        unsigned char *grown = realloc(m->data, cap);
        if (!grown)
            return error_cb(ctxt, EXR_ERR_OUT_OF_MEMORY, "no memory for the EXR file"), -1;
        m->data = grown, m->cap = cap;
    }
    memcpy(m->data + offset, buffer, (size_t)sz);
    if (end > m->size)
        m->size = end;
    return (int64_t)sz;
}

static int64_t read_memory(exr_const_context_t ctxt, void *user, void *buffer, uint64_t sz,
                           uint64_t offset, exr_stream_error_func_ptr_t error_cb)
{
    memory_stream *m = user;
    (void)ctxt, (void)error_cb;
    if (offset >= m->in_size)
        return 0;
    uint64_t n = m->in_size - offset < sz ? m->in_size - offset : sz;
    memcpy(buffer, m->in + offset, (size_t)n);
    return (int64_t)n;
}

static int64_t size_memory(exr_const_context_t ctxt, void *user)
{
    (void)ctxt;
    return (int64_t)((memory_stream *)user)->in_size;
}

/* The channel names of a volume, in word order within a node. */
static int channel_names(const sdf_volume_info *in, const char *names[4])
{
    if (in->encoding == SDF_ENCODING_PACKED32) {
        names[0] = "packed";
        return 1;
    }
    if (in->order == 0) {
        names[0] = "d";
        return 1;
    }
    names[0] = "a", names[1] = "b", names[2] = "c", names[3] = "d";
    return 4;
}

static int word_of(const char *name, const char *names[4], int count)
{
    for (int w = 0; w < count; w++)
        if (!strcmp(name, names[w]))
            return w;
    return -1;
}

static int exr_fail(sdf_diag *diag, int code, exr_result_t r, const memory_stream *m,
                    const char *what)
{
    return sdf__diag_set(diag, code, 0, -1, "OpenEXR %s: %s", what,
                         m->error[0] ? m->error : exr_get_default_error_message(r));
}

/* Point a coding pipeline's channels at their words in the volume's node data for the chunk
 * starting at row `start_y`: nodes are `words` 32-bit words apart, rows N nodes long. Encode
 * and decode pointers share one union, so this serves both directions. */
static void point_channels(exr_coding_channel_info_t *channels, int16_t count, const sdf_volume *v,
                           int32_t start_y)
{
    const char *names[4];
    int words = channel_names(&v->info, names);
    size_t pixel = (size_t)words * 4, row = v->info.dims[0] * pixel;
    for (int c = 0; c < count; c++) {
        exr_coding_channel_info_t *ch = &channels[c];
        int w = word_of(ch->channel_name, names, words);
        ch->decode_to_ptr = (uint8_t *)v->data.p + (size_t)start_y * row + (size_t)(w < 0 ? 0 : w) * 4;
        ch->user_pixel_stride = (int32_t)pixel;
        ch->user_line_stride = (int32_t)row;
        ch->user_bytes_per_element = 4;
        ch->user_data_type = ch->data_type;
    }
}

/* ---- writing ----------------------------------------------------------------------------- */

static exr_result_t write_header(exr_context_t ctxt, const sdf_volume *v, int width, int height)
{
    const sdf_volume_info *in = &v->info;
    const char *names[4];
    int channels = channel_names(in, names), part;
    exr_result_t r = exr_add_part(ctxt, "volume", EXR_STORAGE_SCANLINE, &part);
    if (!r)
        r = exr_initialize_required_attr_simple(ctxt, part, width, height, EXR_COMPRESSION_ZIP);
    exr_pixel_type_t type = in->encoding == SDF_ENCODING_PACKED32 ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT;
    for (int c = 0; !r && c < channels; c++)
        r = exr_add_channel(ctxt, part, names[c], type, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    exr_attr_v3i_t dims = {.arr = {(int32_t)in->dims[0], (int32_t)in->dims[1], (int32_t)in->dims[2]}};
    exr_attr_v3d_t origin = {.arr = {in->origin[0], in->origin[1], in->origin[2]}};
    exr_attr_v3d_t spacing = {.arr = {in->spacing[0], in->spacing[1], in->spacing[2]}};
    if (!r) r = exr_attr_set_v3i(ctxt, part, "sdf.dims", &dims);
    if (!r) r = exr_attr_set_v3d(ctxt, part, "sdf.origin", &origin);
    if (!r) r = exr_attr_set_v3d(ctxt, part, "sdf.spacing", &spacing);
    if (!r) r = exr_attr_set_int(ctxt, part, "sdf.order", in->order);
    if (!r) r = exr_attr_set_string(ctxt, part, "sdf.encoding", sdf_encoding_name(in->encoding));
    if (!r) r = exr_attr_set_double(ctxt, part, "sdf.packedCenter", in->packed_center);
    if (!r) r = exr_attr_set_double(ctxt, part, "sdf.packedRange", in->packed_range);
    if (!r) r = exr_attr_set_int(ctxt, part, "sdf.fineHalf", in->fine_half);
    if (!r) r = exr_attr_set_double(ctxt, part, "sdf.fineSpacing", in->fine_spacing);
    if (!r) r = exr_attr_set_string(ctxt, part, "sdf.normalize", sdf_normalize_name(in->normalize));
    if (!r) r = exr_attr_set_int(ctxt, part, "sdf.filtered", in->filtered);
    if (!r) r = exr_write_header(ctxt);
    return r;
}

/* OpenEXR reads a chunk stored at exactly its raw size as raw pixels, the C++ library and
 * OpenEXRCore alike. OpenEXRCore 3.1's ZIP step keeps its output when that is exactly the raw
 * size, and such a chunk reads back as garbage. So its compress step runs wrapped: a chunk
 * that does not pack smaller than raw is stored raw, as the C++ library writes it. */
typedef struct compress_step {
    exr_result_t (*compress)(exr_encode_pipeline_t *encoder);
} compress_step;

static exr_result_t compress_or_store_raw(exr_encode_pipeline_t *e)
{
    const compress_step *step = e->encoding_user_data;
    exr_result_t r = step->compress(e);
    if (r || e->compressed_bytes < e->packed_bytes)
        return r;
    if (e->compressed_alloc_size < e->packed_bytes)
        return EXR_ERR_OUT_OF_MEMORY;
    memcpy(e->compressed_buffer, e->packed_buffer, e->packed_bytes);
    e->compressed_bytes = e->packed_bytes;
    return EXR_ERR_SUCCESS;
}

static exr_result_t write_pixels(exr_context_t ctxt, const sdf_volume *v, int height)
{
    int lines = 1;
    exr_result_t r = exr_get_scanlines_per_chunk(ctxt, 0, &lines);
    exr_encode_pipeline_t encoder = EXR_ENCODE_PIPELINE_INITIALIZER;
    compress_step step = {NULL};
    int started = 0;
    for (int y = 0; !r && y < height; y += lines) {
        exr_chunk_info_t chunk;
        r = exr_write_scanline_chunk_info(ctxt, 0, y, &chunk);
        if (!r)
            r = started ? exr_encoding_update(ctxt, 0, &chunk, &encoder)
                        : exr_encoding_initialize(ctxt, 0, &chunk, &encoder);
        if (r)
            break;
        point_channels(encoder.channels, encoder.channel_count, v, chunk.start_y);
        if (!started && !(r = exr_encoding_choose_default_routines(ctxt, 0, &encoder))) {
            started = 1;
            if (encoder.compress_fn) {
                step.compress = encoder.compress_fn;
                encoder.encoding_user_data = &step;
                encoder.compress_fn = compress_or_store_raw;
            }
        }
        if (!r)
            r = exr_encoding_run(ctxt, 0, &encoder);
    }
    if (started)
        exr_encoding_destroy(ctxt, &encoder);
    return r;
}

int sdf__exr_save(const sdf_volume *v, void **data, size_t *size, sdf_diag *diag)
{
    *data = NULL, *size = 0;
    size_t height = v->info.dims[1] * v->info.dims[2];
    if (height > INT32_MAX)
        return sdf__diag_set(diag, SDF_ELIMIT, 0, -1, "volume too tall for one EXR image");
    memory_stream m = {0};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &m;
    init.write_fn = write_memory;
    init.error_handler_fn = on_error;
    exr_context_t ctxt = NULL;
    exr_result_t r = exr_start_write(&ctxt, "volume.exr", EXR_WRITE_FILE_DIRECTLY, &init);
    if (!r)
        r = write_header(ctxt, v, (int)v->info.dims[0], (int)height);
    if (!r)
        r = write_pixels(ctxt, v, (int)height);
    exr_result_t finished = ctxt ? exr_finish(&ctxt) : EXR_ERR_SUCCESS;
    if (!r)
        r = finished;
    if (r) {
        free(m.data);
        return exr_fail(diag, r == EXR_ERR_OUT_OF_MEMORY ? SDF_ENOMEM : SDF_EIO, r, &m, "write");
    }
    *data = m.data, *size = m.size;
    return 0;
}

/* ---- reading ----------------------------------------------------------------------------- */

static int read_info(exr_context_t ctxt, sdf_volume_info *in, memory_stream *m, sdf_diag *diag)
{
    exr_attr_v3i_t dims;
    exr_attr_v3d_t origin, spacing;
    int32_t order = 0, fine_half = 0, filtered = 0, length = 0, normalize_length = 0;
    const char *encoding = NULL, *normalize = NULL;
    exr_result_t r = exr_attr_get_v3i(ctxt, 0, "sdf.dims", &dims);
    if (!r) r = exr_attr_get_v3d(ctxt, 0, "sdf.origin", &origin);
    if (!r) r = exr_attr_get_v3d(ctxt, 0, "sdf.spacing", &spacing);
    if (!r) r = exr_attr_get_int(ctxt, 0, "sdf.order", &order);
    if (!r) r = exr_attr_get_string(ctxt, 0, "sdf.encoding", &length, &encoding);
    if (!r) r = exr_attr_get_double(ctxt, 0, "sdf.packedCenter", &in->packed_center);
    if (!r) r = exr_attr_get_double(ctxt, 0, "sdf.packedRange", &in->packed_range);
    if (!r) r = exr_attr_get_int(ctxt, 0, "sdf.fineHalf", &fine_half);
    if (!r) r = exr_attr_get_double(ctxt, 0, "sdf.fineSpacing", &in->fine_spacing);
    if (!r) r = exr_attr_get_string(ctxt, 0, "sdf.normalize", &normalize_length, &normalize);
    if (!r) r = exr_attr_get_int(ctxt, 0, "sdf.filtered", &filtered);
    if (r)
        return exr_fail(diag, SDF_EFORMAT, r, m, "file is not an sdfd volume (sdf.* attributes)");
    char name[16] = "", how[16] = "";
    if (length > 0 && length < (int32_t)sizeof name)
        memcpy(name, encoding, (size_t)length);
    if (normalize_length > 0 && normalize_length < (int32_t)sizeof how)
        memcpy(how, normalize, (size_t)normalize_length);
    if (sdf_encoding_from_name(name, &in->encoding) || sdf_normalize_from_name(how, &in->normalize))
        return sdf__diag_set(diag, SDF_EFORMAT, 0, -1,
                             "unknown volume encoding or normalisation in the EXR file");
    for (int a = 0; a < 3; a++) {
        if (dims.arr[a] < 2 || dims.arr[a] > SDF_VOLUME_MAX_DIM)
            return sdf__diag_set(diag, SDF_EFORMAT, 0, -1, "EXR volume dimension %d out of range",
                                 dims.arr[a]);
        in->dims[a] = (size_t)dims.arr[a];
        in->origin[a] = origin.arr[a];
        in->spacing[a] = spacing.arr[a];
    }
    in->order = order, in->fine_half = fine_half, in->filtered = filtered;
    int rc = sdf__volume_check_info(in, diag);
    if (rc)
        return rc == SDF_ELIMIT ? rc : SDF_EFORMAT;
    /* The image must be exactly the layout above. */
    exr_storage_t storage;
    exr_attr_box2i_t window;
    const exr_attr_chlist_t *list = NULL;
    if ((r = exr_get_storage(ctxt, 0, &storage)) || (r = exr_get_data_window(ctxt, 0, &window)) ||
        (r = exr_get_channels(ctxt, 0, &list)))
        return exr_fail(diag, SDF_EFORMAT, r, m, "header");
    const char *names[4];
    int words = channel_names(in, names);
    exr_pixel_type_t type = in->encoding == SDF_ENCODING_PACKED32 ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT;
    int ok = storage == EXR_STORAGE_SCANLINE && window.min.x == 0 && window.min.y == 0 &&
             (size_t)window.max.x + 1 == in->dims[0] &&
             (size_t)window.max.y + 1 == in->dims[1] * in->dims[2] && list->num_channels == words;
    for (int c = 0; ok && c < list->num_channels; c++) {
        const exr_attr_chlist_entry_t *e = &list->entries[c];
        ok = e->pixel_type == type && e->x_sampling == 1 && e->y_sampling == 1 &&
             word_of(e->name.str, names, words) >= 0;
    }
    if (!ok)
        return sdf__diag_set(diag, SDF_EFORMAT, 0, -1,
                             "EXR image does not match its sdf.* description (size or channels)");
    return 0;
}

/* A chunk must cover rows inside the image, hold the raw size of its rows, store no more
 * than that (OpenEXR never writes a chunk larger than raw) and end inside the file. OpenEXRCore
 * 3.1 checks most of this itself; the reader does not rely on one version's checks. */
static int check_chunk(const exr_chunk_info_t *c, const sdf_volume *v, int height,
                       const memory_stream *m, sdf_diag *diag)
{
    uint64_t row = (uint64_t)v->info.dims[0] * (uint64_t)v->channels * 4;
    if (c->start_y < 0 || c->height < 1 || c->start_y > height - c->height)
        return sdf__diag_set(diag, SDF_EPARSE, 0, -1,
                             "EXR chunk at row %d covers rows outside the image", (int)c->start_y);
    if (c->unpacked_size != (uint64_t)c->height * row || c->packed_size > c->unpacked_size ||
        c->data_offset > m->in_size || c->packed_size > m->in_size - c->data_offset)
        return sdf__diag_set(diag, SDF_EPARSE, 0, -1,
                             "EXR chunk at row %d stores %llu bytes at offset %llu for %llu raw "
                             "bytes (%llu expected) in a file of %zu bytes", (int)c->start_y,
                             (unsigned long long)c->packed_size, (unsigned long long)c->data_offset,
                             (unsigned long long)c->unpacked_size,
                             (unsigned long long)((uint64_t)c->height * row), m->in_size);
    return 0;
}

static int read_pixels(exr_context_t ctxt, sdf_volume *v, memory_stream *m, sdf_diag *diag)
{
    int lines = 1;
    int height = (int)(v->info.dims[1] * v->info.dims[2]);
    exr_result_t r = exr_get_scanlines_per_chunk(ctxt, 0, &lines);
    exr_decode_pipeline_t decoder = EXR_DECODE_PIPELINE_INITIALIZER;
    int started = 0, rc = 0;
    for (int y = 0; !r && y < height; y += lines) {
        exr_chunk_info_t chunk;
        r = exr_read_scanline_chunk_info(ctxt, 0, y, &chunk);
        if (!r && (rc = check_chunk(&chunk, v, height, m, diag)))
            break;
        if (!r)
            r = started ? exr_decoding_update(ctxt, 0, &chunk, &decoder)
                        : exr_decoding_initialize(ctxt, 0, &chunk, &decoder);
        if (r)
            break;
        point_channels(decoder.channels, decoder.channel_count, v, chunk.start_y);
        if (!started && !(r = exr_decoding_choose_default_routines(ctxt, 0, &decoder)))
            started = 1;
        if (!r)
            r = exr_decoding_run(ctxt, 0, &decoder);
    }
    if (started)
        exr_decoding_destroy(ctxt, &decoder);
    return rc ? rc : r ? exr_fail(diag, SDF_EPARSE, r, m, "pixels") : 0;
}

int sdf__exr_load(const void *data, size_t size, sdf_volume **out, sdf_diag *diag)
{
    *out = NULL;
    memory_stream m = {.in = data, .in_size = size};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &m;
    init.read_fn = read_memory;
    init.size_fn = size_memory;
    init.error_handler_fn = on_error;
    init.max_image_width = SDF_VOLUME_MAX_DIM;
    init.max_image_height = SDF_VOLUME_MAX_DIM * SDF_VOLUME_MAX_DIM;
    exr_context_t ctxt = NULL;
    exr_result_t r = exr_start_read(&ctxt, "volume.exr", &init);
    int rc = 0, parts = 0;
    if (r || (r = exr_get_count(ctxt, &parts)) || parts != 1)
        rc = r ? exr_fail(diag, SDF_EFORMAT, r, &m, "read")
               : sdf__diag_set(diag, SDF_EFORMAT, 0, -1, "an sdfd EXR volume has one part");
    sdf_volume_info info = {0};
    if (!rc)
        rc = read_info(ctxt, &info, &m, diag);
    sdf_volume *v = NULL;
    if (!rc && (rc = sdf__volume_alloc(&info, &v)))
        sdf__diag_set(diag, rc, 0, -1, "no memory for the volume");
    if (!rc)
        rc = read_pixels(ctxt, v, &m, diag);
    if (ctxt)
        exr_finish(&ctxt);
    if (!rc && info.encoding == SDF_ENCODING_FLOAT32) {
        /* The same check sdf_volume_create makes. */
        size_t n = sdf_volume_data_bytes(v) / 4;
        for (size_t i = 0; i < n && !rc; i++)
            if (!isfinite(v->data.f[i]))
                rc = sdf__diag_set(diag, SDF_ENONFINITE, 0, -1, "EXR volume holds a non-finite value");
    }
    if (rc) {
        sdf_volume_destroy(v);
        return rc;
    }
    *out = v;
    return 0;
}
