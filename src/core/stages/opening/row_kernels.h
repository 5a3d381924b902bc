// Private to the core: the opening's row kernels of one SIMD target (stages/opening/kernels.cpp).
#pragma once

#include <type_traits>

#include <opencv2/core.hpp>

namespace kinect_pipeline
{
namespace detail
{
/** The row kernels of stages/opening_kernels.h for one pixel type. */
template <typename T>
struct RowKernels
{
  void (*erode)(const cv::Mat& src, int r, int rad, T* tmp, T* dst);
  void (*dilate)(const cv::Mat& src, int r, int rad, T* tmp, T* dst);
  void (*erode_mapped)(const cv::Mat& src, int r, int rad, T* tmp, T* dst);
  void (*dilate3)(const T* a, const T* b, const T* c, int w, T* dst);
};

/** The opening's kernels of one SIMD target: openingKernels() gives those of the target the dispatch picks. */
struct OpeningKernels
{
  RowKernels<std::uint8_t> u8;
  RowKernels<std::uint16_t> u16;
  RowKernels<float> f32;

  template <typename T>
  const RowKernels<T>& of() const
  {
    if constexpr (std::is_same_v<T, std::uint8_t>)
      return u8;
    else if constexpr (std::is_same_v<T, std::uint16_t>)
      return u16;
    else
      return f32;
  }
};
const OpeningKernels& openingKernels();
}  // namespace detail
}  // namespace kinect_pipeline
