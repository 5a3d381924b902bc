// The floor and ceiling predicted per pixel from the pose: the geometry in docs/how_it_works.md, "The steps".
#include "kinect_pipeline/model/plane_model.h"

#include <algorithm>
#include <cmath>
#include <functional>
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
  one_rise_per_row_ = std::adjacent_find(col_.begin(), col_.end(), std::not_equal_to<float>()) == col_.end();
  monotone_columns_ = std::is_sorted(col_.begin(), col_.end()) || std::is_sorted(col_.rbegin(), col_.rend());
  buildLift();
  return true;
}

void PlaneModel::setProfile(const float* bias, int bands, float band_width)
{
  if (bands <= 0)
  {
    bias_.clear();
    lift_.clear();
    return;
  }
  if (!lift_.empty() && band_width == band_width_ && std::equal(bias, bias + bands, bias_.begin(), bias_.end()))
    return;  // unchanged (the profile learns a few times a second)
  bias_.assign(bias, bias + bands);  // no allocation once the size is known
  band_width_ = band_width;
  buildLift();
}

namespace
{
// The profile's bias at depth D [m]: piecewise linear between the bands' centres, flat beyond.
float biasAt(const std::vector<float>& bias, float band_width, float depth)
{
  const float x = depth / band_width - 0.5f;
  if (!(x > 0.0f))
    return bias.front();
  const int k = static_cast<int>(x);
  if (k + 1 >= static_cast<int>(bias.size()))
    return bias.back();
  const float f = x - static_cast<float>(k);
  return bias[k] + f * (bias[k + 1] - bias[k]);
}
}  // namespace

void PlaneModel::buildLift()
{
  lift_.clear();
  if (bias_.empty() || col_.empty() || row_.empty())
    return;
  const float lo = *std::min_element(col_.begin(), col_.end()) + *std::min_element(row_.begin(), row_.end());
  if (!(lo < 0.0f))
    return;  // no ray meets the floor
  lift_lo_ = lo;
  lift_inv_step_ = kLiftSteps / -lo;
  lift_.resize(kLiftSteps);
  for (int i = 0; i < kLiftSteps; ++i)
  {
    // The middle of step i: a ray of rise R meets the plane at D = floor_h / -R and the sensed floor bias(D)
    // farther, floor_h + bias(D) (-R) above its depth's plane point: the lift.
    const float rise = lo * (1.0f - (static_cast<float>(i) + 0.5f) / kLiftSteps);
    lift_[i] = -rise * biasAt(bias_, band_width_, floor_offset_ / -rise);
  }
}

FloorLift PlaneModel::lift() const
{
  if (lift_.empty())
    return {};
  return {lift_.data(), lift_lo_, lift_inv_step_, kLiftSteps - 1};
}

double PlaneModel::floorDepth(int u, int r) const
{
  const float rise = col_[u] + row_[r];
  const double s = static_cast<double>(col_[u]) + row_[r];
  return s < 0.0 ? floorAt(rise) / -s : std::numeric_limits<double>::infinity();
}

double PlaneModel::ceilingDepth(int u, int r) const
{
  const double s = static_cast<double>(col_[u]) + row_[r];
  return s > 0.0 ? ceiling_offset_ / s : std::numeric_limits<double>::infinity();
}

}  // namespace kinect_pipeline
