/* simd.h - wider vectors where the CPU has them, one portable binary everywhere.
 *
 * The hot lane loops (points/packet.c) are plain C that the compiler vectorizes. Built for
 * baseline x86-64 they use 4-wide SSE2; SDF__SIMD_CLONES asks GCC (and clang >= 15) to also
 * compile the function for x86-64-v3 (AVX2 + FMA, 8 floats per vector) and pick the version
 * when the program loads (an ifunc), so no -march flag is needed and old CPUs still run.
 * Elsewhere the macro is empty; so under clang 14, which names the dispatcher "f.ifunc" where
 * other files look for "f" (they fail to link), the library is built for baseline x86-64 only.
 * Only float pre-filters run in cloned code: every answer is decided by the
 * double-precision triangle test, compiled once, so results do not depend on the CPU. */
#ifndef SDF_CORE_SIMD_H
#define SDF_CORE_SIMD_H

/* Not under ThreadSanitizer: the ifunc resolvers run while the program is relocated, before
 * TSan's runtime is up, and its instrumentation in them crashed every binary at load (GCC
 * 12). GCC says so by __SANITIZE_THREAD__, clang by __has_feature. */
#if defined(__SANITIZE_THREAD__)
#define SDF__UNDER_TSAN 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define SDF__UNDER_TSAN 1
#endif
#endif
#if defined(__x86_64__) && defined(__ELF__) && !defined(SDF__UNDER_TSAN) && \
    ((defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 11) || \
     (defined(__clang__) && __clang_major__ >= 15))
#define SDF__SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define SDF__SIMD_CLONES
#endif

/* Helpers of a cloned function must be inlined into it to be compiled for each target. */
#if defined(__GNUC__)
#define SDF__HOT_INLINE static inline __attribute__((always_inline))
#else
#define SDF__HOT_INLINE static inline
#endif

#endif
