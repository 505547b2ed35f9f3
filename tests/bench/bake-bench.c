/* bake-bench - time volume bakes of a mesh: bake-bench MESH DIM [THREADS (0 = all)]
 * [normalize] [fine=H,DELTA] [repeat=N] [order=0|1]. Bakes DIM^3 zero-order, then first-order
 * (float32; fitting grids of (2H + 1)^3 samples DELTA cells apart, default 1,0.1), or only
 * the order that order= names (to profile one), over the default bounds (or [-1, 1]^3 around
 * the mesh normalised to it), each N times (default 1) keeping the fastest, and prints
 * seconds, nodes per second (first order: also fine samples per second) and, with both
 * orders, the first/zero time ratio, one JSON object per line (tests/bench/bake-compare.sh). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/accuracy.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: bake-bench MESH DIM [THREADS] [normalize] [fine=H,DELTA] "
                        "[repeat=N] [order=0|1]\n");
        return 2;
    }
    size_t dim = strtoul(argv[2], NULL, 10);
    int threads = argc > 3 ? atoi(argv[3]) : 0;
    int normalize = 0, fine_half = 1, repeat = 1, only_order = -1;
    double fine_spacing = 0.1;
    for (int i = 4; i < argc; i++) {
        if (!strcmp(argv[i], "normalize")) {
            normalize = 1;
        } else if (sscanf(argv[i], "repeat=%d", &repeat) == 1) {
            if (repeat < 1) {
                fprintf(stderr, "bake-bench: repeat must be >= 1\n");
                return 2;
            }
        } else if (sscanf(argv[i], "order=%d", &only_order) == 1) {
            if (only_order != 0 && only_order != 1) {
                fprintf(stderr, "bake-bench: order must be 0 or 1\n");
                return 2;
            }
        } else if (sscanf(argv[i], "fine=%d,%lf", &fine_half, &fine_spacing) != 2) {
            fprintf(stderr, "bake-bench: unknown argument %s\n", argv[i]);
            return 2;
        }
    }
    sdf_mesh *mesh = NULL;
    sdf_diag diag;
    if (sdf_mesh_load_file(argv[1], NULL, &mesh, &diag)) {
        fprintf(stderr, "%s: %s\n", argv[1], diag.message);
        return 1;
    }
    if (normalize) {
        sdf_mesh *n = normalized_mesh(mesh);
        sdf_mesh_release(mesh);
        mesh = n;
    }
    sdf_bake_options o = {.dims = {dim, dim, dim}, .query.threads = threads,
                          .fine_half = fine_half, .fine_spacing = fine_spacing};
    if (normalize)
        for (int a = 0; a < 3; a++)
            o.lo[a] = -1, o.hi[a] = 1;
    double seconds[2];
    for (int order = 0; order < 2; order++) {
        if (only_order >= 0 && order != only_order)
            continue;
        o.order = order;
        seconds[order] = INFINITY;
        for (int r = 0; r < repeat; r++) {
            sdf_volume *v = NULL;
            double t0 = now();
            if (sdf_volume_bake(mesh, &o, &v, &diag)) {
                fprintf(stderr, "bake: %s\n", diag.message);
                return 1;
            }
            double took = now() - t0;
            seconds[order] = took < seconds[order] ? took : seconds[order];
            sdf_volume_destroy(v);
        }
        double nodes = (double)dim * (double)dim * (double)dim;
        double side = order ? 2.0 * fine_half + 1 : 1;
        printf("{\"order\": %d, \"dim\": %zu, \"seconds\": %.4f, \"nodes_per_second\": %.0f, "
               "\"samples_per_second\": %.0f}\n", order, dim, seconds[order],
               nodes / seconds[order], nodes * side * side * side / seconds[order]);
    }
    if (only_order < 0)
        printf("{\"first_over_zero\": %.2f}\n", seconds[1] / seconds[0]);
    sdf_mesh_release(mesh);
    return 0;
}
