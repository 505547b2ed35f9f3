/* test_workspace.c - sdf_workspace (lib/core/workspace.c): calls given a workspace answer
 * exactly as calls without one, while the workspace keeps their arrays between calls.
 *  - sdf_query (distance, gradient, closest point, triangle), sdf_winding_numbers and
 *    sdf_query_filtered (value and gradient) on fandisk, batches large enough for huge-page
 *    arrays and small ones in turn, compared bit for bit with the same calls without one;
 *  - the workspace grows only for a larger batch: a batch no larger than one it served before
 *    leaves sdf_workspace_bytes as it was;
 *  - a lattice, which the scan answers (scan/scan.c), keeps its per-node bests there too;
 *  - two threads sharing one workspace (one of them runs without it) and a bake given one
 *    (which ignores it) still answer as without;
 *  - the argument rules: NULL out, NULL workspace. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "../common/workload.h"

#define MOST 300000 /* visit-order copies of 3.6 MB: on huge pages (core/bigmem.h) */

static int same_floats(const float *a, const float *b, size_t n)
{
    return memcmp(a, b, n * sizeof *a) == 0;
}

/* Outputs of one raw query: distance, gradient, closest point, triangle. */
typedef struct answers {
    float *distance, *gradient, *closest;
    uint32_t *triangle;
} answers;

static int answers_alloc(answers *a, size_t n)
{
    a->distance = malloc((n + 1) * sizeof(float));
    a->gradient = malloc((3 * n + 1) * sizeof(float));
    a->closest = malloc((3 * n + 1) * sizeof(float));
    a->triangle = malloc((n + 1) * sizeof(uint32_t));
    return a->distance && a->gradient && a->closest && a->triangle;
}

static void answers_free(answers *a)
{
    free(a->distance), free(a->gradient), free(a->closest), free(a->triangle);
}

static int query(const sdf_mesh *mesh, const float *points, size_t n, sdf_workspace *ws,
                 answers *a)
{
    sdf_query_options o = {.threads = 2, .workspace = ws};
    sdf_query_result r = {.distance = a->distance, .gradient = a->gradient,
                          .closest = a->closest, .triangle = a->triangle};
    return sdf_query(mesh, points, n, &o, &r);
}

static int same_answers(const answers *a, const answers *b, size_t n)
{
    return same_floats(a->distance, b->distance, n) &&
           same_floats(a->gradient, b->gradient, 3 * n) &&
           same_floats(a->closest, b->closest, 3 * n) &&
           memcmp(a->triangle, b->triangle, n * sizeof(uint32_t)) == 0;
}

/* Raw queries and winding numbers over batches of changing size, with and without ws. */
static void check_raw(const sdf_mesh *mesh, const float *points, sdf_workspace *ws)
{
    const size_t sizes[] = {MOST, 1000, 0, 1, MOST / 2, MOST};
    answers want = {0}, got = {0};
    float *wind_want = malloc((MOST + 1) * sizeof(float));
    float *wind_got = malloc((MOST + 1) * sizeof(float));
    CHECK(answers_alloc(&want, MOST) && answers_alloc(&got, MOST) && wind_want && wind_got,
          "memory");
    size_t largest = 0, held = 0;
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; i++) {
        size_t n = sizes[i];
        int rc_want = query(mesh, points, n, NULL, &want);
        int rc_got = query(mesh, points, n, ws, &got);
        CHECK(rc_want == 0 && rc_got == 0, "%zu points: rc %d / %d", n, rc_want, rc_got);
        CHECK(same_answers(&want, &got, n), "%zu points: answers differ with a workspace", n);
        sdf_query_options plain = {.threads = 2}, with_ws = {.threads = 2, .workspace = ws};
        rc_want = sdf_winding_numbers(mesh, points, n, &plain, wind_want, NULL);
        rc_got = sdf_winding_numbers(mesh, points, n, &with_ws, wind_got, NULL);
        CHECK(rc_want == 0 && rc_got == 0 && same_floats(wind_want, wind_got, n),
              "%zu points: winding numbers differ with a workspace", n);
        size_t now = sdf_workspace_bytes(ws);
        if (n <= largest)
            CHECK(now == held, "%zu points after %zu: held %zu -> %zu bytes", n, largest, held,
                  now);
        else
            CHECK(now >= 12 * n, "%zu points: holds only %zu bytes", n, now);
        largest = n > largest ? n : largest, held = now;
    }
    answers_free(&want), answers_free(&got);
    free(wind_want), free(wind_got);
}

