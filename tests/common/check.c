/* check.c - counters and helpers behind check.h. */
#include "check.h"

_Atomic int check_failures;
_Atomic int check_count;

int check_finish(const char *name)
{
    printf("%s: %d checks, %d failed\n", name, (int)check_count, (int)check_failures);
    return check_failures ? 1 : 0;
}

const char *data_path(const char *file)
{
    static char path[4096];
    snprintf(path, sizeof path, "%s/%s", SDF_TEST_DATA, file);
    return path;
}

sdf_mesh *load_data_mesh(const char *file)
{
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    int rc = sdf_mesh_load_file(data_path(file), NULL, &mesh, &diag);
    CHECK(rc == 0, "%s: %s", file, diag.message);
    return rc ? NULL : mesh;
}
