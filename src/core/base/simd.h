// Private to the core: the SIMD kernels' run-time dispatch (Google Highway) and a loop helper they share.
//
// A file with kernels names itself in HWY_TARGET_INCLUDE and includes <hwy/foreach_target.h>: Highway compiles its
// HWY_NAMESPACE section once per target (EMU128, SSE4, AVX2, AVX3 on x86-64; NEON, SVE on aarch64), each under its
// own "#pragma GCC target", and HWY_DYNAMIC_DISPATCH calls the best one the CPU has and the restriction allows
// (kinect_pipeline/simd.h). The core is built with -ffp-contract=off and the kernels use no fused multiply-add, so
// every target gives the same bits. Design notes: docs/core_design.md ("SIMD kernels and their references").
#pragma once

#include <cstdint>
#include <type_traits>

namespace kinect_pipeline
{
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

namespace detail
{
/** One K<T> per depth pixel type (8-bit, 16-bit, float): a kernel table's entries for each. */
template <template <typename> class K>
struct ByDepthType
{
  K<std::uint8_t> u8;
  K<std::uint16_t> u16;
  K<float> f32;

  template <typename T>
  const K<T>& of() const
  {
    if constexpr (std::is_same_v<T, std::uint8_t>)
      return u8;
    else if constexpr (std::is_same_v<T, std::uint16_t>)
      return u16;
    else
      return f32;
  }
};

/** Applies KINECT_PIPELINE_SIMD once per process (kinect_pipeline/simd.h); throws what restrictSimd throws. */
void simdFromEnvironment();
}  // namespace detail
}  // namespace kinect_pipeline
