// The floor and ceiling predicted per pixel from the pose: the geometry in docs/how_it_works.md, "The steps".
#include "kinect_pipeline/model/plane_model.h"

#include <cmath>
#include <limits>

#include "kinect_pipeline/model/pose.h"

namespace kinect_pipeline
{

bool PlaneModel::update(const Camera& camera, const Config& config, double height, double pitch, double roll)
{
  const Geometry geometry = config.geometry;
  if (valid_ && camera == camera_ && geometry == geometry_ && height_ == height &&
      ceiling_ == config.ceiling_height && pitch_ == pitch && roll_ == roll)
    return false;
  camera_ = camera;
  geometry_ = geometry;
  height_ = height;
  ceiling_ = config.ceiling_height;
  pitch_ = pitch;
  roll_ = roll;
  valid_ = true;

  col_.assign(camera.width, 0.0f);
  row_.assign(camera.height, 0.0f);
  floor_offset_ = static_cast<float>(height_);
  if (geometry == Geometry::kExact)
  {
    // The z (up) component of the ray (xn, yn, 1) in the level frame is the rise per metre of depth.
    const std::array<double, 9> m = levelFromOptical(pitch, roll);
    for (int u = 0; u < camera.width; ++u)
      col_[u] = static_cast<float>(m[6] * (u - camera.cx) / camera.fx);
    for (int r = 0; r < camera.height; ++r)
      row_[r] = static_cast<float>(m[8] + m[7] * (r - camera.cy) / camera.fy);
    ceiling_offset_ = static_cast<float>(ceiling_ - height_);
  }
  else
  {
    // Thesis eq 4.10-4.18: z = c / (tan(theta_pixel) + tan(pitch)) with c = cos(pitch) * h, expressed as
    // a rise per metre s = -(tan(theta_pixel) + tan(pitch)) / cos(pitch) so one kernel serves both modes.
    const double vfov = camera.vfov();
    const double tp = std::tan(pitch), cp = std::cos(pitch);
    for (int r = 0; r < camera.height; ++r)
    {
      const double theta = (r - 0.5 * camera.height) / camera.height * vfov;
      row_[r] = static_cast<float>(-(std::tan(theta) + tp) / cp);
    }
    ceiling_offset_ = static_cast<float>(ceiling_);
  }
  return true;
}

double PlaneModel::floorDepth(int u, int r) const
{
  const double s = static_cast<double>(col_[u]) + row_[r];
  return s < 0.0 ? floor_offset_ / -s : std::numeric_limits<double>::infinity();
}

double PlaneModel::ceilingDepth(int u, int r) const
{
  const double s = static_cast<double>(col_[u]) + row_[r];
  return s > 0.0 ? ceiling_offset_ / s : std::numeric_limits<double>::infinity();
}

}  // namespace kinect_pipeline
