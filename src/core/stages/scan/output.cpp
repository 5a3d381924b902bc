// Stage 3 of a frame (stages/scan/output.h): the threads' bins merged, the cliff scan, REP 117, and the beams' rolling
// confidence (Confidence, stages/scan.h). Design notes: docs/core_design.md ("Stage 3").
#include "stages/scan/output.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "kinect_pipeline/stages/scan.h"

namespace kinect_pipeline
{
namespace detail
{
void mergeBins(const std::vector<const BinScratch*>& team, int beams, bool squared, std::vector<float>& ranges)
{
  ranges.assign(beams, kInf);
  for (const BinScratch* s : team)
    for (int b = 0; b < beams; ++b)
      ranges[b] = std::min(ranges[b], s->bins[b + 1]);
  if (squared)
    for (float& r : ranges)
      r = std::sqrt(r);
}

void mergeCliff(const std::vector<const BinScratch*>& team, int beams, const Config& config, const CliffRule& rule,
                std::vector<std::int32_t>& count, std::vector<float>& scan, std::vector<float>& cliff)
{
  cliff.assign(beams, kInf);
  count.assign(beams, 0);
  for (const BinScratch* s : team)
  {
    for (int b = 0; b < beams; ++b)
    {
      cliff[b] = std::min(cliff[b], s->cliff_bins[b + 1]);
      count[b] += s->cliff_count[b + 1];
    }
  }
  for (int b = 0; b < beams; ++b)
  {
    if (count[b] < config.cliff_min_pixels || rule.hidden(cliff[b], scan[b], config.threshold_curve))
      cliff[b] = kInf;
    if (config.cliff_in_scan)
      scan[b] = std::min(scan[b], cliff[b]);
  }
  if (!config.cliff_scan)
    cliff.clear();
}

// Selects, in whole vectors.
void rep117(float* __restrict ranges, int n, float cov_lo, float cov_hi, float range_min, float range_max)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int b = 0; b < n; ++b)
  {
    const float r = ranges[b], fb = static_cast<float>(b);  // b < 2^24: b + 1 is exact either way
    const float clipped = r < range_min ? -kInf : (r > range_max ? kInf : r);
    ranges[b] = (fb + 1.0f <= cov_lo || fb > cov_hi) ? nan : clipped;
  }
}
}  // namespace detail

void Confidence::configure(int beams, const Config& config)
{
  const int window = config.confidence_window;
  if (beams != beams_ || window != window_)
  {
    beams_ = beams;
    window_ = window;
    history_.assign(static_cast<std::size_t>(beams_) * window_, std::numeric_limits<float>::quiet_NaN());
    sum_.assign(beams_, 0.0f);
    count_.assign(beams_, 0);
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

namespace
{
// Confidence::apply's sums over the window, beam by beam in the order of the window's slots (k outer, so that the
// loop runs over beams in whole vectors), NaN slots left out.
void windowSums(const float* __restrict history, int beams, int window, float* __restrict sum,
                std::int32_t* __restrict n)
{
  for (int b = 0; b < beams; ++b)
  {
    sum[b] = 0.0f;
    n[b] = 0;
  }
  for (int k = 0; k < window; ++k)
  {
    const float* h = history + static_cast<std::size_t>(k) * beams;
    for (int b = 0; b < beams; ++b)
    {
      const bool ok = h[b] == h[b];  // not NaN
      sum[b] += ok ? h[b] : 0.0f;    // the history holds ranges > 0: adding +0 changes nothing
      n[b] += ok;
    }
  }
}

// Intensity of each beam from its window's mean (see Confidence), NaN for filtered beams. Selects, no branches.
void intensityLoop(float* __restrict ranges, const float* __restrict sum, const std::int32_t* __restrict n,
                   int beams, float distance, float min_intensity, bool filter, float* __restrict out)
{
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (int b = 0; b < beams; ++b)
  {
    const float d = ranges[b];
    const bool is_nan = d != d, is_inf = d == inf || d == -inf;
    const float mean = sum[b] / static_cast<float>(n[b] > 0 ? n[b] : 1);  // n >= 1 where d is finite
    float i = 1.0f - std::fabs(d - mean) / distance;
    i = 0.0f < i ? i : 0.0f;  // std::min(1, std::max(0, i)), operand for operand
    i = i < 1.0f ? i : 1.0f;
    const float value = is_nan ? 0.0f : (is_inf ? 1.0f : i);
    out[b] = value;
    ranges[b] = (filter && !is_nan && !is_inf && value <= min_intensity) ? nan : d;
  }
}
}  // namespace

void Confidence::apply(std::vector<float>& ranges, std::vector<float>& intensities)
{
  intensities.resize(ranges.size());
  float* slot = history_.data() + static_cast<std::size_t>(head_) * beams_;
  for (int b = 0; b < beams_; ++b)
    slot[b] = std::isfinite(ranges[b]) ? ranges[b] : std::numeric_limits<float>::quiet_NaN();
  head_ = (head_ + 1) % window_;
  windowSums(history_.data(), beams_, window_, sum_.data(), count_.data());
  intensityLoop(ranges.data(), sum_.data(), count_.data(), beams_, distance_, min_intensity_, filter_,
                intensities.data());
}

}  // namespace kinect_pipeline
