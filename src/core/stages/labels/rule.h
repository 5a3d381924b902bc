// Private to the core: the plane removal's rule for one pixel (thesis section 4.4.1, with exact geometry), the one
// definition that the per-pixel labelling, the rescue, the value-threshold labelling and the proof that lets the
// latter search for thresholds all use. Design notes: docs/core_design.md ("The rule", "Labels by value").
#pragma once

#include <cstdint>
#include <type_traits>

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{
namespace detail
{
/**
 * The plane removal of one pixel. A pixel at depth d [m] whose ray rises by R metres per metre of depth
 * (PlaneModel: col[u] + row[r]; R < 0: the ray goes down) lies e = d R above the sensor and e + floor_h above the
 * floor (floor_h: floorAt(R), the plane's offset lifted by the floor's profile where one is learned); t = t(d) is
 * the noise threshold of its value. Exclusive classes, in this order:
 *   no return                              kInvalid
 *   e > ceil_h                             kAboveCeiling (beyond the ceiling plane)
 *   R < 0 and e + floor_h < farBand(t) R   kBelowFloor   (more than farBand(t) beyond the floor: a hole, a stair)
 *   R < 0 and e + floor_h < -nearBand(t) R kFloor        (less than nearBand(t) nearer than the floor)
 *   otherwise                              kKept
 * The bands are non-decreasing functions of t (the value labelling's proof needs it). The rescue (rescued()) uses
 * the same classes for the raw depth where the opening moved a pixel by more than moveBand(t(raw)).
 */
struct PlaneRule
{
  float scale;     ///< metres per unit of the encoding
  float floor_h;   ///< PlaneModel::floorOffset()
  float ceil_h;    ///< PlaneModel::ceilingOffset()
  FloorLift lift;  ///< PlaneModel::lift(): the floor's profile beyond the plane (table nullptr: none)

  /** @return the floor's offset on a ray of rise R: floor_h plus the profile's lift (PlaneModel::floorAt()). */
  __attribute__((always_inline)) float floorAt(float rise) const { return lift.floorAt(floor_h, rise); }

  /// How far beyond the floor a pixel is still floor [m], at threshold t.
  static float farBand(float t) { return t; }
  /// How far nearer than the floor a pixel is still floor [m], at threshold t.
  static float nearBand(float t) { return t; }
  /// How far the opening must have moved a pixel nearer for its raw depth to decide its label (the rescue) [m].
  static float moveBand(float t) { return t; }
  /**
   * A bound on the float error of label()'s below-floor test, fl(fl(d R) + floor_h) < fl(farBand(t) R), against
   * its exact G = floor_h + (d - farBand(t)) R, for |d R| <= dr and |farBand(t) R| <= tr: three roundings of values up
   * to |d R| + floor_h, and two of the band's product (one for farBand(t) itself where it is not exact), with 1 %
   * for the roundings of the bound (u = 2^-24).
   */
  static double belowTestError(double dr, double floor_h, double tr)
  {
    return 1.01 / 16777216.0 * (2.01 * dr + floor_h + 2.01 * tr);
  }

  /**
   * @return the label of a pixel of (mapped) value v with threshold t and rise R, on a ray whose floor offset is
   * fh (floorAt(R)); d its depth, keep whether it is kept, below whether it is below the floor. Branch-free
   * (exclusive masks combined arithmetically: a select chain would not vectorise); outputs by reference, as a
   * returned struct stops the vectoriser.
   */
  template <typename T>
  __attribute__((always_inline)) std::uint8_t label(T v, float t, float rise, float fh, float& d, bool& keep,
                                                    bool& below) const
  {
    d = static_cast<float>(v) * scale;
    const float e = d * rise;
    const float above = e + fh;             // height above the floor (exact geometry)
    const float far = farBand(t) * rise;    // -farBand(t) |R| where the ray goes down
    const float near = nearBand(t) * rise;  // -nearBand(t) |R|
    const bool down = rise < 0.0f;
    const bool inv = DepthTraits<T>::isNoReturn(v);
    const bool ceil = !inv & (e > ceil_h);
    below = !inv & !ceil & down & (above < far);
    const bool floor = !inv & !ceil & !below & down & (above < -near);
    keep = !(inv | ceil | below | floor);
    return static_cast<std::uint8_t>(inv * kInvalid + ceil * kAboveCeiling + below * kBelowFloor + floor * kFloor);
  }

  /// How far the opening moved a pixel of raw value raw to its opened value v [m], as the rescue computes it.
  template <typename T>
  __attribute__((always_inline)) float moved(T raw, T v) const
  {
    return static_cast<float>(raw) * scale - static_cast<float>(v) * scale;
  }

  /**
   * The rescue of a pixel labelled kept or below the floor at its opened value v, with the raw value raw (mapped,
   * not no return) and its threshold t_raw: where the opening moved it by more than moveBand(t_raw) and the raw
   * depth is beyond the ceiling plane or on the floor (strictly inside the band: not at its far edge itself),
   * @return that label, else kKept (no change). Not "below the floor": beyond an object's silhouette that would
   * turn noisy far floor into cliffs; at the rim of a hole the opening leaves an obstacle pixel, on the safe side.
   */
  template <typename T>
  std::uint8_t rescued(T raw, T v, float t_raw, float rise) const
  {
    if (!(moved(raw, v) > moveBand(t_raw)))
      return kKept;
    const float d = static_cast<float>(raw) * scale;
    const float e = d * rise;
    const float above = e + floorAt(rise);
    if (e > ceil_h)
      return kAboveCeiling;
    if (rise < 0.0f && above < -(nearBand(t_raw) * rise) && above > farBand(t_raw) * rise)
      return kFloor;
    return kKept;
  }
};

/** The threshold t [m] of a pixel value v of depth v * scale, from the table of its encoding. */
template <typename T>
__attribute__((always_inline)) inline float thresholdOf(const ThresholdLut& lut, T v, float scale)
{
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return lut.forValue(v);
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return lut.forMillimetres(v);  // forDepth(v * 0.001f), and scale is 0.001f
  else
    return lut.forDepth(static_cast<float>(v) * scale);
}

/** A labelled row's pixels per label, and what the labelling found on its way. */
struct RowCounts
{
  int kept = 0, invalid = 0, floor = 0, ceiling = 0;
  int candidates = 0;  ///< pixels flagged for the rescue
  /// First and last kept and below-floor column where the labelling found them on its way (-1: not known).
  int kept_first = -1, kept_last = -1, below_first = -1, below_last = -1;
  int below(int w) const { return w - kept - invalid - floor - ceiling; }
};

/** A frame's terms of the rule: the rule, the rise's terms per column and row, the threshold table. */
struct RuleTerms
{
  PlaneRule rule;
  const float* col;   ///< PlaneModel::colTerm()
  const float* row;   ///< PlaneModel::rowTerm()
  const ThresholdLut* lut;
  bool one_rise_per_row = false;  ///< PlaneModel::oneRisePerRow(): a row has one rise and one floor offset
  /// PlaneModel::monotoneColumns() and not ReferencePaths::labels: a floor profile's offsets from the row's few steps
  /// (liftRowByLookup(), liftRowByRuns())
  bool lift_by_runs = false;
  /// not ReferencePaths::portable: the pixels' thresholds by the gather kernel and a floor profile's offsets by the
  /// lookup kernel (liftRowByLookup()), else their plain loops
  bool vectors = false;
};
}  // namespace detail
}  // namespace kinect_pipeline
