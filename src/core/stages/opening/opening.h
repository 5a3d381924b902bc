// Private to the core: stage 1, unknown pixels to no return and the morphological opening (thesis section 4.4.1),
// row by row for the fused row loop. Design notes: docs/core_design.md ("Stage 1: the opening").
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{
namespace detail
{
/** One thread's rows for the opening: the opened row, a row of scratch, the 3x3 opening's ring of eroded rows. */
struct OpeningScratch
{
  std::vector<float> row, tmp;     ///< one image row of the input's type (floats are the widest)
  std::vector<float> ring;         ///< three eroded rows of the input's type, row j in slot j % 3
  std::array<int, 3> ring_rows{};  ///< the row each slot holds (-1: none this frame)
  void resize(std::size_t w)
  {
    row.resize(w);
    tmp.resize(w);
    ring.resize(3 * w);
  }
};

/** The frame's images of the opening (reused between frames). */
struct OpeningImages
{
  cv::Mat eroded, mapped, opened;
};

/**
 * How a frame is opened:
 * - kNone: no opening (kernel < 3), rows only mapped (unknown -> no return);
 * - kStream3: the 3x3 rectangle, streamed: each thread erodes the rows its rows' dilation needs into a ring of
 *   three rows as it goes (no eroded image, no pass and no wait between erosion and dilation);
 * - kRectRows: larger rectangles: an eroded image (the threads' rows), then each row's dilation;
 * - kOpenCV: cv::morphologyEx of the mapped image (the cross and ellipse shapes, and the reference path).
 * All four give the same opened values (stages/opening_kernels.h's kernels are checked against OpenCV bit for bit).
 */
enum class OpeningMode
{
  kNone,
  kStream3,
  kRectRows,
  kOpenCV,
};

template <typename T>
class Opening
{
public:
  /** @param paths opening: cv::morphologyEx for every kernel shape (the reference path) */
  Opening(const Config& config, const ReferencePaths& paths, OpeningImages& images);
  bool opens() const { return mode_ != OpeningMode::kNone; }
  /** Before the row loop: the whole image's opening where OpenCV does it (else nothing). */
  void openWhole(const cv::Mat& depth, int threads);
  /** In the row loop's parallel region, once per thread before its rows: the eroded image (kRectRows; a
   *  worksharing loop over the rows, with its barrier) and the thread's ring. */
  void erodeRows(const cv::Mat& depth, OpeningScratch& s) const;
  /** @return row r of the opened image (no return for unknown pixels), in s.row or an image of the opening. */
  const T* row(const cv::Mat& depth, int r, OpeningScratch& s) const;

private:
  OpeningMode mode_ = OpeningMode::kNone;
  int ksize_ = 0, rad_ = 0;
  int cv_shape_ = 0;
  OpeningImages& images_;
};
}  // namespace detail
}  // namespace kinect_pipeline
