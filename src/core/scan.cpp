#include "kinect_pipeline/scan.h"

#include "simd.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace kinect_pipeline
{

void ScanProjector::configure(const Camera& camera, const Config& config)
{
  projection_ = config.projection;
  width_ = camera.width;
  height_ = camera.height;
  xn_.resize(width_);
  xe_.resize(width_ + 1);
  yn_.resize(height_);
  for (int u = 0; u < width_; ++u)
    xn_[u] = static_cast<float>((u - camera.cx) / camera.fx);
  for (int e = 0; e <= width_; ++e)
    xe_[e] = static_cast<float>((e - 0.5 - camera.cx) / camera.fx);
  for (int r = 0; r < height_; ++r)
    yn_[r] = static_cast<float>((r - camera.cy) / camera.fy);

  // Beam angle of each column edge in the column model: -theta_x (counter-clockwise from forward).
  const bool thesis_columns = projection_ == Projection::kColumn && config.geometry == Geometry::kThesis;
  const double hfov = camera.hfov();
  std::vector<double> edge_angle(width_ + 1);
  for (int e = 0; e <= width_; ++e)
    edge_angle[e] = thesis_columns ? -((e - 0.5) - 0.5 * width_) / width_ * hfov
                                   : -std::atan((e - 0.5 - camera.cx) / camera.fx);

  double lo = edge_angle[width_], hi = edge_angle[0];
  if (config.scan_fov > 0.0)
  {
    lo = -0.5 * config.scan_fov;
    hi = 0.5 * config.scan_fov;
  }
  beams_ = config.scan_beams > 0 ? config.scan_beams : width_;
  const double inc = (hi - lo) / beams_;
  inc_ = static_cast<float>(inc);
  lo_ = static_cast<float>(lo);
  angle_min_ = static_cast<float>(lo + 0.5 * inc);
  angle_max_ = static_cast<float>(hi - 0.5 * inc);

  col_edge_bins_.resize(width_ + 1);
  col_factor_.resize(width_);
  for (int e = 0; e <= width_; ++e)
    col_edge_bins_[e] = static_cast<float>((edge_angle[e] - lo) / inc);
  col_centre_bins_.resize(width_);
  for (int u = 0; u < width_; ++u)
  {
    const double theta_x = thesis_columns ? (u - 0.5 * width_) / width_ * hfov : std::atan((u - camera.cx) / camera.fx);
    col_factor_[u] = static_cast<float>(1.0 / std::cos(theta_x));
    col_centre_bins_[u] = static_cast<float>((-theta_x - lo) / inc);
  }
  bx_.assign(height_, 1.0f);
  by_.assign(height_, 0.0f);
}

void ScanProjector::setPose(double pitch, double roll)
{
  if (projection_ == Projection::kColumn)
    return;
  // The ray (1, -xn, -yn) of the sensor frame rotated by roll about x, then pitch about y (see PlaneModel).
  const double sp = std::sin(pitch), cp = std::cos(pitch), sr = std::sin(roll), cr = std::cos(roll);
  ax_ = static_cast<float>(-sp * sr);
  ay_ = static_cast<float>(-cr);
  for (int r = 0; r < height_; ++r)
  {
    bx_[r] = static_cast<float>(cp - sp * cr * yn_[r]);
    by_[r] = static_cast<float>(sr * yn_[r]);
  }
}

const float* ScanProjector::rowEdgeBins(int r, float* buffer) const
{
  if (projection_ == Projection::kColumn)
    return col_edge_bins_.data();
  edgeBins(r, 0, width_, buffer);
  return buffer;
}

namespace
{
// Restrict parameters of a small function: the loops vectorise without a runtime alias check.
KP_CLONES void edgeBinLoop(const float* __restrict xe, int e0, int e1, float ax, float ay, float bx, float by, float lo,
                 float inv, float* __restrict out)
{
  for (int e = e0; e <= e1; ++e)
    out[e] = (fastAtan2(ay * xe[e] + by, ax * xe[e] + bx) - lo) * inv;
}

// The horizontal projection's: bin position (as edgeBinLoop for edges), bin and range of each pixel centre.
KP_CLONES void spanLoop(const float* __restrict xn, int u0, int u1, float ax, float ay, float bx, float by, float lo,
                        float inv, float beams, const float* __restrict z, float* __restrict fb,
                        std::int32_t* __restrict key, float* __restrict range)
{
  for (int u = u0; u <= u1; ++u)
  {
    const float x = ax * xn[u] + bx, y = ay * xn[u] + by;
    const float f = (fastAtan2(y, x) - lo) * inv;
    fb[u] = f;
    key[u] = binKey(f, beams);
    range[u] = z[u] * std::sqrt(x * x + y * y);
  }
}

// The column projection's: each column's bin position and range factor.
KP_CLONES void columnLoop(const float* __restrict cb, const float* __restrict k, int u0, int u1, float beams,
                          const float* __restrict z, float* __restrict fb, std::int32_t* __restrict key,
                          float* __restrict range)
{
  for (int u = u0; u <= u1; ++u)
  {
    fb[u] = cb[u];
    key[u] = binKey(cb[u], beams);
    range[u] = z[u] * k[u];
  }
}

}  // namespace

void ScanProjector::edgeBins(int r, int e0, int e1, float* out) const
{
  edgeBinLoop(xe_.data(), e0, e1, ax_, ay_, bx_[r], by_[r], lo_, 1.0f / inc_, out);
}

void ScanProjector::spanBins(int r, int u0, int u1, const float* depth, float* fb, std::int32_t* key,
                             float* range) const
{
  const float beams = static_cast<float>(beams_);
  if (projection_ == Projection::kColumn)
    columnLoop(col_centre_bins_.data(), col_factor_.data(), u0, u1, beams, depth, fb, key, range);
  else
    spanLoop(xn_.data(), u0, u1, ax_, ay_, bx_[r], by_[r], lo_, 1.0f / inc_, beams, depth, fb, key, range);
}

void ScanProjector::coverage(float& lo, float& hi) const
{
  if (projection_ == Projection::kColumn)
  {
    lo = std::min(col_edge_bins_.front(), col_edge_bins_.back());
    hi = std::max(col_edge_bins_.front(), col_edge_bins_.back());
    return;
  }
  lo = std::numeric_limits<float>::infinity();
  hi = -lo;
  const float inv = 1.0f / inc_;
  for (int r = 0; r < height_; ++r)
  {
    for (const float x : {xe_.front(), xe_.back()})
    {
      const float f = (fastAtan2(ay_ * x + by_[r], ax_ * x + bx_[r]) - lo_) * inv;
      lo = std::min(lo, f);
      hi = std::max(hi, f);
    }
  }
}

void Confidence::configure(int beams, const Config& config)
{
  const int window = config.confidence_window;
  if (beams != beams_ || window != window_)
  {
    beams_ = beams;
    window_ = window;
    history_.assign(static_cast<std::size_t>(beams_) * window_, std::numeric_limits<float>::quiet_NaN());
    head_ = 0;
  }
  distance_ = static_cast<float>(config.confidence_distance);
  min_intensity_ = static_cast<float>(config.min_intensity);
  filter_ = config.intensity_filter;
}

void Confidence::reset()
{
  std::fill(history_.begin(), history_.end(), std::numeric_limits<float>::quiet_NaN());
  head_ = 0;
}

void Confidence::apply(std::vector<float>& ranges, std::vector<float>& intensities)
{
  intensities.resize(ranges.size());
  float* slot = history_.data() + static_cast<std::size_t>(head_) * beams_;
  for (int b = 0; b < beams_; ++b)
    slot[b] = std::isfinite(ranges[b]) ? ranges[b] : std::numeric_limits<float>::quiet_NaN();
  head_ = (head_ + 1) % window_;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int b = 0; b < beams_; ++b)
  {
    const float d = ranges[b];
    if (std::isnan(d))
    {
      intensities[b] = 0.0f;
      continue;
    }
    if (std::isinf(d))
    {
      intensities[b] = 1.0f;
      continue;
    }
    float sum = 0.0f;
    int n = 0;
    for (int k = 0; k < window_; ++k)
    {
      const float h = history_[static_cast<std::size_t>(k) * beams_ + b];
      if (!std::isnan(h))
      {
        sum += h;
        ++n;
      }
    }
    const float mean = sum / n;  // n >= 1: this frame's finite range is in the window
    float i = 1.0f - std::fabs(d - mean) / distance_;
    i = std::min(1.0f, std::max(0.0f, i));
    intensities[b] = i;
    if (filter_ && i <= min_intensity_)
      ranges[b] = nan;
  }
}

}  // namespace kinect_pipeline
