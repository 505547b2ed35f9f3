/* sdf-bench - throughput of batched queries on one mesh, for side-by-side runs with the
 * peer (tests/bench/peer_bench.py) on the same points. Not a test: it asserts nothing.
 *
 *   sdf-bench MESH|demo [POINTS.npy] [--workload box|band|grid --n N --seed S]
 *             [--mode distance|signed|gradient|closest|filtered|filtered-gradient]
 *             [--samples N] [--min-samples N] [--sample-gradient 0|1]
 *             [--sign auto|pseudonormal|winding|raycast|none]
 *             [--threads N] [--repeat R] [--out OUT.npy] [--traversal packets|single]
 *             [--workspace 0|1] [--points-out POINTS.npy]
 *
 * Points come from POINTS.npy (float32 or float64, shape (N, 3)) or are generated
 * (--workload, default band, 1,000,000 points). The batch is timed R times (default 2) after
 * a warm-up, best run reported, like the peer script. --workspace 1 gives every call one
 * sdf_workspace, as sdfd's batcher does (the first timed call fills it; default 0: each call
 * allocates its own scratch). --out writes float32 results:
 * distance/signed (N,); gradient (N, 4) = distance, gradient xyz; closest (N, 4) = distance,
 * closest point xyz. --points-out writes the points queried as float32 (N, 3), so that other
 * programs (the clients' benches in server-compare.sh) can send exactly these points.
 * The last line printed is always `throughput: X Mq/s`. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/files.h"
#include "../common/npyio.h"
#include "../common/workload.h"
#include "sdf/sdf.h"

typedef struct args {
    const char *mesh, *points, *out, *points_out, *workload, *mode;
    size_t n;
    uint64_t seed;
    sdf_sign_method sign;
    sdf_traversal traversal;
    int threads, repeat, samples, min_samples, sample_gradient, workspace;
} args;

static void usage(void)
{
    fprintf(stderr,
            "usage: sdf-bench MESH|demo [POINTS.npy] [--workload box|band|grid] [--n N] [--seed S]\n"
            "                 [--mode distance|signed|gradient|closest|filtered|filtered-gradient]\n"
            "                 [--samples N (filtered: n, default 64)] [--min-samples N (adaptive)]\n"
            "                 [--sample-gradient 0|1 (filtered-gradient: the samples' mean)]\n"
            "                 [--sign auto|pseudonormal|winding|raycast|none]\n"
            "                 [--threads N] [--repeat R] [--out OUT.npy] [--traversal packets|single]\n"
            "                 [--workspace 0|1 (1: one sdf_workspace for every call, as sdfd)]\n"
            "                 [--points-out POINTS.npy (the points queried, float32 (N, 3))]\n");
    exit(2);
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static long parse_long(const char *s, const char *flag)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || v < 0) {
        fprintf(stderr, "sdf-bench: %s needs a non-negative integer, got '%s'\n", flag, s);
        exit(2);
    }
    return v;
}

static args parse_args(int argc, char **argv)
{
    args a = {.workload = "band", .mode = "signed", .n = 1000000, .seed = 7, .repeat = 2};
    for (int i = 1; i < argc; i++) {
        const char *s = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (s[0] != '-') {
            if (!a.mesh)
                a.mesh = s;
            else if (!a.points)
                a.points = s;
            else
                usage();
            continue;
        }
        if (!v)
            usage();
        i++;
        if (!strcmp(s, "--workload")) a.workload = v;
        else if (!strcmp(s, "--n")) a.n = (size_t)parse_long(v, s);
        else if (!strcmp(s, "--seed")) a.seed = (uint64_t)parse_long(v, s);
        else if (!strcmp(s, "--mode")) a.mode = v;
        else if (!strcmp(s, "--samples")) a.samples = (int)parse_long(v, s);
        else if (!strcmp(s, "--min-samples")) a.min_samples = (int)parse_long(v, s);
        else if (!strcmp(s, "--sample-gradient")) a.sample_gradient = parse_long(v, s) != 0;
        else if (!strcmp(s, "--threads")) a.threads = (int)parse_long(v, s);
        else if (!strcmp(s, "--repeat")) a.repeat = (int)parse_long(v, s);
        else if (!strcmp(s, "--out")) a.out = v;
        else if (!strcmp(s, "--points-out")) a.points_out = v;
        else if (!strcmp(s, "--workspace")) a.workspace = parse_long(v, s) != 0;
        else if (!strcmp(s, "--traversal")) {
            if (strcmp(v, "packets") && strcmp(v, "single")) {
                fprintf(stderr, "sdf-bench: --traversal packets|single\n");
                exit(2);
            }
            a.traversal = strcmp(v, "single") ? SDF_TRAVERSAL_PACKETS : SDF_TRAVERSAL_SINGLE;
        }
        else if (!strcmp(s, "--sign")) {
            if (sdf_sign_from_name(v, &a.sign)) {
                fprintf(stderr, "sdf-bench: unknown sign method '%s'\n", v);
                exit(2);
            }
        } else usage();
    }
    if (!a.mesh || a.repeat < 1)
        usage();
    if (strcmp(a.mode, "distance") && strcmp(a.mode, "signed") && strcmp(a.mode, "gradient") &&
        strcmp(a.mode, "closest") && strcmp(a.mode, "filtered") &&
        strcmp(a.mode, "filtered-gradient")) {
        fprintf(stderr, "sdf-bench: unknown mode '%s'\n", a.mode);
        exit(2);
    }
    if (!strcmp(a.mode, "distance"))
        a.sign = SDF_SIGN_NONE;
    return a;
}

/* The points as a float32 (N, 3) .npy, for the programs that must send the same ones. */
static void write_points(const char *path, const float *points, size_t n)
{
    FILE *f = fopen(path, "wb");
    char header[128];
    size_t shape[2] = {n, 3};
    long len = sdf_npy_write_header(header, sizeof header, 2, shape);
    if (!f || len < 0 || fwrite(header, 1, (size_t)len, f) != (size_t)len ||
        fwrite(points, 12, n, f) != n || fclose(f)) {
        fprintf(stderr, "sdf-bench: cannot write %s: %s\n", path, strerror(errno));
        exit(1);
    }
}

