/* json_filter.c - fuzzes the "filter" object of sdfd's JSON query bodies
 * (server/ops/filterparams.c, sdfd_filter_from_json), then hands what it accepts to the
 * library's checks (sdf_query_filtered with no points, as sdfd_filter_validate does), with
 * the demo mesh standing in for a named smoothing mesh. */
#include "ops/filterparams.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdf_filter_options f;
    char volume_mesh[SDFD_VOLUME_NAME_MAX + 1], err[256];
    if (sdfd_filter_from_json((const char *)data, size, &f, volume_mesh, err, sizeof err)) {
        FUZZ_CHECK(memchr(err, 0, sizeof err));
        return 0;
    }
    FUZZ_CHECK(memchr(volume_mesh, 0, sizeof volume_mesh));
    sdf_mesh *mesh = fuzz_demo_mesh();
    if (!mesh)
        return 0;
    if (volume_mesh[0])
        f.smooth.mesh = mesh;
    sdf_query_result none = {0};
    sdf_diag diag = {0};
    if (sdf_query_filtered(mesh, NULL, 0, NULL, &f, &none, &diag))
        FUZZ_CHECK(diag.message[0] && memchr(diag.message, 0, sizeof diag.message));
    return 0;
}