/* The filtered field (value and gradient, adaptive too) with and without ws. */
static void check_filtered(const sdf_mesh *mesh, const float *points, sdf_workspace *ws)
{
    const size_t n = 20000;
    float *f_want = malloc(n * sizeof(float)), *f_got = malloc(n * sizeof(float));
    float *g_want = malloc(3 * n * sizeof(float)), *g_got = malloc(3 * n * sizeof(float));
    CHECK(f_want && f_got && g_want && g_got, "memory");
    sdf_filter_options filters[2] = {{.samples = 16}, {.samples = 32, .min_samples = 8}};
    for (int k = 0; k < 2; k++) {
        sdf_query_options plain = {.threads = 2}, with_ws = {.threads = 2, .workspace = ws};
        sdf_query_result want = {.distance = f_want, .gradient = g_want};
        sdf_query_result got = {.distance = f_got, .gradient = g_got};
        sdf_diag diag;
        int rc_want = sdf_query_filtered(mesh, points, n, &plain, &filters[k], &want, &diag);
        int rc_got = sdf_query_filtered(mesh, points, n, &with_ws, &filters[k], &got, &diag);
        CHECK(rc_want == 0 && rc_got == 0, "filter %d: rc %d / %d", k, rc_want, rc_got);
        CHECK(same_floats(f_want, f_got, n) && same_floats(g_want, g_got, 3 * n),
              "filter %d: values differ with a workspace", k);
    }
    free(f_want), free(f_got), free(g_want), free(g_got);
}

/* A 64^3 lattice: the scan's per-worker bests come from the workspace. */
static void check_lattice(const sdf_mesh *mesh, sdf_workspace *ws)
{
    size_t n = 64 * 64 * 64;
    float *grid = malloc(3 * n * sizeof *grid);
    answers want = {0}, got = {0};
    CHECK(grid && answers_alloc(&want, n) && answers_alloc(&got, n), "memory");
    CHECK(sdf_workload(mesh, "grid", &n, 1, grid) == 0 && n == 64 * 64 * 64, "grid");
    size_t before = sdf_workspace_bytes(ws);
    for (int round = 0; round < 2; round++) {
        CHECK(query(mesh, grid, n, NULL, &want) == 0 && query(mesh, grid, n, ws, &got) == 0,
              "lattice queries");
        CHECK(same_answers(&want, &got, n), "round %d: a lattice's answers differ with a "
              "workspace", round);
    }
    /* One 16-byte best per node for each of at least one worker. */
    CHECK(sdf_workspace_bytes(ws) >= before + 16 * n, "the lattice left %zu -> %zu bytes",
          before, sdf_workspace_bytes(ws));
    answers_free(&want), answers_free(&got);
    free(grid);
}

typedef struct sharer {
    const sdf_mesh *mesh;
    const float *points;
    size_t n;
    sdf_workspace *ws;
    const answers *want;
    int mismatches;
} sharer;

static void *share(void *arg)
{
    sharer *s = arg;
    answers got = {0};
    if (!answers_alloc(&got, s->n)) {
        s->mismatches = -1;
        answers_free(&got);
        return NULL;
    }
    for (int round = 0; round < 4; round++)
        if (query(s->mesh, s->points, s->n, s->ws, &got) || !same_answers(s->want, &got, s->n))
            s->mismatches++;
    answers_free(&got);
    return NULL;
}

