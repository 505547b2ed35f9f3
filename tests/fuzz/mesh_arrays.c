/* mesh_arrays.c - fuzzes meshes uploaded as arrays (server/ops/mesharrays.c and the npz
 * reader server/ops/npz.c): the same bytes as a JSON body and as an npz. An accepted body
 * must give a binary PLY of at most MAX_TRIANGLES triangles that the library reads back to a
 * mesh of that many triangles; a refused one a message. */
#include "ops/mesharrays.h"
#include "fuzz.h"

#define MAX_TRIANGLES 4096

static void parse(sdfd_mesh_body kind, const uint8_t *data, size_t size)
{
    char *body = fuzz_text(data, size); /* NUL-terminated, as sdfd's body buffer */
    if (!body)
        return;
    void *ply = NULL;
    size_t len = 0;
    char err[256];
    if (sdfd_mesh_arrays_to_ply(kind, body, size, MAX_TRIANGLES, &ply, &len, err, sizeof err)) {
        FUZZ_CHECK(!ply && err[0] && memchr(err, 0, sizeof err));
    } else {
        FUZZ_CHECK(ply && len > 10 && !memcmp(ply, "ply\n", 4));
        sdf_mesh_options o = {.format = SDF_FORMAT_PLY, .max_triangles = MAX_TRIANGLES};
        sdf_mesh *mesh = NULL;
        sdf_mesh_report r;
        /* no index is built for meshes the library refuses (a degenerate one is kept) */
        if (!sdf_mesh_load_memory(ply, len, &o, &mesh, NULL)) {
            sdf_mesh_get_report(mesh, &r);
            FUZZ_CHECK(r.triangles <= MAX_TRIANGLES);
            sdf_mesh_release(mesh);
        }
    }
    free(ply);
    free(body);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    parse(SDFD_MESH_BODY_JSON, data, size);
    parse(SDFD_MESH_BODY_NPZ, data, size);
    return 0;
}
