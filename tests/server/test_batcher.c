/* test_batcher.c - which queries server/state/batcher.c lets share a batch. Requests whose answers
 * differ must never be run as one library call, or one of them gets the other's answer:
 *  - two jobs that differ in the mesh, the mode, the sign or any one field of the filter
 *    options (every field of sdf_filter_options and its smoothing volume, changed one at a
 *    time) have different batch keys;
 *  - two spellings of one answer have equal keys, so they still share batches: equal jobs,
 *    sample_gradient 1 and 7, a shape-NONE smoothing volume with different unused fields,
 *    and an unfiltered mode whatever its (unread) filter options say;
 *  - end to end: filtered jobs differing in one parameter each, submitted to a real batcher
 *    within one batch window, each get exactly the floats a direct sdf_query_filtered with
 *    their own options gives. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../common/check.h"
#include "state/batcher.h"

static int dummy_meshes[2]; /* distinct addresses: the key compares mesh pointers */

static sdfd_job base_job(void)
{
    sdfd_job j = {0};
    j.mesh = (sdf_mesh *)&dummy_meshes[0];
    j.mode = SDF_MODE_FILTERED;
    j.sign = SDF_SIGN_WINDING;
    sdf_filter_options *f = &j.filter;
    f->kernel = SDF_KERNEL_GAUSSIAN;
    f->cap = 0.5, f->a = 2, f->b = 0.25, f->samples = 32, f->min_samples = 8, f->medial = 0.3;
    f->grid = 0, f->unsigned_integrand = 0, f->allow_wide_bump = 0, f->sample_gradient = 0;
    f->seed = 42;
    sdf_smoothing_volume *s = &f->smooth;
    s->shape = SDF_VOLUME_SPHERE;
    for (int k = 0; k < 3; k++)
        s->center[k] = 0.1 * k, s->lo[k] = -1 - k, s->hi[k] = 1 + k;
    s->radius = 0.75, s->mesh = (sdf_mesh *)&dummy_meshes[1], s->depth = 0.05, s->scale = 1.5;
    return j;
}

static int same_key(const sdfd_job *a, const sdfd_job *b)
{
    sdfd_batch_key ka, kb;
    sdfd_batch_key_of(a, &ka);
    sdfd_batch_key_of(b, &kb);
    return !memcmp(&ka, &kb, sizeof ka);
}

/* One field changed per case: every field of sdf_filter_options and sdf_smoothing_volume
 * (the batcher's static assertions send whoever adds a field here). */
#define VARIANTS(X)                                                                         \
    X(mesh, j.mesh = NULL) X(mode, j.mode = SDF_MODE_FILTERED_GRADIENT)                     \
    X(sign, j.sign = SDF_SIGN_RAYCAST) X(kernel, f->kernel = SDF_KERNEL_BUMP)               \
    X(cap, f->cap = 0.5000001) X(a, f->a = 3) X(b, f->b = 0.3) X(samples, f->samples = 33)  \
    X(min_samples, f->min_samples = 9) X(medial, f->medial = 0.31) X(grid, f->grid = 1)     \
    X(unsigned_integrand, f->unsigned_integrand = 1)                                        \
    X(allow_wide_bump, f->allow_wide_bump = 1) X(sample_gradient, f->sample_gradient = 1)   \
    X(seed, f->seed = 43) X(shape, s->shape = SDF_VOLUME_BOX)                               \
    X(center0, s->center[0] = 9) X(center1, s->center[1] = 9) X(center2, s->center[2] = 9)  \
    X(radius, s->radius = 0.7) X(lo0, s->lo[0] = -9) X(lo1, s->lo[1] = -9)                  \
    X(lo2, s->lo[2] = -9) X(hi0, s->hi[0] = 9) X(hi1, s->hi[1] = 9) X(hi2, s->hi[2] = 9)    \
    X(smooth_mesh, s->mesh = NULL) X(depth, s->depth = 0.06) X(scale, s->scale = 1.25)

