// Private to the core: runtime dispatch of the per-pixel loops to the widest vector unit the CPU has.
//
// KP_CLONES compiles a function three times (AVX-512 as in x86-64-v4, AVX2, the baseline) and picks one when the
// library is loaded (GCC's target_clones, an ifunc). The core is built with -ffp-contract=off, so that no clone
// fuses a multiply and an add: every clone gives bit-identical results, on every CPU.
// Off for sanitizer builds (an ifunc resolver runs before the sanitizer runtime is up), for other compilers and
// other architectures, and with -DKP_NO_CLONES. Design notes: docs/core_design.md ("Fast paths and their references").
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__) && \
    !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__) && !defined(KP_NO_CLONES)
#define KP_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define KP_CLONES
#endif

// The binning's pull (stages/scan/scan.cpp), the 3x3 opening (stages/opening/kernels.cpp) and the labelling of a
// row by value (stages/labels/by_value.cpp) have AVX-512 paths of their own, taken at run time where the CPU has
// them (vectorPathsSupported) and the Pipeline does not ask for the portable loops (ReferencePaths::portable).
#if defined(__GNUC__) && defined(__x86_64__) && !defined(KP_NO_CLONES)
#define KP_AVX512_PATHS 1
#define KP_TARGET_AVX512 __attribute__((target("avx512f,avx512bw,avx512dq,avx512vl")))
#include <immintrin.h>
#endif

namespace kinect_pipeline
{
namespace detail
{
/** Whether the library has the hand-written AVX-512 paths and the CPU the AVX-512 subsets they use. */
inline bool vectorPathsSupported()
{
#if defined(KP_AVX512_PATHS)
  static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                          __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
  return has;
#else
  return false;
#endif
}

}  // namespace detail

/**
 * Covers [i0, i0 + n) with calls body(start, B) of a fixed length B, the last one overlapping the one before
 * instead of leaving a remainder (spans shorter than B: one call body(i0, n)). With body inlined, each call is a
 * loop of B iterations the compiler turns into whole vectors, without the scalar tail a loop of n has. Only for
 * loops whose outputs are a function of their index (writing one twice writes the same value).
 */
template <int B, typename Body>
__attribute__((always_inline)) inline void overlappedBlocks(int i0, int n, const Body& body)
{
  if (n < B)
  {
    body(i0, n);
    return;
  }
  int i = i0;
  for (; i + B <= i0 + n; i += B)
    body(i, B);
  if (i < i0 + n)
    body(i0 + n - B, B);
}
}  // namespace kinect_pipeline
