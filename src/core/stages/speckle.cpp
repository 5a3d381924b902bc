// A stereo camera's wrong matches, taken as no return before the opening (stages/speckle.h). A plain loop per row,
// compiled once per SIMD target: each row is compared with the rows two above and below and with itself two
// columns either way.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/speckle.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "stages/speckle.h"

#include <cstdint>
#include <limits>

#include "kinect_pipeline/model/encoding.h"

HWY_BEFORE_NAMESPACE();
namespace kinect_pipeline
{
namespace detail
{
namespace HWY_NAMESPACE
{
// The value a pixel is compared at: no measurement counts as farther than anything.
template <typename T>
inline float compared(T v)
{
  const T m = DepthTraits<T>::map(v);
  return DepthTraits<T>::isNoReturn(m) ? std::numeric_limits<float>::infinity() : static_cast<float>(m);
}

// Row v (row) of the output (dst), columns 2 .. w - 3, from rows v - 2 (up), v and v + 2 (down); the number of
// wrong matches set to 0.
template <typename T>
int islandRow(const T* __restrict up, const T* __restrict row, const T* __restrict down, T* __restrict dst, int w,
              float factor)
{
  int n = 0;
  for (int u = 2; u < w - 2; ++u)  // & rather than &&: no branch, so that it vectorises
  {
    const float z = compared(row[u]) * factor;  // +Inf for no measurement: never an island
    const bool island = (compared(row[u - 2]) > z) & (compared(row[u + 2]) > z) & (compared(up[u]) > z) &
                        (compared(down[u]) > z);
    dst[u] = island ? T(0) : row[u];
    n += island;
  }
  return n;
}
int islandRow8(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down, std::uint8_t* dst, int w,
               float factor)
{
  return islandRow(up, row, down, dst, w, factor);
}
int islandRow16(const std::uint16_t* up, const std::uint16_t* row, const std::uint16_t* down, std::uint16_t* dst,
                int w, float factor)
{
  return islandRow(up, row, down, dst, w, factor);
}
int islandRowF(const float* up, const float* row, const float* down, float* dst, int w, float factor)
{
  return islandRow(up, row, down, dst, w, factor);
}
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(islandRow8);
HWY_EXPORT(islandRow16);
HWY_EXPORT(islandRowF);

namespace
{
int islandRowOf(const std::uint8_t* up, const std::uint8_t* row, const std::uint8_t* down, std::uint8_t* dst, int w,
                float factor)
{
  return HWY_DYNAMIC_DISPATCH(islandRow8)(up, row, down, dst, w, factor);
}
int islandRowOf(const std::uint16_t* up, const std::uint16_t* row, const std::uint16_t* down, std::uint16_t* dst,
                int w, float factor)
{
  return HWY_DYNAMIC_DISPATCH(islandRow16)(up, row, down, dst, w, factor);
}
int islandRowOf(const float* up, const float* row, const float* down, float* dst, int w, float factor)
{
  return HWY_DYNAMIC_DISPATCH(islandRowF)(up, row, down, dst, w, factor);
}

template <typename T>
int removeRows(const cv::Mat& depth, float factor, cv::Mat& out, int threads)
{
  depth.copyTo(out);
  int removed = 0;
#pragma omp parallel for num_threads(threads) reduction(+ : removed) schedule(static)
  for (int v = 2; v < depth.rows - 2; ++v)
    removed += islandRowOf(depth.ptr<T>(v - 2), depth.ptr<T>(v), depth.ptr<T>(v + 2), out.ptr<T>(v), depth.cols,
                           factor);
  return removed;
}
}  // namespace

int removeSpeckles(const cv::Mat& depth, double jump, cv::Mat& out, int threads)
{
  const float factor = static_cast<float>(1.0 + jump);
  switch (depth.type())
  {
    case CV_8UC1:
      return removeRows<std::uint8_t>(depth, factor, out, threads);
    case CV_16UC1:
      return removeRows<std::uint16_t>(depth, factor, out, threads);
    default:
      return removeRows<float>(depth, factor, out, threads);
  }
}
}  // namespace detail
}  // namespace kinect_pipeline
#endif  // HWY_ONCE
