/* test_tdf_accuracy.c - the TDF paper's accuracy table (sec. 5.2) on fandisk.off: the mesh
 * normalised to [-1, 1]^3, zero- and first-order volumes at 8^3 .. 128^3 resampled by
 * nearest neighbour at the 256^3 nodes, mean absolute error against the exact distances.
 * Asserts what the paper reports: first order is more accurate at every resolution, at
 * least 3x from 16^3 up, and packing (sec. 5.3) costs at most 30 % more error than float32.
 * Then the reconstructions at 32^3 (docs/volumes.md "Evaluation"): the default for first
 * order, hermite, has less than half the mean error of zero-order trilinear, and a smaller
 * mean gradient angle.
 * Prints the tables (docs/volumes.md has them for three meshes, from tests/bench/tdf-table). */
#include <stdio.h>

#include "../common/accuracy.h"
#include "../common/check.h"

static void test_fandisk(void)
{
    sdf_mesh *loaded = load_data_mesh("fandisk.off");
    sdf_mesh *mesh = loaded ? normalized_mesh(loaded) : NULL;
    CHECK(mesh != NULL, "normalising fandisk");
    if (!mesh)
        return;
    const size_t dims[] = {8, 16, 32, 64, 128};
    accuracy_row rows[5];
    accuracy_grid grid;
    int rc = accuracy_grid_make(mesh, 256, 1, 0, 1, &grid);
    if (!rc)
        rc = accuracy_table(mesh, &grid, dims, 5, 0, 0, rows);
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
    const size_t dim32 = 32;
    filter_row f;
    if (!rc)
        rc = filter_table(mesh, &grid, &dim32, 1, 0, &f);
    CHECK(rc == 0, "filter table: %s", sdf_strerror(rc));
    if (!rc) {
        const accuracy_error *zero = &f.e[FILTER_ZERO_TRILINEAR], *h = &f.e[FILTER_FIRST_HERMITE];
        printf("32^3: zero order trilinear mean %.6f angle %.3f; first order hermite mean %.6f "
               "angle %.3f\n", zero->mean, zero->angle, h->mean, h->angle);
        CHECK(h->mean < 0.5 * zero->mean, "hermite %g is not below half of trilinear %g",
              h->mean, zero->mean);
        CHECK(h->angle < zero->angle, "hermite's gradient angle %g is not below trilinear's %g",
              h->angle, zero->angle);
    }
    accuracy_grid_free(&grid);
    sdf_mesh_release(mesh);
    sdf_mesh_release(loaded);
}

static const check_case cases[] = {
    {"fandisk", test_fandisk},
};

int main(int argc, char **argv)
{
    return check_main("tdf_accuracy", cases, CHECK_COUNT_OF(cases), argc, argv);
}
