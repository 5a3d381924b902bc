/**
 * @file scan.h
 * @brief Projection of kept pixels into uniform angle bins, and the laser scan they make.
 */
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/** A laser scan in the LaserScan message's terms (REP 117 ranges, REP 103 angles). */
struct ScanData
{
  float angle_min = 0.0f;        ///< angle of the first beam [rad], counter-clockwise from forward
  float angle_max = 0.0f;        ///< angle of the last beam [rad]
  float angle_increment = 0.0f;  ///< [rad], > 0
  float range_min = 0.0f;        ///< [m]
  float range_max = 0.0f;        ///< [m]
  std::vector<float> ranges;       ///< [m]; +Inf no return, -Inf closer than range_min, NaN no data / filtered
  std::vector<float> intensities;  ///< confidence in [0, 1] (see Confidence)
};

/**
 * Branch-free atan2 from an approximation of atan on [0, 1] (atan01(a) for a = min / max of |x|, |y|), by the
 * octant's reflections: the one reduction of fastAtan2 and coarser variants.
 */
template <typename Atan01>
inline float atan2ByOctant(float y, float x, const Atan01& atan01)
{
  const float ax = x < 0.0f ? -x : x;
  const float ay = y < 0.0f ? -y : y;
  const float mx = ax > ay ? ax : ay;
  const float mn = ax > ay ? ay : ax;
  float r = atan01(mn / (mx > 1e-30f ? mx : 1e-30f));
  r = ay > ax ? 1.57079637f - r : r;
  r = x < 0.0f ? 3.14159274f - r : r;
  return y < 0.0f ? -r : r;
}

/** Branch-free atan2 (max error ~2e-6 rad) that the compiler can vectorise. */
inline float fastAtan2(float y, float x)
{
  return atan2ByOctant(y, x, [](float a) {
    const float s = a * a;
    // Minimax polynomial for atan on [0, 1].
    float r = -0.0117212f;
    r = r * s + 0.05265332f;
    r = r * s - 0.11643287f;
    r = r * s + 0.19354346f;
    r = r * s - 0.33262347f;
    r = r * s + 0.99997726f;
    return r * a;
  });
}

/**
 * Fractional bin position of the ray at normalised column xn of a row of the horizontal projection: its bearing
 * atan2(Y, X), (X, Y) = (ax xn + bx, ay xn + by), from the scan's lower edge lo in bins of 1 / inv radians.
 */
__attribute__((always_inline)) inline float rayBin(float xn, float ax, float ay, float bx, float by, float lo,
                                                   float inv)
{
  return (fastAtan2(ay * xn + by, ax * xn + bx) - lo) * inv;
}

/**
 * floor(f) and ceil(f) of a finite f within the int32 range, exactly, from the conversion towards zero: branch-free
 * and without a library call (the x86-64 baseline has no rounding instruction), so that the loops calling them
 * vectorise on every target.
 */
__attribute__((always_inline)) inline std::int32_t floorToInt(float f)
{
  const std::int32_t t = static_cast<std::int32_t>(f);  // towards zero
  return t - (f < static_cast<float>(t));
}
__attribute__((always_inline)) inline std::int32_t ceilToInt(float f)
{
  const std::int32_t t = static_cast<std::int32_t>(f);
  return t + (f > static_cast<float>(t));
}

/**
 * The bin of a fractional bin position f: its exact floor (the gap fill splits at exact borders too), clamped to
 * the padding slots -1 and beams; NaN goes to -1. Branch-free, so that the loops calling it vectorise.
 */
__attribute__((always_inline)) inline std::int32_t binKey(float f, float beams)
{
  return floorToInt(!(f >= -1.0f) ? -1.0f : (f > beams ? beams : f));
}

/**
 * The bins a span of a row reaches in the horizontal projection (ScanProjector::spanPlan): the pixels of bin
 * first + j (j < n) are the columns between where the bearings of its borders j and j + 1 cross the row,
 * cx + (bx p[j] - by q[j]), clipped to a..b.
 */
struct SpanPlan
{
  int first = 0, n = 0;
  bool up = true;  ///< bearings grow with the column
  const float *p = nullptr, *q = nullptr;  ///< the crossing terms of borders first .. first + n
  float bx = 0.0f, by = 0.0f, cx = 0.0f;   ///< the row's terms, the principal point's column
  int a = 0, b = 0;                        ///< the span
};

