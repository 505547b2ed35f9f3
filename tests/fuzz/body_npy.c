/* body_npy.c - fuzzes sdfd's binary query bodies (server/transport/body.c): the same bytes as an
 * application/x-npy body and as an application/octet-stream body. An accepted body must
 * give at most max_points points, every coordinate readable, and as npy the file's numbers
 * wherever the header leaves them. */
#include "transport/body.h"
#include "fuzz.h"

#define MAX_POINTS 4096

/* The points of an accepted npy body are the file's numbers (float64 rounded to float). */
static void same_as_file(const uint8_t *data, size_t size, const float *points, size_t count)
{
    sdf_npy_info info;
    FUZZ_CHECK(!sdf_npy_parse(data, size, &info, NULL) && info.ndim >= 2);
    size_t n = 1; /* shape (..., 3): the leading dimensions are the points */
    for (int i = 0; i + 1 < info.ndim; i++)
        n *= info.shape[i];
    FUZZ_CHECK(n == count);
    for (size_t i = 0; i < 3 * count; i++) {
        float want;
        if (info.dtype == SDF_NPY_F32) {
            memcpy(&want, data + info.data_offset + 4 * i, 4);
        } else {
            double d;
            memcpy(&d, data + info.data_offset + 8 * i, 8);
            want = (float)d;
        }
        FUZZ_CHECK(!memcmp(&want, &points[i], sizeof want));
    }
}

static void parse(sdfd_form form, const uint8_t *data, size_t size)
{
    char *body = fuzz_text(data, size); /* malloc'd: aligned, as sdfd's body buffer */
    if (!body)
        return;
    sdfd_query_params params = {0};
    float *points = NULL;
    size_t count = 0;
    int owned = 0;
    char err[256];
    if (!sdfd_parse_points(form, body, size, MAX_POINTS, &params, &points, &count, &owned, err,
                           sizeof err)) {
        FUZZ_CHECK(count <= MAX_POINTS && (points || !count));
        fuzz_touch_floats(points, 3 * count);
        if (form == SDFD_FORM_NPY)
            same_as_file(data, size, points, count);
        if (owned)
            free(points);
    } else {
        FUZZ_CHECK(memchr(err, 0, sizeof err) && !owned);
    }
    free(body);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    parse(SDFD_FORM_NPY, data, size);
    parse(SDFD_FORM_OCTET, data, size);
    return 0;
}
