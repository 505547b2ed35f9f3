/* exr.c - fuzzes the EXR volume reader (sdf_volume_load_exr_memory), which takes volume
 * files from users (sdf-volume eval, docs/volumes.md). A volume it accepts is evaluated at
 * its centre and outside its corner, with gradients: the description it checked must be
 * one the lookups can use. */
#include <math.h>

#include "fuzz.h"
#include "sdf/sdf.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdf_volume *v = NULL;
    sdf_diag diag;
    int rc = sdf_volume_load_exr_memory(data, size, &v, &diag);
    if (rc) {
        FUZZ_CHECK(!v && memchr(diag.message, 0, sizeof diag.message));
        return 0;
    }
    sdf_volume_info info;
    sdf_volume_get_info(v, &info);
    FUZZ_CHECK(sdf_volume_data_bytes(v) ==
               info.dims[0] * info.dims[1] * info.dims[2] * 4 * (size_t)sdf_volume_channels(&info));
    fuzz_touch(sdf_volume_data(v), sdf_volume_data_bytes(v));
    double q[6];
    int in_float = 1; /* a double beyond float's range has no float value (C11 6.3.1.5) */
    for (int a = 0; a < 3; a++) {
        q[a] = info.origin[a] + 0.5 * info.spacing[a] * (double)(info.dims[a] - 1);
        q[3 + a] = info.origin[a] - info.spacing[a];
    }
    float p[6];
    for (int i = 0; i < 6; i++)
        if (!(fabs(q[i]) < 1e38))
            in_float = 0;
        else
            p[i] = (float)q[i];
    float value[2], gradient[6];
    size_t bad;
    for (int f = 0; f < 2 && in_float; f++)
        (void)sdf_volume_eval(v, p, 2, (sdf_volume_filter)f, value, gradient, &bad);
    char json[1024];
    FUZZ_CHECK(sdf_volume_describe_json(v, json, sizeof json) > 0);
    sdf_volume_destroy(v);
    return 0;
}
