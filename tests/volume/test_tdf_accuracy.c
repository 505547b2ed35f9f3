/* test_tdf_accuracy.c - the TDF paper's accuracy table (sec. 5.2) on fandisk.off: the mesh
 * normalised to [-1, 1]^3, zero- and first-order volumes at 8^3 .. 128^3 resampled by
 * nearest neighbour at the 256^3 nodes, mean absolute error against the exact distances.
 * Asserts what the paper reports: first order is more accurate at every resolution, at
 * least 3x from 16^3 up, and packing (sec. 5.3) costs at most 30 % more error than float32.
 * Prints the table (docs/volumes.md has it for two meshes, from tests/bench/tdf-table). */
#include <stdio.h>

#include "../common/accuracy.h"
#include "../common/check.h"

int main(void)
{
    sdf_mesh *loaded = load_data_mesh("fandisk.off");
    sdf_mesh *mesh = loaded ? normalized_mesh(loaded) : NULL;
    CHECK(mesh != NULL, "normalising fandisk");
    if (!mesh)
        return check_finish("tdf_accuracy");
    const size_t dims[] = {8, 16, 32, 64, 128};
    accuracy_row rows[5];
    accuracy_grid grid;
    int rc = accuracy_grid_make(mesh, 256, 1, 0, 0, &grid);
    if (!rc)
        rc = accuracy_table(mesh, &grid, dims, 5, 0, 0, rows);
    accuracy_grid_free(&grid);
    CHECK(rc == 0, "accuracy table: %s", sdf_strerror(rc));
    printf("  dim   zero order   first order   packed    zero/first  packed/first\n");
    for (int r = 0; !rc && r < 5; r++) {
        const accuracy_row *w = &rows[r];
        printf("%5zu   %.6f     %.6f      %.6f  %6.2f      %5.3f\n", w->dim, w->zero, w->first,
               w->packed, w->zero / w->first, w->packed / w->first);
        CHECK(w->first < w->zero, "%zu^3: first order %g is not below zero order %g", w->dim,
              w->first, w->zero);
        if (w->dim >= 16)
            CHECK(w->zero >= 3 * w->first, "%zu^3: first order %g not 3x below zero order %g",
                  w->dim, w->first, w->zero);
        CHECK(w->packed <= 1.3 * w->first, "%zu^3: packed %g more than 30 %% above float32 %g",
              w->dim, w->packed, w->first);
    }
    sdf_mesh_release(mesh);
    sdf_mesh_release(loaded);
    return check_finish("tdf_accuracy");
}
