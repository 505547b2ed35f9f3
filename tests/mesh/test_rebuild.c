/* test_rebuild.c - building and releasing meshes over and over on one thread holds no more
 * memory at the end than after the first few builds. A long-running server builds a mesh
 * for every upload: a few hundred bytes kept per build is a leak that only shows over hours
 * (the soak found one: Embree keeps an allocator for every thread that has ever built an
 * index, and each build used to run Embree on a new thread). LeakSanitizer cannot see such
 * memory, which is still referenced; the heap's live bytes can. */
#include <stdio.h>
#include <string.h>

#include "../common/check.h"

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define SANITIZED_HEAP 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define SANITIZED_HEAP 1
#endif

#ifdef SANITIZED_HEAP
/* The sanitizer runtimes' own count (freed memory in quarantine is not live). */
size_t __sanitizer_get_current_allocated_bytes(void);
static size_t live_bytes(void)
{
    return __sanitizer_get_current_allocated_bytes();
}
#else
#include <malloc.h>
static size_t live_bytes(void)
{
    struct mallinfo2 m = mallinfo2();
    return m.uordblks + m.hblkhd;
}
#endif

static const char tetrahedron[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
                                  "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/* Build, query (its lazy parts too: the raycast sign builds Embree's own scene) and release. */
static int build_once(void)
{
    sdf_mesh_options o = {.format = SDF_FORMAT_OBJ};
    sdf_mesh *m;
    sdf_diag d;
    if (sdf_mesh_load_memory(tetrahedron, strlen(tetrahedron), &o, &m, &d))
        return -1;
    float p[6] = {0.2f, 0.2f, 0.2f, 2, 2, 2}, dist[2];
    sdf_query_options qo = {.threads = 1, .sign = SDF_SIGN_RAYCAST};
    sdf_query_result out = {.distance = dist};
    int rc = sdf_query(m, p, 2, &qo, &out);
    sdf_mesh_release(m);
    return rc || !(dist[0] < 0 && dist[1] > 0) ? -1 : 0;
}

static void test_repeated_builds(void)
{
    enum { WARM = 200, BUILDS = 2000 };
    int failed = 0;
    for (int i = 0; i < WARM; i++)
        failed += build_once() != 0;
    size_t before = live_bytes();
    for (int i = 0; i < BUILDS; i++)
        failed += build_once() != 0;
    size_t after = live_bytes();
    CHECK(failed == 0, "%d builds or queries failed", failed);
    /* 48 bytes a build would be 96 KB: far above any one-off cache, far below the 192 bytes
     * a build Embree kept when it ran on a new thread each time. */
    long grown = (long)after - (long)before;
    CHECK(grown < 48L * BUILDS, "%d builds on one thread: live heap %zu -> %zu bytes (+%ld)",
          BUILDS, before, after, grown);
    printf("%d builds: live heap %zu -> %zu bytes (%+ld)\n", BUILDS, before, after, grown);
}

static const check_case cases[] = {
    {"repeated_builds", test_repeated_builds},
};

int main(int argc, char **argv)
{
    return check_main("mesh_rebuild", cases, CHECK_COUNT_OF(cases), argc, argv);
}