int main(int argc, char **argv)
{
    args a = parse_args(argc, argv);
    sdf_mesh *mesh = NULL;
    sdf_diag diag = {0};
    int rc = !strcmp(a.mesh, "demo") ? sdf_mesh_create_demo(&mesh)
                                     : sdf_mesh_load_file(a.mesh, NULL, &mesh, &diag);
    if (rc) {
        fprintf(stderr, "sdf-bench: %s: %s\n", a.mesh, rc && diag.code ? diag.message : sdf_strerror(rc));
        return 1;
    }
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    size_t n = a.n;
    float *points;
    if (a.points) {
        points = npy_load_points("sdf-bench", a.points, &n);
    } else {
        points = malloc((3 * n + 1) * sizeof *points);
        if (sdf_workload(mesh, a.workload, &n, a.seed, points)) {
            fprintf(stderr, "sdf-bench: unknown workload '%s'\n", a.workload);
            return 2;
        }
    }
    if (a.points_out)
        write_points(a.points_out, points, n);
    int filtered = !strncmp(a.mode, "filtered", 8);
    int gradient = !strcmp(a.mode, "gradient") || !strcmp(a.mode, "filtered-gradient");
    int closest = !strcmp(a.mode, "closest");
    float *dist = malloc((n + 1) * sizeof *dist);
    float *vec3 = gradient || closest ? malloc((3 * n + 1) * sizeof *vec3) : NULL;
    uint32_t *tri = closest ? malloc((n + 1) * sizeof *tri) : NULL;
    sdf_query_result out = {.distance = dist, .gradient = gradient ? vec3 : NULL,
                            .closest = closest ? vec3 : NULL, .triangle = tri};
    sdf_workspace *ws = NULL;
    if (a.workspace && sdf_workspace_create(&ws)) {
        fprintf(stderr, "sdf-bench: no memory for a workspace\n");
        return 1;
    }
    sdf_query_options opts = {.sign = a.sign, .threads = a.threads, .traversal = a.traversal,
                              .workspace = ws};
    printf("mesh: %s triangles: %zu vertices: %zu closed: %d manifold: %d flipped: %d "
           "auto sign: %s index: %.1f MB (%.1f B/triangle) build: %.3f s\n",
           a.mesh, r.triangles, r.vertices, r.closed, r.edge_manifold, r.flipped,
           sdf_sign_name(r.auto_sign), r.index_bytes / 1e6,
           r.triangles ? (double)r.index_bytes / (double)r.triangles : 0.0, r.build_seconds);
    printf("points: %zu source: %s mode: %s sign: %s threads: %d traversal: %s workspace: %d\n",
           n, a.points ? a.points : a.workload, a.mode,
           sdf_sign_name(a.sign == SDF_SIGN_AUTO ? r.auto_sign : a.sign), a.threads,
           a.traversal == SDF_TRAVERSAL_SINGLE ? "single" : "packets", a.workspace);
    sdf_filter_options filter = {.samples = a.samples, .min_samples = a.min_samples,
                                 .sample_gradient = a.sample_gradient};
    /* The mode's query: raw, or filtered (sdf_query_filtered, docs/filtered.md). */
#define RUN(count) (filtered ? sdf_query_filtered(mesh, points, (count), &opts, &filter, &out, &diag) \
                             : sdf_query(mesh, points, (count), &opts, &out))
    rc = RUN(n < 1000 ? n : 1000); /* warm-up */
    double best = 1e300;
    for (int i = 0; !rc && i < a.repeat; i++) {
        double t0 = now();
        rc = RUN(n);
        double t = now() - t0;
        best = t < best ? t : best;
    }
    if (rc) {
        fprintf(stderr, "sdf-bench: query failed: %s (point %zu) %s\n", sdf_strerror(rc),
                out.bad_index, filtered ? diag.message : "");
        return 1;
    }
    if (a.out)
        npy_write_results("sdf-bench", a.out, n, gradient || closest ? 4 : 1, dist, vec3);
    printf("seconds: %.4f\n", best);
    printf("throughput: %.4f Mq/s\n", (double)n / best / 1e6);
    free(points);
    free(dist);
    free(vec3);
    free(tri);
    sdf_workspace_destroy(ws);
    sdf_mesh_release(mesh);
    return 0;
}
