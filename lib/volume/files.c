/* files.c - volumes as files: OpenEXR (exr.c), NumPy .npy and raw words with JSON metadata
 * (layouts in sdf.h and docs/volumes.md). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/diag.h"
#include "volume/exr.h"
#include "volume/volume.h"

#define MAX_EXR_FILE_BYTES ((size_t)1 << 34) /* 16 GiB: more than any allowed volume */

/* .npy: (K, M, N) or (K, M, N, 4), float32 - or uint32 for packed nodes. */
long sdf_volume_npy_header(const sdf_volume *v, char *dst, size_t cap)
{
    const sdf_volume_info *in = &v->info;
    size_t shape[4] = {in->dims[2], in->dims[1], in->dims[0], 4};
    return sdf_npy_write_header_descr(dst, cap,
                                      in->encoding == SDF_ENCODING_PACKED32 ? "'<u4'" : "'<f4'",
                                      v->channels == 4 ? 4 : 3, shape);
}

static int save_npy(const sdf_volume *v, void **data, size_t *size, sdf_diag *diag)
{
    char header[512];
    long len = sdf_volume_npy_header(v, header, sizeof header);
    if (len < 0)
        return sdf__diag_set(diag, (int)len, 0, -1, "cannot write the npy header");
    size_t bytes = sdf_volume_data_bytes(v);
    unsigned char *out = malloc((size_t)len + bytes);
    if (!out)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory for the npy file");
    memcpy(out, header, (size_t)len);
    memcpy(out + len, v->data.p, bytes);
    *data = out, *size = (size_t)len + bytes;
    return 0;
}

static int save_raw(const sdf_volume *v, void **data, size_t *size, sdf_diag *diag)
{
    size_t bytes = sdf_volume_data_bytes(v);
    void *out = malloc(bytes);
    if (!out)
        return sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory for the raw file");
    memcpy(out, v->data.p, bytes);
    *data = out, *size = bytes;
    return 0;
}

int sdf_volume_save_memory(const sdf_volume *volume, sdf_volume_file type, void **data,
                           size_t *size, sdf_diag *diag)
{
    if (!volume || !data || !size)
        return SDF_EINVAL;
    *data = NULL, *size = 0;
    switch (type) {
    case SDF_VOLUME_EXR: return sdf__exr_save(volume, data, size, diag);
    case SDF_VOLUME_NPY: return save_npy(volume, data, size, diag);
    case SDF_VOLUME_RAW: return save_raw(volume, data, size, diag);
    }
    return sdf__diag_set(diag, SDF_EINVAL, 0, -1, "unknown volume file type");
}

int sdf_volume_save_file(const sdf_volume *volume, sdf_volume_file type, const char *path,
                         sdf_diag *diag)
{
    if (!path)
        return SDF_EINVAL;
    void *data;
    size_t size;
    int rc = sdf_volume_save_memory(volume, type, &data, &size, diag);
    if (rc)
        return rc;
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(data, 1, size, f) == size;
    if (f && fclose(f))
        ok = 0;
    free(data);
    if (!ok)
        return sdf__diag_set(diag, SDF_EIO, 0, -1, "cannot write %s: %s", path, strerror(errno));
    return 0;
}

int sdf_volume_load_exr_memory(const void *data, size_t size, sdf_volume **out, sdf_diag *diag)
{
    if (!out || (!data && size))
        return SDF_EINVAL;
    return sdf__exr_load(data, size, out, diag);
}

int sdf_volume_load_exr_file(const char *path, sdf_volume **out, sdf_diag *diag)
{
    if (!out || !path)
        return SDF_EINVAL;
    *out = NULL;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sdf__diag_set(diag, SDF_EIO, 0, -1, "cannot open %s: %s", path, strerror(errno));
    long size = fseek(f, 0, SEEK_END) ? -1 : ftell(f);
    int rc = 0;
    unsigned char *data = NULL;
    if (size < 0 || (size_t)size > MAX_EXR_FILE_BYTES)
        rc = sdf__diag_set(diag, size < 0 ? SDF_EIO : SDF_ELIMIT, 0, -1, "cannot size %s", path);
    else if (!(data = malloc((size_t)size + 1)))
        rc = sdf__diag_set(diag, SDF_ENOMEM, 0, -1, "no memory to read %s", path);
    else if (fseek(f, 0, SEEK_SET) || fread(data, 1, (size_t)size, f) != (size_t)size)
        rc = sdf__diag_set(diag, SDF_EIO, 0, -1, "cannot read %s", path);
    fclose(f);
    if (!rc)
        rc = sdf__exr_load(data, (size_t)size, out, diag);
    free(data);
    return rc;
}

long sdf_volume_describe_json(const sdf_volume *volume, char *dst, size_t cap)
{
    const sdf_volume_info *in = &volume->info;
    int n = snprintf(dst, cap,
                     "{\"dims\": [%zu, %zu, %zu], \"origin\": [%.17g, %.17g, %.17g], "
                     "\"spacing\": [%.17g, %.17g, %.17g], \"order\": %d, \"encoding\": \"%s\", "
                     "\"packed_center\": %.17g, \"packed_range\": %.17g, \"fine_half\": %d, "
                     "\"fine_spacing\": %.17g, \"normalize\": \"%s\", "
                     "\"filtered\": %s, \"channels\": %d, \"layout\": \"x fastest, then y, "
                     "then z\", \"dtype\": \"%s\", \"bytes\": %zu}",
                     in->dims[0], in->dims[1], in->dims[2], in->origin[0], in->origin[1],
                     in->origin[2], in->spacing[0], in->spacing[1], in->spacing[2], in->order,
                     sdf_encoding_name(in->encoding), in->packed_center, in->packed_range, in->fine_half,
                     in->fine_spacing, sdf_normalize_name(in->normalize),
                     in->filtered ? "true" : "false", volume->channels,
                     in->encoding == SDF_ENCODING_PACKED32 ? "<u4" : "<f4",
                     sdf_volume_data_bytes(volume));
    if (n < 0 || (size_t)n >= cap)
        return SDF_ELIMIT;
    return n;
}
