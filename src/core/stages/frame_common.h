// Private to the core: what the frame's stages share (docs/core_design.md): the depth scale of each encoding, the
// row chunk of the fused row loop, OpenMP's thread numbers and the stage clock.
#pragma once

#include <chrono>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "kinect_pipeline/model/encoding.h"
#ifdef _OPENMP
#include <omp.h>
#endif

namespace kinect_pipeline
{
namespace detail
{
constexpr float kInf = std::numeric_limits<float>::infinity();

// Rows of a chunk of the row loop (a thread's unit of work): their bins are planned together.
constexpr int kRowChunk = 8;

// Metres per unit of each encoding (8-bit: max_depth / 255).
template <typename T>
float depthScale(double max_depth)
{
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return static_cast<float>(max_depth / 255.0);
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return 0.001f;
  else
    return 1.0f;
}

// A pixel value's depth [m], -1 where it holds no depth (no return, unknown).
template <typename T>
float metresOf(T v, float scale)
{
  if constexpr (std::is_floating_point_v<T>)
    return DepthTraits<T>::isNoReturn(DepthTraits<T>::map(v)) ? -1.0f : v;
  else
    return v < DepthTraits<T>::kMinValid ? -1.0f : static_cast<float>(v) * scale;
}

inline int defaultThreads()
{
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

inline int threadId()
{
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

using Clock = std::chrono::steady_clock;
inline double msSince(Clock::time_point t0)
{
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace detail
}  // namespace kinect_pipeline
