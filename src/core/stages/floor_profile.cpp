// The floor profile (stages/floor_profile.h). Design notes: docs/floor_refinement.md ("The floor profile").
#include "kinect_pipeline/stages/floor_profile.h"

#include <algorithm>
#include <cmath>

#include "stages/floor_sampling.h"
#include "stages/frame_common.h"
#include "stages/labels/rule.h"

namespace kinect_pipeline
{
namespace
{
// Pixels sampled per frame, about, on the floor fit's grid (stages/floor_sampling.h) with every kRowStep-th row.
constexpr double kSamples = 2000.0;
constexpr int kRowStep = 4;
// A band learns from a frame only with this many floor samples (fewer give no median worth the name), and only
// when they are at least this fraction of the band's pixels with a depth: a band that mostly shows what stands on
// the floor (a wall, furniture) shows too little floor to tell its bias from the base of those.
constexpr int kMinSamples = 20;
constexpr double kMinFloorFraction = 0.5;
}  // namespace

FloorProfileBands FloorProfile::initial()
{
  FloorProfileBands b;
  b.weight.fill(1.0f);  // the prior, no bias, counts as one frame
  return b;
}

void FloorProfile::reset()
{
  bands_ = initial();
}

template <typename T>
void FloorProfile::sample(const cv::Mat& depth, const Config& cfg, const ThresholdLut& lut, const PlaneModel& planes)
{
  const int w = depth.cols, h_rows = depth.rows;
  const detail::SampleGrid grid(w, h_rows, kRowStep, kSamples);
  const int rows = grid.rows(h_rows), col_step = grid.col_step;
  const std::size_t capacity = static_cast<std::size_t>(rows) * (w / col_step + 1);
  for (auto* v : {&residual_, &sorted_})
    v->resize(capacity);  // once per camera
  band_.resize(capacity);
  const float scale = detail::depthScale<T>(cfg.max_depth), h = planes.floorOffset();
  const float bound = static_cast<float>(cfg.floor_profile_max);
  const float* col = planes.colTerm().data();
  const float* row_term = planes.rowTerm().data();
  seen_.fill(0);
  int n = 0;
  for (int k = 0; k < rows; ++k)
  {
    const int r = k * kRowStep, r2 = r + detail::kGradRows;
    const T* row = depth.ptr<T>(r);
    const T* below = r2 < h_rows ? depth.ptr<T>(r2) : nullptr;
    for (int u = grid.firstColumn(k); u < w; u += col_step)
    {
      const float z = detail::metresOf(row[u], scale), rise = col[u] + row_term[r];
      if (!(z > 0.0f && rise < 0.0f))
        continue;
      const float plane = h / -rise;  // the plane's depth on this ray
      const int band = static_cast<int>(plane / kBandWidth);
      if (!(plane < kBands * kBandWidth))
        continue;
      ++seen_[band];
      // Within floor_profile_max in height of the floor the profile predicts so far (not the noise band as well:
      // far away that would take in the base of a wall; where the noise is wider than the window, the median stays
      // near the profile's), and not a vertical surface.
      if (!(std::fabs(planes.floorAt(rise) + z * rise) <= bound))
        continue;
      const float t = detail::thresholdOf(lut, row[u], scale);
      if (below && detail::looksVertical(z, rise, col[u] + row_term[r2], detail::metresOf(below[u], scale), t))
        continue;
      residual_[n] = z - plane;
      band_[n] = static_cast<std::uint8_t>(band);
      ++n;
    }
  }
  count_ = n;
}

void FloorProfile::learn(const cv::Mat& depth, const Config& cfg, const ThresholdLut& lut, const PlaneModel& planes,
                         double dt, FloorProfileBands& out)
{
  // At most every kLearnPeriod (a profile changes slowly; the samples cost): the weights decay by the whole time.
  bands_.since_learned += dt;
  bands_.samples.fill(0);
  if (bands_.since_learned < FloorProfileBands::kLearnPeriod)
  {
    out = bands_;
    return;
  }
  dt = bands_.since_learned;
  bands_.since_learned = 0.0;
  switch (depth.type())
  {
    case CV_8UC1:
      sample<std::uint8_t>(depth, cfg, lut, planes);
      break;
    case CV_16UC1:
      sample<std::uint16_t>(depth, cfg, lut, planes);
      break;
    default:
      sample<float>(depth, cfg, lut, planes);
      break;
  }
  // The samples by band (a counting sort), then each band's median.
  std::array<int, kBands + 1> start{};
  for (int i = 0; i < count_; ++i)
    ++start[band_[i] + 1];
  for (int k = 0; k < kBands; ++k)
    start[k + 1] += start[k];
  std::array<int, kBands> fill{};
  for (int i = 0; i < count_; ++i)
    sorted_[start[band_[i]] + fill[band_[i]]++] = residual_[i];
  const double decay = cfg.floor_learn_time > 0.0 ? std::exp(-dt / cfg.floor_learn_time) : 1.0;
  const float h = planes.floorOffset();
  for (int k = 0; k < kBands; ++k)
  {
    const int n = start[k + 1] - start[k];
    bands_.samples[k] = n;
    bands_.weight[k] = static_cast<float>(bands_.weight[k] * decay);
    if (n < kMinSamples || n < kMinFloorFraction * seen_[k] || !(cfg.floor_learn_time > 0.0))
      continue;
    float* first = sorted_.data() + start[k];
    std::nth_element(first, first + n / 2, first + n);
    // A recency-weighted mean of the frames' medians, the prior (no bias) counting as one frame.
    bands_.weight[k] += 1.0f;
    bands_.bias[k] += (first[n / 2] - bands_.bias[k]) / bands_.weight[k];
    // Bounded in height: floor_profile_max at the band's centre is this much depth.
    const float limit = static_cast<float>(cfg.floor_profile_max) * (static_cast<float>(k) + 0.5f) * kBandWidth / h;
    bands_.bias[k] = std::clamp(bands_.bias[k], -limit, limit);
  }
  out = bands_;
}

}  // namespace kinect_pipeline
