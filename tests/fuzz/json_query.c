/* json_query.c - fuzzes sdfd's JSON query body (server/transport/body.c's hand-written reader,
 * sdfd_parse_points), then the parameters it found as sdfd reads them: mode, sign and
 * interpolation names, and the "filter" object (server/ops/filterparams.c). */
#include "transport/body.h"
#include "ops/filterparams.h"
#include "fuzz.h"

#define MAX_POINTS 4096

/* A parameter's value as the C string sdfd makes of it (sdfd_http_param: 32 bytes). */
static const char *param(const char *value, size_t n, char buf[32])
{
    if (!value)
        return NULL;
    snprintf(buf, 32, "%.*s", (int)(n < 32 ? n : 31), value);
    return buf;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *body = fuzz_text(data, size);
    if (!body)
        return 0;
    sdfd_query_params params = {0};
    float *points = NULL;
    size_t count = 0;
    int owned = 0;
    char err[256];
    if (sdfd_parse_points(SDFD_FORM_JSON, body, size, MAX_POINTS, &params, &points, &count,
                          &owned, err, sizeof err)) {
        FUZZ_CHECK(memchr(err, 0, sizeof err) && !owned);
        free(body);
        return 0;
    }
    FUZZ_CHECK(count <= MAX_POINTS && owned);
    fuzz_touch_floats(points, 3 * count);
    free(points);
    char buf[32];
    sdf_proto_mode mode;
    sdf_sign_method sign;
    sdf_volume_filter interpolation;
    const char *m = param(params.mode, params.mode_len, buf);
    if (m)
        (void)sdf_proto_mode_from_name(m, &mode);
    const char *s = param(params.sign, params.sign_len, buf);
    if (s)
        (void)sdf_sign_from_name(s, &sign);
    const char *in = param(params.interpolation, params.interpolation_len, buf);
    if (in)
        (void)sdf_volume_filter_from_name(in, &interpolation);
    if (params.filter) {
        FUZZ_CHECK(params.filter >= body && params.filter + params.filter_len <= body + size);
        sdf_filter_options f;
        char volume_mesh[SDFD_VOLUME_NAME_MAX + 1];
        if (sdfd_filter_from_json(params.filter, params.filter_len, &f, volume_mesh, err,
                                  sizeof err))
            FUZZ_CHECK(memchr(err, 0, sizeof err));
    }
    free(body);
    return 0;
}
