// The floor refinement (stages/floor_fit.h). Design notes and measurements: docs/floor_refinement.md.
#include "kinect_pipeline/stages/floor_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/plane_fit.h"
#include "kinect_pipeline/model/pose.h"
#include "stages/floor_sampling.h"
#include "stages/normal_equations.h"
#include "stages/frame_common.h"

namespace kinect_pipeline
{
namespace
{
// Pixels sampled per frame, about (a regular grid of every stride-th pixel): a few thousand give the plane to a
// fraction of a millimetre at a few microseconds.
constexpr double kSamples = 2500.0;
constexpr int kRowStep = 2;
// Farther pixels are not sampled: the depth noise and the band of pose uncertainty both grow with distance.
constexpr float kMaxFitDepth = 4.0f;
// The fit's noise scale of a pixel is band / kBandSigmas: t(d) is about 4.5 sigma + 2 cm for the default curve.
constexpr float kBandSigmas = 3.0f;
// Tukey's biweight constant (95 % efficiency on Gaussian noise) in units of the noise scale.
constexpr float kTukey = 4.685f;
// The iterations grow a region from the robot outwards while the biweight's window narrows: the floor is the
// surface the robot stands on, so the nearest floor fixes the plane first (wide window: the whole band of pose
// uncertainty), and farther pixels join once the plane is known well enough to tell a lower level beyond a stair
// from the floor. Radii beyond the nearest sampled floor [m] (Inf: all) and window widths in noise scales.
struct Stage
{
  float radius, window;
};
constexpr Stage kStages[] = {{1.0f, 8.0f}, {2.0f, 4.0f}, {1e9f, 2.0f}, {1e9f, 1.0f}, {1e9f, 1.0f}, {1e9f, 1.0f}};
// The nearest sampled floor: the range within which this fraction of the candidates lie (outliers nearer do not
// count), from a histogram of kRangeBin bins.
constexpr double kNearFraction = 0.02;
constexpr float kRangeBin = 0.1f;
// Declines: the support's RMS residual in units of t(d) (pure noise about 0.33, residuals spread evenly over
// +-t(d): 0.58), and the largest standard deviation of a fitted term as a fraction of its bound.
constexpr double kMaxSpread = 0.5;
constexpr double kMaxStdOfBound = 0.5;
// A fit that moves the floor by less than this fraction of t(d) wherever it is seen is below the noise: the frame
// keeps the (corrected) prior, so that a well-known pose is not moved by noise and clutter (about 1 mm and 0.02 deg
// on the lab scene), and nothing is learned from it. A roll term alone below it is left out of the fit (decide()).
constexpr double kMinShift = 0.1;
// Beyond floor_max_*_error (the soft bounds) a fit is still accepted up to kHardBound times them when the frame
// supports it clearly: the image pixels on it at least kBeyondPixels times floor_min_pixels, and the prior's cost
// (Plane::cost) at least kBeyondGain times the fit's. A platform that rocks 2-3 deg, a mount that moved. Tables and
// beds (>= 0.45 m) lie far beyond any hard bound of the height.
constexpr double kHardBound = 2.0;
constexpr double kBeyondPixels = 2.0;
constexpr double kBeyondGain = 1.5;
constexpr double kNominalFramePeriod = 1.0 / 30.0;  // [s] between frames without stamps
constexpr int kLanes = detail::kNormalLanes;  // whole lanes of the normal equations' sums

bool poseIsValid(const SensorPose& p, const Config& c)
{
  return std::isfinite(p.height) && p.height > 0.0 && p.height < c.ceiling_height && std::fabs(p.pitch) <= kPi / 2 &&
         std::isfinite(p.roll);
}

/** Whether each term of c lies within factor times its floor_max_*_error. */
bool withinBounds(const PoseCorrection& c, const Config& cfg, double factor)
{
  return std::fabs(c.height) <= factor * cfg.floor_max_height_error &&
         std::fabs(c.pitch) <= factor * cfg.floor_max_pitch_error &&
         std::fabs(c.roll) <= factor * cfg.floor_max_roll_error;
}

SensorPose plus(const SensorPose& p, const PoseCorrection& c)
{
  return {p.height + c.height, p.pitch + c.pitch, wrapAngle(p.roll + c.roll)};  // roll: upside down is +-pi
}

PoseCorrection minus(const SensorPose& a, const SensorPose& b)
{
  return {a.height - b.height, a.pitch - b.pitch, wrapAngle(a.roll - b.roll)};
}

template <typename T>
float thresholdOf(const ThresholdLut& lut, T v, float z)
{
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return lut.forValue(v);
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return lut.forMillimetres(v);
  else
    return lut.forDepth(z);
}
}  // namespace

std::string toString(FloorFitStatus s)
{
  switch (s)
  {
    case FloorFitStatus::kOff:
      return "off";
    case FloorFitStatus::kAccepted:
      return "accepted";
    case FloorFitStatus::kTooFewPixels:
      return "too few pixels";
    case FloorFitStatus::kSpreadTooLarge:
      return "spread too large";
    case FloorFitStatus::kOutOfBounds:
      return "out of bounds";
    case FloorFitStatus::kIllConditioned:
      return "ill-conditioned";
    case FloorFitStatus::kNotBetter:
      return "not better than the prior";
  }
  return "unknown";
}

SensorPose poseFromFloorPlane(const SensorPose& prior, double a, double b, double c)
{
  // The plane's upward unit normal in the level frame, then in the optical frame (R^T n).
  const double norm = std::sqrt(1.0 + b * b + c * c);
  const double n_level[3] = {-b / norm, -c / norm, 1.0 / norm};
  const std::array<double, 9> m = levelFromOptical(prior.pitch, prior.roll);
  double n_opt[3];
  for (int j = 0; j < 3; ++j)
    n_opt[j] = m[j] * n_level[0] + m[3 + j] * n_level[1] + m[6 + j] * n_level[2];
  SensorPose out{-a / norm, 0.0, 0.0};  // the sensor's distance from the plane
  pitchRollFromUp(n_opt, out.pitch, out.roll);
  return out;
}

/** The fitted floor z = (a - h) + b x + c y in the level frame of the corrected prior, and how well it fits. */
struct FloorFit::Plane
{
  double a = 0.0, b = 0.0, c = 0.0;  // a: height of the floor above the prior's
  double std_a = 0.0, std_b = 0.0, std_c = 0.0;
  int support = 0;
  // How badly the fitted and the (corrected) prior's floor explain the candidates: the sum of their residuals'
  // squares in units of t(d), each at most 1 (a pixel off the floor counts once, however far).
  double cost = 0.0, prior_cost = 0.0;
  double spread = 0.0;
  double shift = 0.0;       // the largest move of the floor over the support, in units of t(d)
  double roll_shift = 0.0;  // the same of the roll term (c y) alone
};

template <typename T>
void FloorFit::sample(const cv::Mat& depth, const Camera& cam, const Config& cfg, const ThresholdLut& lut,
                      const SensorPose& prior)
{
  // The sampling grid (stages/floor_sampling.h).
  const detail::SampleGrid grid(cam.width, cam.height, kRowStep, kSamples);
  const int rows = grid.rows(cam.height);
  col_step_ = grid.col_step;
  const std::size_t capacity = static_cast<std::size_t>(rows) * (cam.width / col_step_ + 1) + kLanes;
  for (auto* v : {&x_, &y_, &e_, &band_, &inv_sigma_, &range2_})
    v->resize(capacity);  // once per camera: never reallocates after the first frame
  col_x_.resize(cam.width);
  col_y_.resize(cam.width);
  col_z_.resize(cam.width);
  // The ray of pixel (u, r) in the level frame is a column term (xn times the rotation's first column) plus a row
  // term (yn times the second, plus the third).
  const std::array<double, 9> m = levelFromOptical(prior.pitch, prior.roll);
  for (int u = 0; u < cam.width; ++u)
  {
    const double xn = (u - cam.cx) / cam.fx;
    col_x_[u] = static_cast<float>(m[0] * xn);
    col_y_[u] = static_cast<float>(m[3] * xn);
    col_z_[u] = static_cast<float>(m[6] * xn);
  }
  const float scale = std::is_same_v<T, std::uint8_t> ? static_cast<float>(cfg.max_depth / 255.0)
                                                      : (std::is_same_v<T, std::uint16_t> ? 0.001f : 1.0f);
  const float dh = static_cast<float>(cfg.floor_max_height_error), dp = static_cast<float>(cfg.floor_max_pitch_error),
              dr = static_cast<float>(cfg.floor_max_roll_error), h = static_cast<float>(prior.height);
  int n = 0;
  for (int k = 0; k < rows; ++k)
  {
    const int r = k * kRowStep;
    const double yn = (r - cam.cy) / cam.fy;
    const float rx = static_cast<float>(m[1] * yn + m[2]), ry = static_cast<float>(m[4] * yn + m[5]),
                rz = static_cast<float>(m[7] * yn + m[8]);
    const T* row = depth.ptr<T>(r);
    const int r2 = r + detail::kGradRows;  // the row the column's depth gradient is read against
    const T* below = r2 < cam.height ? depth.ptr<T>(r2) : nullptr;
    const float rz2 = static_cast<float>(m[7] * ((r2 - cam.cy) / cam.fy) + m[8]);
    for (int u = grid.firstColumn(k); u < cam.width; u += col_step_)
    {
      const T v = row[u];
      const float z = detail::metresOf(v, scale), rise = col_z_[u] + rz;
      if (!(z > 0.0f && z <= kMaxFitDepth && rise < 0.0f))
        continue;  // unknown, too far, or a ray that never meets the floor
      const float x = z * (col_x_[u] + rx), y = z * (col_y_[u] + ry), e = h + z * rise;
      const float t = thresholdOf(lut, v, z), band = -rise * t;
      if (!(std::fabs(e) <= dh + std::fabs(x) * dp + std::fabs(y) * dr + band))
        continue;
      if (below && detail::looksVertical(z, rise, col_z_[u] + rz2, detail::metresOf(below[u], scale), t))
        continue;
      x_[n] = x;
      y_[n] = y;
      e_[n] = e;
      band_[n] = band;
      inv_sigma_[n] = kBandSigmas / band;
      range2_[n] = x * x + y * y;
      ++n;
    }
  }
  count_ = n;
  for (int i = n; i < n + kLanes; ++i)  // weightless padding up to whole vectors
    x_[i] = y_[i] = e_[i] = band_[i] = inv_sigma_[i] = range2_[i] = 0.0f;
}

std::vector<FloorFit::Point> FloorFit::points() const
{
  std::vector<Point> out;
  for (int i = 0; i < count_; ++i)
    out.push_back({x_[i], y_[i], e_[i], band_[i]});
  return out;
}

float FloorFit::nearestFloor() const
{
  std::array<int, static_cast<int>(kMaxFitDepth / kRangeBin) + 1> hist{};
  for (int i = 0; i < count_; ++i)
    ++hist[std::min(static_cast<int>(hist.size()) - 1, static_cast<int>(std::sqrt(range2_[i]) / kRangeBin))];
  const int enough = static_cast<int>(kNearFraction * count_);
  int seen = 0;
  for (std::size_t k = 0; k < hist.size(); ++k)
    if ((seen += hist[k]) > enough)
      return (k + 1) * kRangeBin;
  return kMaxFitDepth;
}

FloorFit::Plane FloorFit::fitPlane(const Config& cfg) const
{
  // Prior: each term ~ N(0, bound^2), so that a direction the pixels do not fix (a narrow strip of floor) stays at
  // the prior instead of following the noise. The pixels' weights are 1 / sigma^2: the prior counts for little
  // wherever there is floor to see.
  const double prior_w[3] = {1.0 / (cfg.floor_max_height_error * cfg.floor_max_height_error),
                             1.0 / (cfg.floor_max_pitch_error * cfg.floor_max_pitch_error),
                             1.0 / (cfg.floor_max_roll_error * cfg.floor_max_roll_error)};
  const int n = (count_ + kLanes - 1) / kLanes * kLanes;
  Plane p;
  double sums[9] = {};
  const float near = nearestFloor();
  for (const Stage& st : kStages)
  {
    const float radius = near + st.radius;
    detail::normalEquations(x_.data(), y_.data(), e_.data(), inv_sigma_.data(), range2_.data(), n, static_cast<float>(p.a),
                    static_cast<float>(p.b), static_cast<float>(p.c), 1.0f / (kTukey * st.window), radius * radius,
                    sums);
    const double reg[6] = {sums[0] + prior_w[0], sums[1], sums[2], sums[3] + prior_w[1], sums[4], sums[5] + prior_w[2]};
    double sol[3];
    if (!solvePlane(reg, sums + 6, sol))
      break;
    p.a = sol[0];
    p.b = sol[1];
    p.c = sol[2];
  }
  // Support and spread at the final plane; the terms' standard deviations from the pixels alone (the last
  // iteration's matrix), scaled by the spread actually seen (sigma = band / kBandSigmas is the model's).
  double ss = 0.0;
  for (int i = 0; i < count_; ++i)
  {
    const double r0 = e_[i] / band_[i], r = (e_[i] - (p.a + p.b * x_[i] + p.c * y_[i])) / band_[i];
    p.prior_cost += std::min(1.0, r0 * r0);
    p.cost += std::min(1.0, r * r);
    if (std::fabs(r) <= 1.0)
    {
      ++p.support;
      ss += r * r;
      p.shift = std::max(p.shift, std::fabs(p.a + p.b * x_[i] + p.c * y_[i]) / band_[i]);
      p.roll_shift = std::max(p.roll_shift, std::fabs(p.c * y_[i]) / band_[i]);
    }
  }
  p.spread = p.support ? std::sqrt(ss / p.support) : 0.0;
  double var[3];
  planeTermVariances(sums, var);
  const double k = std::max(1.0, kBandSigmas * p.spread);
  p.std_a = k * std::sqrt(var[0]);
  p.std_b = k * std::sqrt(var[1]);
  p.std_c = k * std::sqrt(var[2]);
  return p;
}

void FloorFit::decide(const Plane& p, const Config& cfg, const SensorPose& prior, FloorFitResult& out) const
{
  const SensorPose corrected = plus(prior, learned_);
  // A roll term below the noise is left out, as a whole fit below it is (kMinShift): the floor cannot tell it
  // from no roll correction, and a roll of exactly zero keeps the frame on the roll-free per-row paths.
  const double c = p.roll_shift < kMinShift ? 0.0 : p.c;
  const SensorPose fitted = poseFromFloorPlane(corrected, p.a - corrected.height, p.b, c);
  out.fit = minus(fitted, prior);
  out.support = p.support;
  out.shift = p.shift;
  out.pixels = p.support * kRowStep * col_step_;
  out.spread = p.spread;
  out.std = {p.std_a, p.std_b, p.std_c};
  if (out.pixels < cfg.floor_min_pixels)
    out.status = FloorFitStatus::kTooFewPixels;
  else if (p.spread > kMaxSpread)
    out.status = FloorFitStatus::kSpreadTooLarge;
  else if (!(p.std_a <= kMaxStdOfBound * cfg.floor_max_height_error &&
             p.std_b <= kMaxStdOfBound * cfg.floor_max_pitch_error &&
             p.std_c <= kMaxStdOfBound * cfg.floor_max_roll_error))
    out.status = FloorFitStatus::kIllConditioned;
  else if (p.shift >= kMinShift && p.cost > p.prior_cost)
    out.status = FloorFitStatus::kNotBetter;
  else if (!poseIsValid(fitted, cfg) || !withinBounds(out.fit, cfg, kHardBound) ||
           (!withinBounds(out.fit, cfg, 1.0) &&
            !(out.pixels >= kBeyondPixels * cfg.floor_min_pixels && p.cost * kBeyondGain <= p.prior_cost)))
    out.status = FloorFitStatus::kOutOfBounds;
  else
    out.status = FloorFitStatus::kAccepted;
}

PoseCorrection FloorFit::priorWeight(const Config& cfg)
{
  return {1.0 / (cfg.floor_max_height_error * cfg.floor_max_height_error),
          1.0 / (cfg.floor_max_pitch_error * cfg.floor_max_pitch_error),
          1.0 / (cfg.floor_max_roll_error * cfg.floor_max_roll_error)};
}

void FloorFit::learn(const FloorFitResult& out, const Config& cfg, double stamp)
{
  double dt = kNominalFramePeriod;
  if (std::isfinite(stamp))
  {
    dt = has_stamp_ ? std::max(0.0, stamp - last_stamp_) : kNominalFramePeriod;
    last_stamp_ = stamp;
    has_stamp_ = true;
  }
  last_dt_ = dt;
  if (!(cfg.floor_learn_time > 0.0))
    return;
  if (!has_weight_)
  {
    weight_ = priorWeight(cfg);
    has_weight_ = true;
  }
  // The learned correction is the mean of the accepted corrections, each weighted by its precision (1 / the
  // fitted term's variance) and by how recent it is (exp(-age / floor_learn_time)), the prior (bound^2) counting as
  // one more. A first good fit weighs far more than the prior: the correction holds from the first second on. At a
  // steady stream of fits of equal precision this is the low-pass learned += (1 - exp(-dt / T)) (fit - learned).
  const double decay = std::exp(-dt / cfg.floor_learn_time);
  weight_ = {weight_.height * decay, weight_.pitch * decay, weight_.roll * decay};
  if (!out.accepted() || out.shift < kMinShift)
    return;
  const auto step = [](double& learned, double& weight, double fit, double std) {
    const double w = std::isfinite(std) && std > 0.0 ? 1.0 / (std * std) : 0.0;
    weight += w;
    if (weight > 0.0)
      learned += w / weight * (fit - learned);
  };
  step(learned_.height, weight_.height, out.fit.height, out.std.height);
  step(learned_.pitch, weight_.pitch, out.fit.pitch, out.std.pitch);
  step(learned_.roll, weight_.roll, out.fit.roll, out.std.roll);
}

SensorPose FloorFit::refine(const cv::Mat& depth, const Camera& camera, const Config& config, const ThresholdLut& lut,
                            const SensorPose& prior, double stamp, FloorFitResult& out)
{
  out = FloorFitResult{};
  if (!config.refine_floor)
    return prior;
  SensorPose corrected = plus(prior, learned_);
  if (!poseIsValid(corrected, config))
    corrected = prior;
  switch (depth.type())
  {
    case CV_8UC1:
      sample<std::uint8_t>(depth, camera, config, lut, corrected);
      break;
    case CV_16UC1:
      sample<std::uint16_t>(depth, camera, config, lut, corrected);
      break;
    default:
      sample<float>(depth, camera, config, lut, corrected);
      break;
  }
  out.row_step = kRowStep;
  out.col_step = col_step_;
  out.candidates = count_;
  decide(fitPlane(config), config, prior, out);
  learn(out, config, stamp);
  out.learned = learned_;
  const SensorPose pose = out.accepted() && out.shift >= kMinShift ? plus(prior, out.fit) : corrected;
  out.applied = minus(pose, prior);
  return pose;
}

void FloorFit::learnProfile(const cv::Mat& depth, const Config& config, const ThresholdLut& lut,
                            const PlaneModel& planes, FloorFitResult& out)
{
  profile_.learn(depth, config, lut, planes, last_dt_, out.profile);
}

FloorFit::State FloorFit::state() const
{
  const double nan = std::numeric_limits<double>::quiet_NaN();
  return {learned_, has_stamp_ ? last_stamp_ : nan, has_weight_ ? weight_ : PoseCorrection{nan, nan, nan},
          profile_.bands()};
}

std::string FloorFit::stateProblem(const State& s, const Config& c)
{
  const auto text = [](double v) {
    std::ostringstream o;
    o << v;
    return o.str();
  };
  const auto bad = [&](const std::string& field, double v, const std::string& expected) {
    return "floor state: " + field + " = " + text(v) + ": expected " + expected;
  };
  const double bound[3] = {c.floor_max_height_error, c.floor_max_pitch_error, c.floor_max_roll_error};
  const double learned[3] = {s.learned.height, s.learned.pitch, s.learned.roll};
  const double weight[3] = {s.weight.height, s.weight.pitch, s.weight.roll};
  const char* term[3] = {"height", "pitch", "roll"};
  for (int i = 0; i < 3; ++i)
  {
    if (!(std::fabs(learned[i]) <= bound[i]))
      return bad(std::string("learned ") + term[i], learned[i],
                 "finite, within the config's floor_max_" + std::string(term[i]) + "_error " + text(bound[i]));
    if (!std::isnan(weight[i]) && !(std::isfinite(weight[i]) && weight[i] >= 0.0))
      return bad(std::string("weight of the learned ") + term[i], weight[i], "finite and >= 0, or none (NaN)");
  }
  if (std::isinf(s.last_stamp))
    return bad("last stamp", s.last_stamp, "finite, or none (NaN)");
  for (int k = 0; k < FloorProfileBands::kBands; ++k)
  {
    if (!std::isfinite(s.profile.bias[k]))
      return bad("profile bias " + std::to_string(k), s.profile.bias[k], "finite");
    if (!(std::isfinite(s.profile.weight[k]) && s.profile.weight[k] >= 0.0f))
      return bad("profile weight " + std::to_string(k), s.profile.weight[k], "finite and >= 0");
  }
  if (!(std::isfinite(s.profile.since_learned) && s.profile.since_learned >= 0.0))
    return bad("time since the profile learned", s.profile.since_learned, "finite and >= 0 [s]");
  return {};
}

void FloorFit::restore(const State& s)
{
  learned_ = s.learned;
  has_weight_ = std::isfinite(s.weight.height) && std::isfinite(s.weight.pitch) && std::isfinite(s.weight.roll);
  weight_ = has_weight_ ? s.weight : PoseCorrection{};
  has_stamp_ = std::isfinite(s.last_stamp);
  last_stamp_ = has_stamp_ ? s.last_stamp : 0.0;
  profile_.restore(s.profile);
}

void FloorFit::reset()
{
  learned_ = PoseCorrection{};
  weight_ = PoseCorrection{};
  has_weight_ = false;
  has_stamp_ = false;
  last_stamp_ = 0.0;
  profile_.reset();
}

}  // namespace kinect_pipeline
