/* json_bake.c - fuzzes sdfd's bake request body (server/ops/bakeparams.c, sdfd_bake_from_json),
 * then hands what it accepts to the library's checks on the demo mesh as sdfd does before it
 * admits a bake (sdf_volume_plan, sdf_volume_bake_scratch): the plan only, never a bake. */
#include "ops/bakeparams.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdfd_bake_request req;
    sdfd_bake_names names;
    char err[256];
    if (sdfd_bake_from_json((const char *)data, size, &req, &names, err, sizeof err)) {
        FUZZ_CHECK(memchr(err, 0, sizeof err));
        return 0;
    }
    FUZZ_CHECK(memchr(names.volume, 0, sizeof names.volume));
    FUZZ_CHECK(memchr(names.smoothing_mesh, 0, sizeof names.smoothing_mesh));
    sdf_mesh *mesh = fuzz_demo_mesh();
    if (!mesh)
        return 0;
    sdf_bake_options *o = &req.options;
    if (req.filtered) {
        if (names.smoothing_mesh[0])
            req.filter.smooth.mesh = mesh;
        o->filter = &req.filter;
    }
    if (req.mesh_box) { /* as sdfd: the mesh's own box */
        sdf_mesh_report r;
        sdf_mesh_get_report(mesh, &r);
        for (int a = 0; a < 3; a++)
            o->lo[a] = r.bbox_min[a], o->hi[a] = r.bbox_max[a];
    }
    sdf_query_result none = {0};
    sdf_diag fdiag = {0}; /* a filtered bake's filter is checked as a query's (volumes.c) */
    if (req.filtered && sdf_query_filtered(mesh, NULL, 0, NULL, &req.filter, &none, &fdiag))
        FUZZ_CHECK(fdiag.message[0] && memchr(fdiag.message, 0, sizeof fdiag.message));
    sdf_volume_info planned;
    size_t scratch;
    sdf_diag diag = {0};
    if (!sdf_volume_plan(mesh, o, &planned, &diag))
        (void)sdf_volume_bake_scratch(mesh, o, &scratch, &diag);
    FUZZ_CHECK(memchr(diag.message, 0, sizeof diag.message));
    return 0;
}
