/* field-bench.c - times each field operation (sdf_volume_apply_ops) on a 128^3 volume, by
 * both solvers, for docs/volumes.md's table beside the rounding paper's timings (its 128^3
 * grid, 10 steps of eq. (1)). The input is a cube with a cylindrical hole sampled as a
 * field that is not a distance (max of the max-norm box and the hole), over [-1, 1]^3.
 *
 * usage: field-bench [n (128)] [threads (2)] [r (0.1)] [repeats (3)]
 * Prints one line per operation and solver: the best wall time of the repeats. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "sdf/sdf.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static sdf_volume *holed_cube(size_t n)
{
    float *data = malloc(n * n * n * sizeof *data);
    if (!data)
        return NULL;
    double h = 2.0 / (double)(n - 1);
    for (size_t k = 0, at = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++, at++) {
                double x = -1 + (double)i * h, y = -1 + (double)j * h, z = -1 + (double)k * h;
                double box = fmax(fabs(x), fmax(fabs(y), fabs(z))) - 0.7;
                data[at] = (float)fmax(box, 0.25 - hypot(x, y));
            }
    sdf_volume_info info = {.dims = {n, n, n}, .origin = {-1, -1, -1}, .spacing = {h, h, h}};
    sdf_volume *v = NULL;
    sdf_diag diag;
    if (sdf_volume_create(&info, data, &v, &diag))
        fprintf(stderr, "field-bench: %s\n", diag.message);
    free(data);
    return v;
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? strtoul(argv[1], NULL, 10) : 128;
    int threads = argc > 2 ? atoi(argv[2]) : 2;
    double r = argc > 3 ? atof(argv[3]) : 0.1;
    int repeats = argc > 4 ? atoi(argv[4]) : 3;
    sdf_volume *in = holed_cube(n);
    if (!in || repeats < 1)
        return 1;
    const sdf_field_op ops[] = {
        {SDF_FIELD_REDISTANCE, (float)r}, {SDF_FIELD_REDISTANCE, 0}, {SDF_FIELD_OFFSET, (float)r},
        {SDF_FIELD_ROUND, (float)r},      {SDF_FIELD_FILLET, (float)r}, {SDF_FIELD_SMOOTH, (float)r},
    };
    printf("%zu^3 nodes, %d threads, r = %g (%.1f cells)\n", n, threads, r,
           r * (double)(n - 1) / 2);
    for (size_t o = 0; o < sizeof ops / sizeof ops[0]; o++)
        for (int s = 0; s < 3; s++) {
            sdf_field_options opts = {.solver = (sdf_field_solver)s, .threads = threads};
            double best = INFINITY;
            for (int rep = 0; rep < repeats; rep++) {
                sdf_volume *out = NULL;
                sdf_diag diag;
                double t0 = now();
                int rc = sdf_volume_apply_ops(in, &ops[o], 1, &opts, &out, NULL, &diag);
                double t = now() - t0;
                if (rc) {
                    fprintf(stderr, "field-bench: %s\n", diag.message);
                    return 1;
                }
                best = fmin(best, t);
                sdf_volume_destroy(out);
            }
            printf("%-10s r=%-5g %-8s %7.3f s\n", sdf_field_op_name(ops[o].kind),
                   (double)ops[o].r, sdf_field_solver_name(opts.solver), best);
        }
    sdf_volume_destroy(in);
    return 0;
}