/* Two threads, one workspace: whichever finds it in use runs without it. */
static void check_shared(const sdf_mesh *mesh, const float *points, sdf_workspace *ws)
{
    size_t n = MOST / 2;
    answers want[2] = {{0}};
    CHECK(answers_alloc(&want[0], n) && answers_alloc(&want[1], n), "memory");
    const float *at[2] = {points, points + 3 * (MOST - n)}; /* different points each */
    for (int t = 0; t < 2; t++)
        CHECK(query(mesh, at[t], n, NULL, &want[t]) == 0, "thread %d's reference", t);
    sharer s[2];
    pthread_t thread[2];
    for (int t = 0; t < 2; t++) {
        s[t] = (sharer){mesh, at[t], n, ws, &want[t], 0};
        CHECK(pthread_create(&thread[t], NULL, share, &s[t]) == 0, "thread %d", t);
    }
    for (int t = 0; t < 2; t++) {
        pthread_join(thread[t], NULL);
        CHECK(s[t].mismatches == 0, "thread %d: %d of 4 calls differ", t, s[t].mismatches);
    }
    answers_free(&want[0]), answers_free(&want[1]);
}

/* A bake given a workspace bakes as without one and leaves it untouched. */
static void check_bake(const sdf_mesh *mesh)
{
    sdf_workspace *ws = NULL;
    CHECK(sdf_workspace_create(&ws) == 0, "workspace");
    sdf_volume *volume[2] = {NULL, NULL};
    sdf_diag diag;
    for (int k = 0; k < 2; k++) {
        sdf_bake_options o = {.dims = {24, 24, 24}, .order = 1,
                              .query = {.threads = 2, .workspace = k ? ws : NULL}};
        CHECK(sdf_volume_bake(mesh, &o, &volume[k], &diag) == 0, "bake %d: %s", k, diag.message);
    }
    if (volume[0] && volume[1]) {
        size_t bytes = sdf_volume_data_bytes(volume[0]);
        CHECK(bytes == sdf_volume_data_bytes(volume[1]) &&
                  memcmp(sdf_volume_data(volume[0]), sdf_volume_data(volume[1]), bytes) == 0,
              "a bake given a workspace differs");
    }
    CHECK(sdf_workspace_bytes(ws) == 0, "a bake used the workspace: %zu bytes",
          sdf_workspace_bytes(ws));
    sdf_volume_destroy(volume[0]), sdf_volume_destroy(volume[1]);
    sdf_workspace_destroy(ws);
}

static void test_arguments(void)
{
    CHECK(sdf_workspace_create(NULL) == SDF_EINVAL, "NULL out");
    CHECK(sdf_workspace_bytes(NULL) == 0, "NULL workspace's bytes");
    sdf_workspace_destroy(NULL);
}

/* One workspace handed from raw queries to filtered ones, to lattices, to two threads: what
 * one kind of call left in it must not change the next one's answers. */
static void test_one_workspace(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    if (!mesh)
        return;
    size_t n = MOST;
    float *points = malloc(3 * MOST * sizeof *points);
    sdf_workspace *ws = NULL;
    CHECK(points && sdf_workspace_create(&ws) == 0, "memory");
    CHECK(sdf_workload(mesh, "band", &n, 11, points) == 0 && n == MOST, "workload");
    check_raw(mesh, points, ws);
    check_filtered(mesh, points, ws);
    check_lattice(mesh, ws);
    check_shared(mesh, points, ws);
    sdf_workspace_destroy(ws);
    free(points);
    sdf_mesh_release(mesh);
}

static void test_bake(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    if (!mesh)
        return;
    check_bake(mesh);
    sdf_mesh_release(mesh);
}

static const check_case cases[] = {
    {"arguments", test_arguments},
    {"one_workspace", test_one_workspace},
    {"bake", test_bake},
};

int main(int argc, char **argv)
{
    return check_main("workspace", cases, CHECK_COUNT_OF(cases), argc, argv);
}
