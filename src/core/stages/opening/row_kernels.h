// Private to the core: the opening's row kernels of one SIMD target (stages/opening/kernels.cpp).
#pragma once

#include <opencv2/core.hpp>

#include "base/simd.h"

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
using OpeningKernels = ByDepthType<RowKernels>;
const OpeningKernels& openingKernels();
}  // namespace detail
}  // namespace kinect_pipeline
