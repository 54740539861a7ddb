/* solver/simd_internal.h -- how the solver's hot loops get the widest
 * vectors the processor has.
 *
 * ISO_CLONES compiles a function once per instruction set (GCC's
 * target_clones: AVX-512F, AVX2 and the baseline) and picks one when the
 * program is loaded. The clones compute the same bits: the library is built
 * as ISO C (-std=c11), so GCC never contracts a * b + c into a fused
 * multiply-add, and the loops spell out their order of summation (generic
 * vectors of fixed width, not reductions the compiler may reorder).
 *
 * Not under the sanitizers: a clone's resolver runs while the program is
 * being loaded, before their run-time is set up, and ThreadSanitizer's
 * instrumentation of it crashes there.
 *
 * ISO_INLINE marks a helper a clone calls: it must be inlined into the
 * clone, or it would be compiled for the baseline alone, with its vectors
 * passed in memory (GCC's -Wpsabi). */
#ifndef ISO_SOLVER_SIMD_INTERNAL_H
#define ISO_SOLVER_SIMD_INTERNAL_H

#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__) &&                             \
    !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define ISO_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define ISO_CLONES
#endif

#define ISO_INLINE static inline __attribute__((always_inline))

#endif
