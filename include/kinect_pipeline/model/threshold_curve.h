/**
 * @file threshold_curve.h
 * @brief The depth-dependent threshold t(d) (thesis fig 4.16) and its lookup table.
 */
#pragma once

#include <cstdint>
#include <vector>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/encoding.h"

namespace kinect_pipeline
{

/**
 * @brief Piecewise-linear interpolation of the control points, flat beyond the first and last point.
 * @param curve control points, depths strictly increasing (see validateThresholdCurve())
 * @param depth depth along the optical axis [m]
 * @return t(depth) [m]
 */
double evaluateCurve(const std::vector<CurvePoint>& curve, double depth);

/**
 * @brief Checks a curve: at least 2 points, finite values, depths >= 0 and strictly increasing,
 *        thresholds > 0 and non-decreasing (the sensor's noise never shrinks with depth).
 * @throw std::invalid_argument naming the point, its value and what was expected.
 */
void validateThresholdCurve(const std::vector<CurvePoint>& curve);

/**
 * Lookup table of t(d) for one encoding: the per-pixel work is one load, never a function call.
 *
 * 8-bit frames index it by the pixel value; 16-bit and float frames by the depth in 1 cm cells.
 * Each cell holds max(t over the cell, one step of the encoding), so the threshold never drops below what
 * the encoding can resolve (8-bit: max_depth / 255 = 4.7 cm at 12 m; 16-bit: 1 mm).
 */
class ThresholdLut
{
public:
  static constexpr float kCellsPerMetre = 100.0f;  ///< cells of the depth-indexed table per metre

  /**
   * @brief Rebuilds the table.
   * @param curve validated control points [m]
   * @param encoding input encoding
   * @param max_depth depth of 8-bit value 255 [m]; also the last depth the table covers for the others
   */
  void build(const std::vector<CurvePoint>& curve, Encoding encoding, double max_depth);

  /** @return t [m] for a depth z [m] (16-bit and float tables). */
  float forDepth(float z) const
  {
    float i = z * kCellsPerMetre;
    i = i < last_ ? i : last_;
    i = i > 0.0f ? i : 0.0f;
    return table_[static_cast<int>(i)];
  }
  /** @return forDepth(v * 0.001f) for a 16-bit value v [mm] (16-bit table): one load, no conversion. */
  float forMillimetres(std::uint16_t v) const { return by_mm_[v]; }
  /** @return t [m] for an 8-bit pixel value (8-bit table). */
  float forValue(std::uint8_t v) const { return table_[v]; }
  /**
   * @return the threshold of each value of an integer encoding: the 8-bit table by pixel value, the 16-bit one by
   *         millimetres (65536 entries); null for float tables.
   */
  const float* valueTable() const
  {
    return encoding_ == Encoding::kMono8 ? table_.data() : (encoding_ == Encoding::kMono16 ? by_mm_.data() : nullptr);
  }
  /** @return the raw table (for tests and the thresholds' gather). */
  const std::vector<float>& table() const { return table_; }
  /** @return the last cell forDepth() reads (as a float: its clamp). */
  float lastCell() const { return last_; }

private:
  std::vector<float> table_;
  std::vector<float> by_mm_;  // 16-bit: forDepth of each value
  float last_ = 0.0f;
  Encoding encoding_ = Encoding::kFloat32;  // of the last build
};

}  // namespace kinect_pipeline
