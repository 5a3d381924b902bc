// The threshold curve t(d): where it comes from and how to fit one, docs/how_it_works.md, "Threshold curve", and
// docs/tools.md, "Threshold curve from data".
#include "kinect_pipeline/model/threshold_curve.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace kinect_pipeline
{

std::string toString(Encoding e)
{
  switch (e)
  {
    case Encoding::kMono8:
      return "8UC1";
    case Encoding::kMono16:
      return "16UC1";
    default:
      return "32FC1";
  }
}

double encodingStep(Encoding e, double max_depth)
{
  switch (e)
  {
    case Encoding::kMono8:
      return max_depth / 255.0;
    case Encoding::kMono16:
      return 0.001;
    default:
      return 0.0;
  }
}

double evaluateCurve(const std::vector<CurvePoint>& curve, double depth)
{
  if (depth <= curve.front().depth)
    return curve.front().threshold;
  if (depth >= curve.back().depth)
    return curve.back().threshold;
  const auto hi = std::upper_bound(curve.begin(), curve.end(), depth,
                                   [](double d, const CurvePoint& p) { return d < p.depth; });
  const auto lo = hi - 1;
  const double f = (depth - lo->depth) / (hi->depth - lo->depth);
  return lo->threshold + f * (hi->threshold - lo->threshold);
}

void validateThresholdCurve(const std::vector<CurvePoint>& curve)
{
  if (curve.size() < 2)
  {
    std::ostringstream s;
    s << "threshold_curve has " << curve.size() << " point(s): expected at least 2 'depth:threshold' points";
    throw std::invalid_argument(s.str());
  }
  for (std::size_t i = 0; i < curve.size(); ++i)
  {
    const CurvePoint& p = curve[i];
    std::ostringstream s;
    s << "threshold_curve point " << i << " (" << p.depth << " m: " << p.threshold << " m): ";
    if (!(std::isfinite(p.depth) && p.depth >= 0.0))
      throw std::invalid_argument(s.str() + "expected a finite depth >= 0 m");
    if (!(std::isfinite(p.threshold) && p.threshold > 0.0))
      throw std::invalid_argument(s.str() + "expected a finite threshold > 0 m");
    if (i > 0 && !(p.depth > curve[i - 1].depth))
      throw std::invalid_argument(s.str() + "expected depths strictly increasing (previous depth " +
                                  std::to_string(curve[i - 1].depth) + " m)");
    if (i > 0 && p.threshold < curve[i - 1].threshold)
      throw std::invalid_argument(s.str() + "expected thresholds non-decreasing with depth (previous " +
                                  std::to_string(curve[i - 1].threshold) + " m)");
  }
}

void ThresholdLut::build(const std::vector<CurvePoint>& curve, Encoding encoding, double max_depth)
{
  const double step = encodingStep(encoding, max_depth);
  encoding_ = encoding;
  by_mm_.clear();
  if (encoding == Encoding::kMono8)
  {
    table_.assign(256, 0.0f);
    for (int v = 0; v < 256; ++v)
    {
      // Value v stands for depths within half a step of v * step; take the largest threshold there.
      const double t = evaluateCurve(curve, (v + 0.5) * step);
      table_[v] = static_cast<float>(std::max(t, step));
    }
    last_ = 255.0f;
    return;
  }
  const double cover = std::max(max_depth, curve.back().depth) + 0.02;
  const int n = static_cast<int>(std::ceil(cover * kCellsPerMetre)) + 1;
  table_.assign(n, 0.0f);
  for (int i = 0; i < n; ++i)
  {
    // Cell i holds depths [i, i + 1) cm: its upper end has the largest threshold of a non-decreasing curve.
    const double t = evaluateCurve(curve, (i + 1) / static_cast<double>(kCellsPerMetre));
    table_[i] = static_cast<float>(std::max(t, step));
  }
  last_ = static_cast<float>(n - 1);
  if (encoding == Encoding::kMono16)
  {
    by_mm_.resize(65536);
    for (int v = 0; v < 65536; ++v)
      by_mm_[v] = forDepth(static_cast<float>(v) * 0.001f);  // as the pipeline computes a 16-bit depth
  }
}

}  // namespace kinect_pipeline
