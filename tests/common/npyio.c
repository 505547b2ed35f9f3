/* npyio.c - see npyio.h. */
#include "npyio.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "files.h"
#include "sdf/sdf.h"

float *npy_load_points(const char *tool, const char *path, size_t *n)
{
    size_t size;
    unsigned char *data = (unsigned char *)read_whole_file(path, &size);
    if (!data) {
        fprintf(stderr, "%s: cannot read %s: %s\n", tool, path, strerror(errno));
        exit(1);
    }
    sdf_npy_info info;
    sdf_diag diag;
    if (sdf_npy_parse(data, size, &info, &diag)) {
        fprintf(stderr, "%s: %s: %s\n", tool, path, diag.message);
        exit(1);
    }
    if (info.ndim != 2 || info.shape[1] != 3) {
        fprintf(stderr, "%s: %s: expected shape (N, 3)\n", tool, path);
        exit(1);
    }
    *n = info.shape[0];
    float *p = malloc((3 * *n + 1) * sizeof *p);
    for (size_t i = 0; i < 3 * *n; i++) {
        if (info.dtype == SDF_NPY_F32)
            memcpy(&p[i], data + info.data_offset + 4 * i, 4);
        else {
            double d;
            memcpy(&d, data + info.data_offset + 8 * i, 8);
            p[i] = (float)d;
        }
    }
    free(data);
    return p;
}

void npy_write_results(const char *tool, const char *path, size_t n, int cols, const float *dist,
                       const float *vec3)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "%s: cannot write %s: %s\n", tool, path, strerror(errno));
        exit(1);
    }
    char header[128];
    size_t shape[2] = {n, (size_t)cols};
    long len = sdf_npy_write_header(header, sizeof header, cols == 1 ? 1 : 2, shape);
    fwrite(header, 1, (size_t)len, f);
    for (size_t i = 0; i < n; i++) {
        fwrite(&dist[i], 4, 1, f);
        if (cols == 4)
            fwrite(&vec3[3 * i], 4, 3, f);
    }
    fclose(f);
}

