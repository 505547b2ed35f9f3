/* mesh.c - fuzzes the mesh parsers through sdf_mesh_load_memory, the way sdfd loads an
 * uploaded body. FUZZ_MESH_FORMAT (meson.build) forces one format per harness (mesh_obj,
 * mesh_ply, mesh_stl, mesh_off), or leaves the format to be sniffed (mesh_auto). A mesh that
 * loads is queried at two points, so the index and sign data built from odd meshes (all
 * degenerate, one triangle, huge coordinates) are exercised too. */
#include <math.h>

#include "fuzz.h"
#include "sdf/sdf.h"

#ifndef FUZZ_MESH_FORMAT
#define FUZZ_MESH_FORMAT SDF_FORMAT_AUTO
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sdf_mesh_options opts = {.format = FUZZ_MESH_FORMAT};
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_load_memory(data, size, &opts, &mesh, &diag);
    if (rc) {
        FUZZ_CHECK(!mesh && diag.code == rc && memchr(diag.message, 0, sizeof diag.message));
        return 0;
    }
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    FUZZ_CHECK(r.vertices <= r.input_vertices && r.triangles > 0);
    FUZZ_CHECK(FUZZ_MESH_FORMAT == SDF_FORMAT_AUTO || r.format == FUZZ_MESH_FORMAT);
    float points[6];
    for (int a = 0; a < 3; a++) {
        points[a] = 0.5f * (r.bbox_min[a] + r.bbox_max[a]);
        points[3 + a] = r.bbox_max[a] + 1.0f;
    }
    float distance[2], closest[6];
    uint32_t triangle[2];
    sdf_query_options qo = {.threads = 1};
    sdf_query_result out = {.distance = distance, .closest = closest, .triangle = triangle};
    if (!sdf_query(mesh, points, 2, &qo, &out))
        for (int i = 0; i < 2; i++)
            FUZZ_CHECK(!isnan(distance[i]) && triangle[i] < r.triangles);
    sdf_mesh_release(mesh);
    return 0;
}