namespace detail
{
/**
 * The nearest of range[lo[j] .. hi[j]] into bins[j] (min with what it holds) for j < n, NaN ranges ignored, with
 * the SIMD kernel of the target the dispatch picks (lo and hi as ScanProjector::planPixels gives them: growing or
 * falling with j; range readable up to 31 floats past the last pixel); with counts, counts[j] also gains the
 * number of finite ranges among them. Its plain reference: the binning's pull bin by bin (ReferencePaths::portable).
 */
void pullNearest(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
                 std::int32_t* counts = nullptr);
}  // namespace detail

/**
 * Maps pixels to beams: a pixel goes to the bin of its centre's bearing, and the bins between two neighbouring
 * centres of a row go to the nearer one, so the binning leaves no bin empty that a surface covers, whatever the
 * pitch. The horizontal projection finds each bin's pixels from the bin's borders (spanPixels()); the column
 * projection, and rows where that does not hold, bin the centres by their bearings (spanBins()).
 * The column edges' bearings (rowEdgeBins(), rowCoverage()) bound what the image sees. The binning of a frame's rows
 * with these methods is the core's (src/core/stages/scan/binning.cpp, docs/core_design.md).
 *
 * Horizontal projection: the ray of pixel (u, r) in the gravity-aligned frame is
 * (X, Y) = (ax * xn + bx(r), ay * xn + by(r)) per metre of depth; its beam angle is atan2(Y, X) and its range
 * z * hypot(X, Y). Column projection (thesis): angle -theta_x(u), range z / cos(theta_x).
 */
class ScanProjector
{
public:
  /** @brief Sets beams and angle range from the camera and config (fixed until they change). */
  void configure(const Camera& camera, const Config& config);
  /** @brief Sets the per-row and per-border terms for this frame's pose (O(rows + beams)). */
  void setPose(double pitch, double roll);

  int beams() const { return beams_; }
  float angleMin() const { return angle_min_; }
  float angleMax() const { return angle_max_; }
  float angleIncrement() const { return inc_; }
  Projection projection() const { return projection_; }

  /**
   * @brief Fractional bin positions of the W + 1 column edges of row r (edge e lies at column e - 0.5;
   *        bin b covers positions [b, b + 1)).
   * @param buffer W + 1 floats the horizontal projection writes to
   * @return @p buffer, or the fixed per-column table of the column projection
   */
  const float* rowEdgeBins(int r, float* buffer) const;
  /**
   * @brief The range [lo, hi] of fractional bin positions any pixel of the image covers at this pose;
   *        bins outside it have no data (NaN), bins inside with no kept pixel no return (+Inf).
   */
  void coverage(float& lo, float& hi) const;
  /**
   * @brief Widens [lo, hi] to the fractional bin positions of the outer edges of row r's first and last pixels
   *        (coverage() is this over every row, from lo = +Inf, hi = -Inf).
   */
  void rowCoverage(int r, float& lo, float& hi) const;
  /**
   * @brief The pixels of each bin, for the span a..b of row r (horizontal projection): the same bins as
   *        spanBins gives the centres, up to float rounding at a bin's border, found from the bins' side instead.
   *
   * The horizontal parts (X, Y) of a row's rays lie on a straight line, so along a row the bearing is monotone
   * and each bin border's bearing crosses the row at one column (two products of the row's terms with the
   * border's, set once per pose; no atan, no division): the centres in bin k are the columns between the
   * crossings of k's two borders, lo[j]..hi[j] for k = first + j. A bin between two
   * neighbouring centres (narrower than a pixel) gets the centre nearest to its middle, lo[j] = hi[j]; its middle
   * is taken halfway between the two crossings. Both are clipped to a..b (lo[j] > hi[j]: nothing of the span).
   * @return the number of bins n (0: the span reaches no bin), or -1 where this does not hold: the column
   *         projection, a row whose line passes (nearly) under the sensor, bearings that leave the forward
   *         half-plane, or a span whose bearings pass the direction straight behind the sensor (a row that looks
   *         behind it: the scan's two ends); the caller then bins the centres by their bearings (spanBins).
   */
  int spanPixels(int r, int a, int b, std::int32_t* lo, std::int32_t* hi, int& first) const;
  /** @brief spanPixels' checks and bins without the pixels: @return n as spanPixels, and the plan where n > 0. */
  int spanPlan(int r, int a, int b, SpanPlan& plan) const;
  /** @brief The pixels lo[j]..hi[j] of each bin j of a plan (as spanPixels gives them). */
  static void planPixels(const SpanPlan& plan, std::int32_t* lo, std::int32_t* hi);
  /** @brief range[u] = depth[u] * hypot(X, Y) of the horizontal projection, u in [u0, u1]. */
  void spanRanges(int r, int u0, int u1, const float* depth, float* range) const;
  /**
   * @brief The squares of spanRanges of a cleaned row of the image's type (the depth of the pixels that are not
   *        removed, +Inf for removed ones, times scale metres per unit), without a pass to convert it and without
   *        a square root per pixel: fl(z^2) fl(X^2 + Y^2). The nearest of a bin's squared ranges, rooted, is its
   *        nearest range to within a few float roundings.
   */
  template <typename T>
  void spanKeptSquaredRanges(int r, int u0, int u1, const T* row, float scale, float* range) const;
  /**
   * @brief For pixels u0..u1 of row r, in one pass: fb = fractional bin positions of their centres, key = their
   *        bins (binKey), range = depth * range per metre of depth (horizontal: hypot(X, Y); column:
   *        1 / cos(theta_x)); +Inf depth stays +Inf.
   */
  void spanBins(int r, int u0, int u1, const float* depth, float* fb, std::int32_t* key, float* range) const;

private:
  /** @brief out[e] = fractional bin position of column edge e of row r, for e in [e0, e1] only. */
  void edgeBins(int r, int e0, int e1, float* out) const;

