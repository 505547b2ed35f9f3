/* test_morton.c - the batch's Morton visit order (lib/points/morton.c) against a slow,
 * obvious one: each point's code built bit by bit (axis k's bit j at bit 3j + k), indices
 * sorted by (code, index) with qsort. Batches below and above the size at which the sort
 * splits over threads, on 1, 2, 3 and 8 threads, with a stride wider than a point: uniform
 * points, all points equal, a flat axis, and a coarse lattice full of equal codes (where a
 * sort that is not stable, or parts merged out of order, shows). On 2 and 8 threads the keys
 * come from one workspace that every batch reuses, grown and not (core/workspace.h). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"
#include "points/morton.h"

#define STRIDE_FLOATS 4 /* a point's xyz and one unused float */

typedef struct keyed {
    uint32_t code, index;
} keyed;

static int by_code_then_index(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    if (x->code != y->code)
        return x->code < y->code ? -1 : 1;
    return x->index < y->index ? -1 : x->index > y->index;
}

/* Axis k's 10 bits, bit j at bit 3j + k, one bit at a time. */
static uint32_t slow_code(const float p[3], const float lo[3], const float scale[3])
{
    uint32_t code = 0;
    for (int k = 0; k < 3; k++) {
        uint32_t c = (uint32_t)((p[k] - lo[k]) * scale[k]) & 1023;
        for (int j = 0; j < 10; j++)
            code |= (c >> j & 1u) << (3 * j + k);
    }
    return code;
}

static void slow_order(const float *pts, size_t count, uint32_t *order)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < count; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fminf(lo[k], pts[STRIDE_FLOATS * i + k]);
            hi[k] = fmaxf(hi[k], pts[STRIDE_FLOATS * i + k]);
        }
    float scale[3];
    for (int k = 0; k < 3; k++)
        scale[k] = hi[k] > lo[k] ? 1023.0f / (hi[k] - lo[k]) : 0.0f;
    keyed *keys = malloc((count + 1) * sizeof *keys);
    CHECK(keys != NULL, "memory");
    for (size_t i = 0; i < count; i++) {
        const float *p = pts + STRIDE_FLOATS * i;
        keys[i].code = slow_code(p, lo, scale);
        keys[i].index = (uint32_t)i;
        CHECK(sdf__morton_code(p, lo, scale) == keys[i].code, "code of point %zu", i);
    }
    qsort(keys, count, sizeof *keys, by_code_then_index);
    for (size_t i = 0; i < count; i++)
        order[i] = keys[i].index;
    free(keys);
}

static uint64_t rng_state = 0x9e3779b97f4a7c15u;

static float uniform(void)
{
    rng_state = rng_state * 6364136223846793005u + 1442695040888963407u;
    return (float)(rng_state >> 40) / (float)(1u << 24);
}

enum kind { UNIFORM, ALL_EQUAL, FLAT_Y, COARSE_LATTICE, KINDS };
static const char *const kind_names[] = {"uniform", "all equal", "flat y", "coarse lattice"};

static void make_points(enum kind kind, size_t count, float *pts)
{
    for (size_t i = 0; i < count; i++) {
        float *p = pts + STRIDE_FLOATS * i;
        for (int k = 0; k < 3; k++) {
            float u = uniform();
            p[k] = kind == UNIFORM       ? 20 * u - 7
                   : kind == ALL_EQUAL   ? 1.5f
                   : kind == FLAT_Y      ? (k == 1 ? -2.0f : u)
                                         : floorf(4 * u) * 0.25f; /* 64 codes in all */
        }
        p[3] = NAN; /* never read */
    }
}

static void test_order(void)
{
    /* Around the size at which the sort splits over threads (2^17 points), and small ones. */
    const size_t counts[] = {0, 1, 2, 31, 1000, 131071, 131072, 131073, 300001};
    const int threads[] = {1, 2, 3, 8};
    size_t most = 300001;
    float *pts = malloc(most * STRIDE_FLOATS * sizeof *pts);
    uint32_t *want = malloc(most * sizeof *want), *got = malloc(most * sizeof *got);
    sdf_workspace *ws = NULL;
    CHECK(pts && want && got && sdf_workspace_create(&ws) == 0, "memory");
    for (int kind = 0; kind < KINDS; kind++)
        for (size_t c = 0; c < sizeof counts / sizeof *counts; c++) {
            size_t count = counts[c];
            make_points((enum kind)kind, count, pts);
            slow_order(pts, count, want);
            for (size_t t = 0; t < sizeof threads / sizeof *threads; t++) {
                memset(got, 0xff, most * sizeof *got);
                int rc = sdf__morton_order((const char *)pts, STRIDE_FLOATS * sizeof(float),
                                           count, threads[t], t % 2 ? ws : NULL, got);
                CHECK(rc == 0, "%s, %zu points, %d threads: rc %d", kind_names[kind], count,
                      threads[t], rc);
                size_t first_bad = count;
                for (size_t i = 0; i < count && first_bad == count; i++)
                    if (got[i] != want[i])
                        first_bad = i;
                CHECK(first_bad == count, "%s, %zu points, %d threads: position %zu is %u, "
                      "not %u", kind_names[kind], count, threads[t], first_bad,
                      first_bad < count ? got[first_bad] : 0,
                      first_bad < count ? want[first_bad] : 0);
                CHECK(count == most || got[count] == UINT32_MAX,
                      "%s, %zu points: wrote past the order", kind_names[kind], count);
            }
        }
    free(pts), free(want), free(got);
    sdf_workspace_destroy(ws);
}

static const check_case cases[] = {
    {"order", test_order},
};

int main(int argc, char **argv)
{
    return check_main("morton", cases, CHECK_COUNT_OF(cases), argc, argv);
}
