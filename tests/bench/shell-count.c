/* shell-count - how many triangles can be the closest to some fine sample of a first-order
 * node (docs/performance.md, "Volumes"): for random nodes of a DIM^3 grid over the default
 * bake bounds, brute force (every triangle, double precision) counts the triangles within
 * |f(x_i)| + 2 rho of the node, rho = 0.1 x the cell diagonal (H = 1, Delta = 0.1).
 *   shell-count MESH [DIM (128)] [NODES (300)] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "../common/reference.h"
#include "../common/workload.h"

static int by_size(const void *a, const void *b)
{
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: shell-count MESH [DIM] [NODES]\n");
        return 2;
    }
    int dim = argc > 2 ? atoi(argv[2]) : 128, count = argc > 3 ? atoi(argv[3]) : 300;
    sdf_mesh *mesh = NULL;
    if (sdf_mesh_load_file(argv[1], NULL, &mesh, NULL) || dim < 2 || count < 1)
        return 1;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    const float *v = sdf_mesh_vertices(mesh);
    const uint32_t *t = sdf_mesh_triangles(mesh);
    double lo[3], step[3], margin = 0.05 * r.diagonal;
    for (int a = 0; a < 3; a++) {
        lo[a] = r.bbox_min[a] - margin;
        step[a] = (r.bbox_max[a] - r.bbox_min[a] + 2 * margin) / (dim - 1);
    }
    double rho = 0.1 * sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]);
    size_t *within = malloc((size_t)count * sizeof *within);
    double *d = malloc(r.triangles * sizeof *d);
    sdf_rng rng = {1};
    for (int k = 0; k < count; k++) {
        double p[3], best = INFINITY;
        for (int a = 0; a < 3; a++)
            p[a] = lo[a] + floor(sdf_rng_uniform(&rng) * dim) * step[a];
        for (size_t i = 0; i < r.triangles; i++) {
            double c[3][3], closest[3];
            for (int q = 0; q < 3; q++)
                for (int a = 0; a < 3; a++)
                    c[q][a] = v[3 * (size_t)t[3 * i + q] + a];
            d[i] = ref_point_triangle(p, c[0], c[1], c[2], closest);
            best = fmin(best, d[i]);
        }
        within[k] = 0;
        for (size_t i = 0; i < r.triangles; i++)
            within[k] += d[i] <= best + 2 * rho;
    }
    qsort(within, (size_t)count, sizeof *within, by_size);
    double mean = 0;
    for (int k = 0; k < count; k++)
        mean += (double)within[k] / count;
    printf("triangles within |f| + 2 rho of a node: median %zu, p90 %zu, max %zu, mean %.1f\n",
           within[count / 2], within[count * 9 / 10], within[count - 1], mean);
    free(within), free(d);
    sdf_mesh_release(mesh);
    return 0;
}
