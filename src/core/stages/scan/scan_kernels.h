// Private to the core: the scan's SIMD kernels (stages/scan/scan.cpp), compiled once per SIMD target, and the
// one-line formulas they share with ScanProjector. Design notes: docs/core_design.md ("SIMD kernels and their
// references").
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace kinect_pipeline
{
namespace detail
{
/** The squared ranges of a cleaned row (ScanProjector::spanKeptSquaredRanges) for one pixel type. */
template <typename T>
struct KeptRangeKernels
{
  void (*any)(const float* xn, int u0, int u1, float ax, float ay, float bx, float by, const T* row, float scale,
              float* range);
  /** A row without roll: X = bx, Y = -xn exactly, xn^2 from a table. */
  void (*level)(const float* xn2, int u0, int u1, float bx, const T* row, float scale, float* range);
};

/** The scan's kernels of one SIMD target: scanKernels() gives those of the target the dispatch picks. */
struct ScanKernels
{
  void (*edge_bins)(const float* xe, int e0, int e1, float ax, float ay, float bx, float by, float lo, float inv,
                    float* out);
  void (*span_bins)(const float* xn, int u0, int u1, float ax, float ay, float bx, float by, float lo, float inv,
                    float beams, const float* z, float* fb, std::int32_t* key, float* range);
  void (*ranges)(const float* xn, int u0, int u1, float ax, float ay, float bx, float by, const float* z,
                 float* range);
  void (*columns)(const float* cb, const float* k, int u0, int u1, float beams, const float* z, float* fb,
                  std::int32_t* key, float* range);
  /** [up][roll]: bearings grow with the column; the row has roll (by != 0). */
  void (*pixels[2][2])(const float* p, const float* q, int n, float bx, float by, float cx, int a, int b,
                       std::int32_t* lo, std::int32_t* hi);
  /** detail::pullNearest. */
  void (*pull)(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
               std::int32_t* counts);
  ByDepthType<KeptRangeKernels> kept;
};
const ScanKernels& scanKernels();

/**
 * The column at which the bearing of border k crosses the row (bx, by): cx + fx (bx s - by c) / (ay c - ax s)
 * with the pose's terms P = fx s / den, Q = fx c / den (ScanProjector::setPose). The one formula of a crossing;
 * without roll (by = 0) the product by q is a zero, and bx p - 0 is bx p: kRoll false leaves it out, same bits.
 */
template <bool kRoll>
__attribute__((always_inline)) inline float crossing(float p, float q, float bx, float by, float cx)
{
  if constexpr (kRoll)
    return cx + (bx * p - by * q);
  else
    return cx + bx * p;
}
}  // namespace detail
}  // namespace kinect_pipeline
