// Private to the core: what makes below-floor pixels a cliff (a hole, a stair down), the one definition that the
// cliff binning (stage 2) and the cliff scan (stage 3) use. Design notes: docs/negative_obstacles.md ("Evidence").
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/threshold_curve.h"

namespace kinect_pipeline
{
namespace detail
{
/**
 * A below-floor pixel (more than t(d) beyond the predicted floor) is cliff evidence only where a real drop of at
 * least min_drop would be told from the sensor's noise, and only when it lies that far below the floor:
 *   - the drop: its height below the floor, -(floor_h + d R), is at least min_drop. Depth errors at grazing angles
 *     (a stereo camera's far-range bias, the smear between the floor and what stands on it) are large in depth but
 *     small in height; a stair or a hole of the configured size is not.
 *   - the range: d <= max_depth, the largest depth at which a drop of min_drop puts the lower level more than t(d)
 *     beyond the floor (d min_drop / (floor_h + min_drop) >= t(d)): beyond it, noise and bias alone make drops of
 *     that size.
 * And a beam's cliff is hidden when the beam's nearest obstacle is no farther than the cliff plus t(obstacle): the
 * pixels sit at the obstacle itself (flying pixels along its base, the matching window's smear between the floor
 * and what stands on it) or behind it (its mirror image in a glossy floor lies below the floor at the object's
 * range, the smear of a farther background), and the robot stops for the obstacle first anyway.
 * min_drop = 0 turns all three off: every below-floor pixel counts, as before this rule existed.
 */
struct CliffRule
{
  static constexpr double kSearchDepth = 30.0;  ///< [m] beyond any floor a depth camera of this field sees

  float min_drop = 0.0f;                                    ///< Config::cliff_min_drop [m]
  float floor_h = 0.0f;                                     ///< the sensor's height above the floor [m]
  float max_depth = std::numeric_limits<float>::infinity();  ///< [m]
  FloorLift lift;  ///< the floor's profile (PlaneModel::lift()): drops are measured from the floor the sensor sees

  /**
   * The rule at a frame's height: max_depth, the far end of the first range of depths (from the sensor out, up to
   * max_range) where d k >= t(d), k = min_drop / (floor_h + min_drop), exactly (t is piecewise linear, constant
   * outside its control points: so is f = d k - t). Only the first: beyond a curve's last point its threshold stays
   * constant while a real sensor's noise keeps growing.
   */
  static CliffRule at(const Config& config, float floor_h, double max_range = kSearchDepth, FloorLift lift = {})
  {
    CliffRule c;
    c.min_drop = static_cast<float>(config.cliff_min_drop);
    c.floor_h = floor_h;
    c.lift = lift;
    if (!(c.min_drop > 0.0f))
      return c;
    const double k = config.cliff_min_drop / (floor_h + config.cliff_min_drop);
    const std::vector<CurvePoint>& curve = config.threshold_curve;
    // The segments' ends: 0, the curve's points below max_range, max_range (no allocation: a frame's work).
    const auto knot = [&](std::size_t i) {
      return i == 0 ? 0.0 : (i <= curve.size() ? std::min(curve[i - 1].depth, max_range) : max_range);
    };
    double best = 0.0;
    for (std::size_t i = 0; i <= curve.size(); ++i)
    {
      const double d0 = knot(i), d1 = knot(i + 1);
      if (!(d1 > d0))
        continue;
      const double f0 = d0 * k - evaluateCurve(curve, d0), f1 = d1 * k - evaluateCurve(curve, d1);
      if (f1 >= 0.0)
        best = d1;  // visible to the segment's end (entering the range here or already in it)
      else if (f0 >= 0.0)
        return c.withMaxDepth(d0 + f0 / (f0 - f1) * (d1 - d0));  // leaving the range within the segment
      else if (best > 0.0)
        return c.withMaxDepth(best);  // left it at the segment's start
    }
    return c.withMaxDepth(best);
  }

  CliffRule withMaxDepth(double d) const
  {
    CliffRule c = *this;
    c.max_depth = static_cast<float>(d);
    return c;
  }

  /** @return whether a below-floor pixel at depth d [m] on a ray of rise R is cliff evidence. */
  bool evidence(float d, float rise) const
  {
    return !(min_drop > 0.0f) || (d <= max_depth && d * rise + lift.floorAt(floor_h, rise) < -min_drop);
  }

  /** @return whether a beam's cliff at range cliff [m] is hidden by its nearest obstacle at range obstacle [m]. */
  bool hidden(float cliff, float obstacle, const std::vector<CurvePoint>& curve) const
  {
    return min_drop > 0.0f && std::isfinite(cliff) && std::isfinite(obstacle) &&
           obstacle <= cliff + static_cast<float>(evaluateCurve(curve, obstacle));
  }
};
}  // namespace detail
}  // namespace kinect_pipeline
