/* test_bake_memory.c - sdf_volume_bake_scratch bounds what sdf_volume_bake really allocates.
 *
 * This program replaces malloc and its relatives with counting wrappers around glibc's own
 * allocator (the library is linked in statically, so its calls land here) and records the
 * peak of live heap bytes while each bake runs. For bakes that take every path (scan and
 * queries; zero and first order; raw and filtered fields; pseudonormal, winding, ray and no
 * sign; a closed and an open mesh) it checks
 *  - peak - (live before) - (the volume) <= the bound, and
 *  - the bound is not uselessly loose: <= 4 x that peak + 16 MB.
 * Embree's scene (raycast sign) allocates through its own allocator, partly outside these
 * wrappers, so there only the first check means much. Not built with the sanitizers, whose
 * own allocator must see every allocation (tests/meson.build). */
#define _GNU_SOURCE
#include <malloc.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/check.h"

extern void *__libc_malloc(size_t size);
extern void *__libc_calloc(size_t count, size_t size);
extern void *__libc_realloc(void *p, size_t size);
extern void *__libc_memalign(size_t alignment, size_t size);
extern void __libc_free(void *p);

static atomic_llong live_bytes, peak_bytes;

static void *counted(void *p)
{
    if (p) {
        long long now = atomic_fetch_add(&live_bytes, (long long)malloc_usable_size(p)) +
                        (long long)malloc_usable_size(p);
        long long peak = atomic_load(&peak_bytes);
        while (now > peak && !atomic_compare_exchange_weak(&peak_bytes, &peak, now)) {
        }
    }
    return p;
}

void *malloc(size_t size) { return counted(__libc_malloc(size)); }
void *calloc(size_t count, size_t size) { return counted(__libc_calloc(count, size)); }
void *memalign(size_t alignment, size_t size) { return counted(__libc_memalign(alignment, size)); }
void *aligned_alloc(size_t alignment, size_t size) { return memalign(alignment, size); }

int posix_memalign(void **out, size_t alignment, size_t size)
{
    void *p = memalign(alignment, size);
    if (!p)
        return 12; /* ENOMEM */
    *out = p;
    return 0;
}

void free(void *p)
{
    if (p)
        atomic_fetch_sub(&live_bytes, (long long)malloc_usable_size(p));
    __libc_free(p);
}

void *realloc(void *old, size_t size)
{
    long long before = old ? (long long)malloc_usable_size(old) : 0;
    void *p = __libc_realloc(old, size);
    if (p || size == 0) {
        atomic_fetch_sub(&live_bytes, before);
        counted(p);
    }
    return p;
}

typedef struct bake_case {
    size_t dim;
    int order;
    int filtered;
    sdf_sign_method sign;
    sdf_volume_encoding encoding; /* first order's planes: apart from the data when packed */
} bake_case;

static void check_mesh(const char *file, const bake_case *cases, size_t count)
{
    sdf_mesh *mesh = load_data_mesh(file);
    if (!mesh)
        return;
    sdf_filter_options filter = {.samples = 16};
    for (size_t c = 0; c < count; c++) {
        const bake_case *k = &cases[c];
        sdf_bake_options o = {.dims = {k->dim, k->dim, k->dim}, .order = k->order,
                              .encoding = k->encoding, .query = {.sign = k->sign, .threads = 2},
                              .filter = k->filtered ? &filter : NULL};
        sdf_diag diag = {0};
        size_t bound = 0;
        int rc = sdf_volume_bake_scratch(mesh, &o, &bound, &diag);
        CHECK(rc == 0, "%s case %zu: %s", file, c, diag.message);
        long long before = atomic_load(&live_bytes);
        atomic_store(&peak_bytes, before);
        sdf_volume *v = NULL;
        rc = sdf_volume_bake(mesh, &o, &v, &diag);
        CHECK(rc == 0, "%s case %zu: %s", file, c, diag.message);
        if (rc)
            continue;
        sdf_volume_info in;
        sdf_volume_get_info(v, &in);
        long long volume = (long long)(in.dims[0] * in.dims[1] * in.dims[2]) *
                           sdf_volume_channels(&in) * 4;
        long long used = atomic_load(&peak_bytes) - before - volume;
        printf("%s %zu^3 order %d filtered %d sign %d encoding %d: peak %.1f MB, bound %.1f MB\n",
               file, k->dim, k->order, k->filtered, (int)k->sign, (int)k->encoding,
               (double)used / 1e6, (double)bound / 1e6);
        CHECK(used <= (long long)bound, "%s case %zu: used %lld > bound %zu", file, c, used,
              bound);
        CHECK((long long)bound <= 4 * used + (16ll << 20), "%s case %zu: bound %zu for %lld",
              file, c, bound, used);
        sdf_volume_destroy(v);
    }
    sdf_mesh_release(mesh);
}

static const sdf_volume_encoding F = SDF_ENCODING_FLOAT32, P = SDF_ENCODING_PACKED32;

static void test_closed_mesh(void)
{
    const bake_case closed[] = {
        {64, 0, 0, SDF_SIGN_AUTO, F},    {128, 0, 0, SDF_SIGN_AUTO, F},
        {64, 1, 0, SDF_SIGN_AUTO, F},    {96, 1, 0, SDF_SIGN_AUTO, F},
        {64, 1, 0, SDF_SIGN_AUTO, P},    {48, 0, 0, SDF_SIGN_WINDING, F},
        {24, 1, 0, SDF_SIGN_WINDING, F}, {32, 0, 0, SDF_SIGN_RAYCAST, F},
        {32, 0, 0, SDF_SIGN_NONE, F},    {16, 0, 1, SDF_SIGN_AUTO, F},
        {8, 1, 1, SDF_SIGN_AUTO, F},
    };
    check_mesh("fandisk.off", closed, sizeof closed / sizeof closed[0]);
}

static void test_open_mesh(void)
{
    const bake_case open[] = {
        {64, 0, 0, SDF_SIGN_AUTO, F}, {24, 1, 0, SDF_SIGN_AUTO, F}, {12, 0, 1, SDF_SIGN_AUTO, F},
    };
    check_mesh("elephant-with-holes.off", open, sizeof open / sizeof open[0]);
}

/* A bad option is refused as sdf_volume_plan refuses it. */
static void test_bad_option(void)
{
    sdf_mesh *mesh = load_data_mesh("fandisk.off");
    if (!mesh)
        return;
    sdf_bake_options bad = {.dims = {1, 8, 8}};
    sdf_diag plan_diag = {0}, scratch_diag = {0};
    sdf_volume_info info;
    size_t bytes = 0;
    CHECK(sdf_volume_plan(mesh, &bad, &info, &plan_diag) == SDF_EINVAL, "plan");
    CHECK(sdf_volume_bake_scratch(mesh, &bad, &bytes, &scratch_diag) == SDF_EINVAL,
          "scratch");
    CHECK(strcmp(plan_diag.message, scratch_diag.message) == 0, "%s / %s", plan_diag.message,
          scratch_diag.message);
    sdf_mesh_release(mesh);
}

static const check_case cases[] = {
    {"closed_mesh", test_closed_mesh},
    {"open_mesh", test_open_mesh},
    {"bad_option", test_bad_option},
};

int main(int argc, char **argv)
{
    return check_main("bake_memory", cases, CHECK_COUNT_OF(cases), argc, argv);
}
