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

  /** @return predicted floor depth at pixel (u, r) [m], +Inf where the ray never meets the floor. */
  double floorDepth(int u, int r) const;
  /** @return predicted ceiling-plane depth at pixel (u, r) [m], +Inf where the ray never meets it. */
  double ceilingDepth(int u, int r) const;

private:
  std::vector<float> col_, row_;
  float floor_offset_ = 0.0f, ceiling_offset_ = 0.0f;
  bool valid_ = false;
  Camera camera_;
  Geometry geometry_ = Geometry::kExact;
  double height_ = 0.0, ceiling_ = 0.0, pitch_ = 0.0, roll_ = 0.0;
};

}  // namespace kinect_pipeline
