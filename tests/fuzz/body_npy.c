/* body_npy.c - fuzzes sdfd's binary query bodies (server/body.c): the same bytes as an
 * application/x-npy body and as an application/octet-stream body. An accepted body must
 * give at most max_points points, every coordinate readable. */
#include "body.h"
#include "fuzz.h"

#define MAX_POINTS 4096

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
        (void)fuzz_touch_floats(points, 3 * count);
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