static void check_keys(void)
{
    const sdfd_job base = base_job();
    int variants = 0;
#define VARIANT(name, change)                                                               \
    {                                                                                       \
        sdfd_job j = base_job();                                                            \
        sdf_filter_options *f = &j.filter;                                                  \
        sdf_smoothing_volume *s = &f->smooth;                                               \
        (void)f, (void)s;                                                                   \
        change;                                                                             \
        CHECK(!same_key(&base, &j), "jobs differing in %s share a batch key", #name);       \
        variants++;                                                                         \
    }
    VARIANTS(VARIANT)
#undef VARIANT
    /* 3 job fields, 12 filter scalars, 14 of the smoothing volume (arrays per element) */
    CHECK(variants == 3 + 12 + 14, "%d variants", variants);

    sdfd_job a = base_job(), b = base_job();
    CHECK(same_key(&a, &b), "equal jobs must share a key");
    a.filter.sample_gradient = 1, b.filter.sample_gradient = 7;
    CHECK(same_key(&a, &b), "sample_gradient 1 and 7 are one answer");
    a = base_job(), b = base_job();
    a.filter.smooth.shape = b.filter.smooth.shape = SDF_VOLUME_NONE;
    b.filter.smooth.radius = 3, b.filter.smooth.center[1] = 5, b.filter.smooth.mesh = NULL;
    b.filter.smooth.depth = 1;
    CHECK(same_key(&a, &b), "a NONE volume's unused fields must not split batches");
    for (int m = SDF_MODE_SIGNED; m <= SDF_MODE_CLOSEST; m++) {
        a = base_job(), b = base_job();
        a.mode = b.mode = (sdf_proto_mode)m;
        b.filter.seed = 7, b.filter.samples = 5, b.filter.smooth.shape = SDF_VOLUME_NONE;
        CHECK(same_key(&a, &b), "mode %d does not read the filter", m);
        b.sign = SDF_SIGN_NONE;
        CHECK(!same_key(&a, &b), "mode %d: the sign splits batches", m);
    }
}

/* ---- end to end ---------------------------------------------------------------------- */

enum { JOBS = 6, POINTS = 40 };
static atomic_int jobs_done;

static void on_done(sdfd_job *job)
{
    (void)job;
    atomic_fetch_add(&jobs_done, 1);
}

static void check_batches(void)
{
    sdf_mesh *mesh = load_data_mesh("cube.ply");
    if (!mesh)
        return;
    sdf_mesh_report r;
    sdf_mesh_get_report(mesh, &r);
    float points[3 * POINTS];
    for (int i = 0; i < POINTS; i++)
        for (int k = 0; k < 3; k++)
            points[3 * i + k] = r.bbox_min[k] + (r.bbox_max[k] - r.bbox_min[k]) *
                                                    (float)((i * (k + 3) + k) % 11) / 10.0f;
    sdf_filter_options opts[JOBS];
    for (int i = 0; i < JOBS; i++)
        opts[i] = (sdf_filter_options){.samples = 16, .seed = 5};
    opts[1].seed = 6;
    opts[2].samples = 17;
    opts[3].cap = 0.03 * r.diagonal;
    opts[4].kernel = SDF_KERNEL_BUMP;
    opts[5].a = 4 * 8 / (0.02 * r.diagonal * 0.02 * r.diagonal); /* sigma halved */

    sdfd_metrics *metrics = sdfd_metrics_create(NULL, 0);
    sdfd_batcher *batcher = NULL;
    /* A long window: every job is queued before the first batch is taken. */
    CHECK(sdfd_batcher_create(1, 300000, 1 << 16, 1 << 20, metrics, &batcher) == 0, "batcher");
    static uint32_t words[JOBS][POINTS];
    static sdfd_job jobs[JOBS];
    for (int i = 0; batcher && i < JOBS; i++) {
        jobs[i] = (sdfd_job){.mesh = mesh, .mode = SDF_MODE_FILTERED, .sign = SDF_SIGN_AUTO,
                             .filter = opts[i], .points = points, .count = POINTS,
                             .words = words[i], .done = on_done};
        CHECK(sdfd_batcher_submit(batcher, &jobs[i], NULL) == 0, "submit %d", i);
    }
    for (int t = 0; t < 3000 && atomic_load(&jobs_done) < JOBS; t++)
        nanosleep(&(struct timespec){0, 10000000}, NULL);
    CHECK(atomic_load(&jobs_done) == JOBS, "%d of %d jobs answered", atomic_load(&jobs_done),
          JOBS);
    sdfd_batcher_destroy(batcher);
    for (int i = 0; i < JOBS; i++) {
        float want[POINTS];
        sdf_query_result res = {.distance = want};
        sdf_diag diag = {0};
        CHECK(sdf_query_filtered(mesh, points, POINTS, NULL, &opts[i], &res, &diag) == 0,
              "direct query %d: %s", i, diag.message);
        CHECK(jobs[i].status == 0, "job %d: %s", i, jobs[i].message);
        int same = !memcmp(words[i], want, sizeof want);
        CHECK(same, "job %d's answer is not its own options' answer", i);
        if (i > 0)
            CHECK(memcmp(words[i], words[0], sizeof want), "job %d: its change made no "
                  "difference, so this case cannot tell batches apart", i);
    }
    sdfd_metrics_destroy(metrics);
    sdf_mesh_release(mesh);
}

static const check_case cases[] = {
    {"keys", check_keys},
    {"batches", check_batches},
};

int main(int argc, char **argv)
{
    return check_main("server_batcher", cases, CHECK_COUNT_OF(cases), argc, argv);
}
