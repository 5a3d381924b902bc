// Stage 1 of a frame: unknown pixels to no return and the opening (stages/opening/opening.h), on the row kernels of
// stages/opening_kernels.h or OpenCV's. Design notes: docs/core_design.md ("Stage 1: the opening").
#include "stages/opening/opening.h"

#include <algorithm>
#include <cstdint>

#include <opencv2/imgproc.hpp>

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/stages/opening_kernels.h"

namespace kinect_pipeline
{
namespace detail
{
template <typename T>
Opening<T>::Opening(const Config& config, const ReferencePaths& paths, OpeningImages& images)
    : images_(images)
{
  ksize_ = config.open_kernel_size;
  rad_ = ksize_ >= 3 ? ksize_ / 2 : 0;
  const KernelShape shape = config.open_kernel_shape;
  const bool rect = shape == KernelShape::kRect;
  if (rad_ == 0)
    mode_ = OpeningMode::kNone;
  else if (!rect || paths.opening)
    mode_ = OpeningMode::kOpenCV;
  else
    mode_ = rad_ == 1 ? OpeningMode::kStream3 : OpeningMode::kRectRows;
  cv_shape_ = rect ? cv::MORPH_RECT : (shape == KernelShape::kCross ? cv::MORPH_CROSS : cv::MORPH_ELLIPSE);
}

template <typename T>
void Opening<T>::openWhole(const cv::Mat& depth, int threads)
{
  if (mode_ == OpeningMode::kRectRows)
  {
    images_.eroded.create(depth.size(), depth.type());
    return;
  }
  if (mode_ != OpeningMode::kOpenCV)
    return;
  using Tr = DepthTraits<T>;
  cv::Mat& mapped = images_.mapped;
  mapped.create(depth.size(), depth.type());
  const int h = depth.rows, w = depth.cols;
#pragma omp parallel for num_threads(threads) schedule(static)
  for (int r = 0; r < h; ++r)
  {
    const T* in = depth.ptr<T>(r);
    T* m = mapped.ptr<T>(r);
    for (int u = 0; u < w; ++u)
      m[u] = Tr::map(in[u]);
  }
  cv::morphologyEx(mapped, images_.opened, cv::MORPH_OPEN,
                   cv::getStructuringElement(cv_shape_, cv::Size(ksize_, ksize_)));
}

template <typename T>
void Opening<T>::erodeRows(const cv::Mat& depth, OpeningScratch& s) const
{
  s.ring_rows.fill(-1);
  if (mode_ != OpeningMode::kRectRows)
    return;
  const int h = depth.rows;
#pragma omp for schedule(static)
  for (int r = 0; r < h; ++r)
    erodeMappedRow<T>(depth, r, rad_, reinterpret_cast<T*>(s.tmp.data()), images_.eroded.ptr<T>(r));
}

template <typename T>
const T* Opening<T>::row(const cv::Mat& depth, int r, OpeningScratch& s) const
{
  T* row = reinterpret_cast<T*>(s.row.data());
  T* tmp = reinterpret_cast<T*>(s.tmp.data());
  const int h = depth.rows, w = depth.cols;
  switch (mode_)
  {
    case OpeningMode::kStream3:
    {
      const T* e[3];  // eroded rows r - 1, r, r + 1 (the row itself at the image's edges)
      for (int d = 0; d < 3; ++d)
      {
        const int j = std::min(std::max(r + d - 1, 0), h - 1), slot = j % 3;
        T* ring = reinterpret_cast<T*>(s.ring.data()) + static_cast<std::size_t>(slot) * w;
        if (s.ring_rows[slot] != j)
        {
          erodeMappedRow<T>(depth, j, 1, tmp, ring);
          s.ring_rows[slot] = j;
        }
        e[d] = ring;
      }
      dilate3Rows<T>(e[0], e[1], e[2], w, row);
      return row;
    }
    case OpeningMode::kRectRows:
      rectRow<T, false>(images_.eroded, r, rad_, tmp, row);
      return row;
    case OpeningMode::kOpenCV:
      return images_.opened.ptr<T>(r);
    case OpeningMode::kNone:
    default:
    {
      const T* in = depth.ptr<T>(r);
      for (int u = 0; u < w; ++u)
        row[u] = DepthTraits<T>::map(in[u]);
      return row;
    }
  }
}

template class Opening<std::uint8_t>;
template class Opening<std::uint16_t>;
template class Opening<float>;
}  // namespace detail
}  // namespace kinect_pipeline
