/* npy.c - fuzzes libsdf's .npy reader (sdf_npy_parse), which sdf-bench, the volume files and
 * sdfd's npy bodies rely on: a header it accepts must describe exactly the bytes that follow. */
#include "fuzz.h"
#include "sdf/sdf.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdf_npy_info info;
    sdf_diag diag;
    if (sdf_npy_parse(data, size, &info, &diag))
        return 0;
    FUZZ_CHECK(info.ndim >= 0 && info.ndim <= SDF_NPY_MAX_DIMS); /* 0: a scalar, shape () */
    FUZZ_CHECK(info.dtype == SDF_NPY_F32 || info.dtype == SDF_NPY_F64);
    size_t elements = 1;
    for (int d = 0; d < info.ndim; d++)
        elements *= info.shape[d];
    FUZZ_CHECK(info.data_bytes == elements * (size_t)info.dtype);
    FUZZ_CHECK(info.data_offset <= size && info.data_bytes == size - info.data_offset);
    fuzz_touch(data + info.data_offset, info.data_bytes);
    return 0;
}
