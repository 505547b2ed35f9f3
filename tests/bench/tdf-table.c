/* tdf-table - print the TDF paper's accuracy table (sec. 5.2) for a mesh file, as in
 * docs/volumes.md: tdf-table MESH [REFERENCE_DIM (256)] [MAX_DIM (128)] [THREADS (0 = all)]. */
#include <stdio.h>
#include <stdlib.h>

#include "../common/accuracy.h"

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: tdf-table MESH [REFERENCE_DIM] [MAX_DIM] [THREADS]\n");
        return 2;
    }
    size_t reference = argc > 2 ? strtoul(argv[2], NULL, 10) : 256;
    size_t max_dim = argc > 3 ? strtoul(argv[3], NULL, 10) : 128;
    int threads = argc > 4 ? atoi(argv[4]) : 0;
    sdf_mesh *loaded = NULL;
    sdf_diag diag;
    if (sdf_mesh_load_file(argv[1], NULL, &loaded, &diag)) {
        fprintf(stderr, "%s: %s\n", argv[1], diag.message);
        return 1;
    }
    sdf_mesh *mesh = normalized_mesh(loaded);
    size_t dims[8];
    int count = 0;
    for (size_t d = 8; d <= max_dim && count < 8; d *= 2)
        dims[count++] = d;
    accuracy_row rows[8];
    int rc = mesh ? accuracy_table(mesh, dims, count, reference, threads, 1, rows) : SDF_ENOMEM;
    if (rc) {
        fprintf(stderr, "%s\n", sdf_strerror(rc));
        return 1;
    }
    printf("| dim | zero order | first order | packed32 | zero / first | packed / first | "
           "first, gradient-normalised | bake 0th s | bake 1st s | 1st / 0th time |\n"
           "|---|---|---|---|---|---|---|---|---|---|\n");
    for (int r = 0; r < count; r++)
        printf("| %zu^3 | %.6f | %.6f | %.6f | %.2f | %.3f | %.6f | %.3f | %.3f | %.1f |\n",
               rows[r].dim, rows[r].zero, rows[r].first, rows[r].packed,
               rows[r].zero / rows[r].first, rows[r].packed / rows[r].first,
               rows[r].first_gradient, rows[r].zero_seconds, rows[r].first_seconds,
               rows[r].first_seconds / rows[r].zero_seconds);
    sdf_mesh_release(mesh);
    sdf_mesh_release(loaded);
    return 0;
}
