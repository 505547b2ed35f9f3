/* tdf-table - print the accuracy tables of docs/volumes.md for a mesh file (the TDF paper's
 * experiment, sec. 5.2: the mesh scaled into [-half, half]^3, volumes over that cube, errors
 * at the nodes of a REFERENCE_DIM^3 grid against exact signed distances):
 *   tdf-table MESH [REFERENCE_DIM (256)] [MAX_DIM (128)] [THREADS (0 = all)]
 *             [--half H (1)] [--filters]
 * By default the paper's table (nearest-neighbour resampling, 8^3 .. MAX_DIM^3); --filters
 * prints every reconstruction instead (zero order nearest and trilinear; first order
 * nearest, trilinear and hermite; packed32 first order hermite; 16^3 .. MAX_DIM^3): each
 * one's mean / max absolute error, hermite's mean error over zero-order trilinear's, and the
 * mean angle in degrees between the reconstructed and the exact gradient. --half 0.5
 * measures over a cube of side 1. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/accuracy.h"

static void print_paper(const accuracy_row *rows, int count)
{
    printf("| dim | zero order | first order | packed32 | zero / first | packed / first | "
           "first, gradient-normalised | bake 0th s | bake 1st s | 1st / 0th time |\n"
           "|---|---|---|---|---|---|---|---|---|---|\n");
    for (int r = 0; r < count; r++)
        printf("| %zu^3 | %.6f | %.6f | %.6f | %.2f | %.3f | %.6f | %.3f | %.3f | %.1f |\n",
               rows[r].dim, rows[r].zero, rows[r].first, rows[r].packed,
               rows[r].zero / rows[r].first, rows[r].packed / rows[r].first,
               rows[r].first_gradient, rows[r].zero_seconds, rows[r].first_seconds,
               rows[r].first_seconds / rows[r].zero_seconds);
}

static void print_filters(const filter_row *rows, int count)
{
    printf("| dim | 0th nearest | 0th trilinear | 1st nearest | 1st trilinear | 1st hermite | "
           "packed32 hermite | hermite / 0th trilinear | angle 0th trilinear | "
           "angle 1st trilinear | angle 1st hermite |\n"
           "|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int r = 0; r < count; r++) {
        const accuracy_error *e = rows[r].e;
        printf("| %zu^3 |", rows[r].dim);
        for (int c = 0; c < FILTER_COLUMNS; c++)
            printf(" %.6f / %.4f |", e[c].mean, e[c].max);
        printf(" %.3f | %.2f | %.2f | %.2f |\n",
               e[FILTER_FIRST_HERMITE].mean / e[FILTER_ZERO_TRILINEAR].mean,
               e[FILTER_ZERO_TRILINEAR].angle, e[FILTER_FIRST_TRILINEAR].angle,
               e[FILTER_FIRST_HERMITE].angle);
    }
}

int main(int argc, char **argv)
{
    const char *positional[4] = {NULL, NULL, NULL, NULL};
    int npos = 0, filters = 0;
    double half = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--filters"))
            filters = 1;
        else if (!strcmp(argv[i], "--half") && i + 1 < argc)
            half = strtod(argv[++i], NULL);
        else if (argv[i][0] != '-' && npos < 4)
            positional[npos++] = argv[i];
        else
            npos = -100;
    }
    if (npos < 1 || !(half > 0)) {
        fprintf(stderr, "usage: tdf-table MESH [REFERENCE_DIM] [MAX_DIM] [THREADS] "
                        "[--half H] [--filters]\n");
        return 2;
    }
    size_t reference = npos > 1 ? strtoul(positional[1], NULL, 10) : 256;
    size_t max_dim = npos > 2 ? strtoul(positional[2], NULL, 10) : 128;
    int threads = npos > 3 ? atoi(positional[3]) : 0;
    sdf_mesh *loaded = NULL;
    sdf_diag diag;
    if (sdf_mesh_load_file(positional[0], NULL, &loaded, &diag)) {
        fprintf(stderr, "%s: %s\n", positional[0], diag.message);
        return 1;
    }
    sdf_mesh *mesh = scaled_mesh(loaded, half);
    size_t dims[8];
    int count = 0;
    for (size_t d = filters ? 16 : 8; d <= max_dim && count < 8; d *= 2)
        dims[count++] = d;
    accuracy_grid grid;
    int rc = mesh ? accuracy_grid_make(mesh, reference, half, threads, filters, &grid)
                  : SDF_ENOMEM;
    accuracy_row rows[8];
    filter_row frows[8];
    if (!rc)
        rc = filters ? filter_table(mesh, &grid, dims, count, threads, frows)
                     : accuracy_table(mesh, &grid, dims, count, threads, 1, rows);
    if (rc) {
        fprintf(stderr, "%s\n", sdf_strerror(rc));
        return 1;
    }
    if (filters)
        print_filters(frows, count);
    else
        print_paper(rows, count);
    accuracy_grid_free(&grid);
    sdf_mesh_release(mesh);
    sdf_mesh_release(loaded);
    return 0;
}