  Projection projection_ = Projection::kHorizontal;
  int width_ = 0, height_ = 0, beams_ = 0;
  float angle_min_ = 0.0f, angle_max_ = 0.0f, inc_ = 1.0f, lo_ = 0.0f;
  std::vector<float> xn_, xe_;                    // per column centre / edge
  std::vector<float> xn2_;                        // xn^2 per column centre
  std::vector<float> yn_;                         // per row
  // Column projection: each column's bearing, [0] upright, [1] upside down (mirrored: cos roll < 0, setPose()).
  std::array<std::vector<float>, 2> col_edge_bins_, col_centre_bins_;
  std::vector<float> col_factor_;
  int col_side_ = 0;
  float ax_ = 0.0f, ay_ = 0.0f;
  std::vector<float> bx_, by_;                    // horizontal projection, per row
  float cx_ = 0.0f, fx_ = 1.0f;                   // column u of a ray: cx + fx * xn
  float inv_fx_ = 1.0f;
  int coarse_margin_ = 1;  // spanPlan's bins either side of its coarse bounds
  std::vector<float> border_s_, border_c_;  // sin, cos of the bearing of bin k's lower border, k <= beams
  // At this pose: den = ay cos - ax sin of each border, and its crossing terms fx sin / den, fx cos / den.
  std::vector<float> border_den_, border_p_, border_q_;
};

/**
 * Confidence of each beam (thesis eq 4.23 with its absolute value):
 * intensity = clamp(1 - |d - mean| / confidence_distance, 0, 1), mean over the finite ranges among the
 * beam's last N (this one included). A beam whose window holds no other finite range (it just appeared out
 * of +Inf) gets intensity 1: a new obstacle is reported at once rather than held back for N frames.
 * +Inf and -Inf beams get 1, NaN beams 0. With intensity_filter, finite beams at or below min_intensity
 * become NaN (the rule of laser_filters' LaserScanIntensityFilter); the window keeps the unfiltered range.
 */
class Confidence
{
public:
  /** @brief Sizes the windows; clears the history if the beam count or window changed. */
  void configure(int beams, const Config& config);
  /** @brief Forgets all history. */
  void reset();
  /** @brief Pushes this frame's ranges and writes intensities; NaNs filtered beams if enabled. */
  void apply(std::vector<float>& ranges, std::vector<float>& intensities);

private:
  int beams_ = 0, window_ = 1, head_ = 0, filled_ = 0;
  float distance_ = 1.0f, min_intensity_ = 0.0f;
  bool filter_ = false;
  std::vector<float> history_;  // window_ x beams_, NaN = not finite
  std::vector<float> sum_;         // per beam: sum of the window's finite ranges (scratch of apply)
  std::vector<std::int32_t> count_;  // per beam: their number
};

}  // namespace kinect_pipeline
