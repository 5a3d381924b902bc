/**
 * @file plane_model.h
 * @brief Where the floor and the ceiling plane must appear in the image, from the sensor's pose.
 */
#pragma once

#include <vector>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/**
 * The floor's profile beyond the plane as a lift of the floor offset per ray: a ray of rise R < 0 meets the floor
 * the sensor sees at depth (floor_h + lift(R)) / -R instead of the plane's floor_h / -R. A table over the frame's
 * rises, read at the step below (one load, the same bits wherever a ray's rise is the same float).
 */
struct FloorLift
{
  const float* table = nullptr;  ///< lift [m] per step of rise from lo; nullptr: none (the plane alone)
  float lo = 0.0f;               ///< the lowest rise of the frame
  float inv_step = 0.0f;         ///< steps per unit of rise
  int last = 0;                  ///< the last step

  /** @return the step of the table a ray of rise @p rise reads: non-decreasing in the rise. */
  __attribute__((always_inline)) int step(float rise) const
  {
    float i = (rise - lo) * inv_step;
    i = i < static_cast<float>(last) ? i : static_cast<float>(last);
    i = i > 0.0f ? i : 0.0f;
    return static_cast<int>(i);
  }
  /** @return the lift [m] on a ray of rise @p rise (table != nullptr). */
  __attribute__((always_inline)) float at(float rise) const { return table[step(rise)]; }
  /** @return the floor offset on a ray of rise @p rise: the plane's @p floor_h plus the lift where there is one. */
  __attribute__((always_inline)) float floorAt(float floor_h, float rise) const
  {
    return table ? floor_h + at(rise) : floor_h;
  }
};

/**
 * Predicts the floor and the ceiling plane per pixel, as separable terms.
 *
 * For pixel (u, r) the ray's rise per metre of depth is s(u, r) = col(u) + row(r) (exact geometry:
 * the "up" component of the ray (xn, yn, 1) rotated by roll then pitch). A point at depth z on that ray is
 * h_floor + z * s above the floor, so the floor is at depth -h_floor / s (only where s < 0) and the
 * ceiling plane at ceiling_offset / s (only where s > 0). Updating is O(rows + cols) and is skipped when
 * neither pose nor camera nor config changed.
 *
 * The thesis mode reproduces eq 4.10-4.18: row angle (r - H/2) / H * vfov, floor intercept
 * cos(pitch) * h and ceiling intercept cos(pitch) * ceiling_height; it ignores roll (col(u) = 0).
 */
class PlaneModel
{
public:
  /**
   * @brief Recomputes the terms if anything changed.
   * @param height height of the optical centre above the floor [m]
   * @param pitch total pitch, sensor + base [rad], + looks down
   * @param roll total roll, sensor + base [rad], + right side down
   * @return true if the terms were recomputed
   */
  bool update(const Camera& camera, const Config& config, double height, double pitch, double roll);

  /** @return col(u) for every column (0 in thesis mode and without roll). */
  const std::vector<float>& colTerm() const { return col_; }
  /** @return row(r) for every row. */
  const std::vector<float>& rowTerm() const { return row_; }
  /** @return the floor's offset h_floor [m] (the sensor height). */
  float floorOffset() const { return floor_offset_; }
  /** @return the ceiling's offset [m]: ceiling_height - sensor_height (exact), ceiling_height (thesis). */
  float ceilingOffset() const { return ceiling_offset_; }

  /**
   * @brief Sets the floor's profile beyond the plane (stages/floor_fit.h, FloorProfile): the sensor sees the floor
   *        that the plane puts at depth D at D + bias(D), bias piecewise linear between the centres of bands of
   *        width band_width [m] (band k: [k, k + 1) band_width), flat beyond the first and last; empty: none.
   */
  void setProfile(const float* bias, int bands, float band_width);
  /** @return the profile as a lift of the floor offset per ray (table nullptr: none). */
  FloorLift lift() const;
  /** @return the floor's offset on a ray of rise @p rise: floorOffset() plus the profile's lift. */
  float floorAt(float rise) const { return lift().floorAt(floor_offset_, rise); }
  /** @return whether every column term is the same (no roll): each row has one rise, one floor offset. */
  bool oneRisePerRow() const { return one_rise_per_row_; }
  /** @return whether the column terms never decrease or never increase in u (so is each row's rise). */
  bool monotoneColumns() const { return monotone_columns_; }

  /** @return predicted floor depth at pixel (u, r) [m] (plane and profile), +Inf where the ray never meets it. */
  double floorDepth(int u, int r) const;
  /** @return predicted ceiling-plane depth at pixel (u, r) [m], +Inf where the ray never meets it. */
  double ceilingDepth(int u, int r) const;

private:
  void buildLift();

  static constexpr int kLiftSteps = 256;
  std::vector<float> col_, row_;
  std::vector<float> bias_;  // the profile per band [m]; empty: none
  float band_width_ = 0.0f;
  std::vector<float> lift_;  // kLiftSteps lifts from lift_lo_ (empty: no profile, or no ray meets the floor)
  float lift_lo_ = 0.0f, lift_inv_step_ = 0.0f;
  float floor_offset_ = 0.0f, ceiling_offset_ = 0.0f;
  bool one_rise_per_row_ = true;
  bool monotone_columns_ = true;
  bool valid_ = false;
  Camera camera_;
  Geometry geometry_ = Geometry::kExact;
  double height_ = 0.0, ceiling_ = 0.0, pitch_ = 0.0, roll_ = 0.0;
};

}  // namespace kinect_pipeline
