// libFuzzer target of the C++ core (clang -fsanitize=fuzzer,address,undefined; see test/fuzz/CMakeLists.txt and
// scripts/fuzz.sh). The input bytes decide a camera model, a config (every field, the threshold curve as control
// points or as text), an image (type, size, stride, contents), poses and the calls made: construct, process a few
// frames, change config or camera between frames, reset, calibrate. Documented failures are std::invalid_argument
// (or a subclass); any other exception, a crash, a sanitizer report or a broken output invariant is a finding.
// The pipeline runs on a SIMD target the input picks (any this CPU has), beside a twin on the scalar target with
// the references of every fast path that claims the same bits (ReferencePaths: labels, opening, portable; not
// binning, whose bins may differ at a border): every output must be the twin's, bit for bit (core_design.md, "Fast
// paths and their references"), and both must refuse the same frames.
#include <fuzzer/FuzzedDataProvider.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <typeinfo>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/settings_exchange.h"
#include "kinect_pipeline/simd.h"
#include "kinect_pipeline/tools/calibration.h"

using namespace kinect_pipeline;

namespace
{
[[noreturn]] void finding(const std::string& what)
{
  std::fprintf(stderr, "FINDING: %s\n", what.c_str());
  std::abort();
}

void check(bool ok, const char* what)
{
  if (!ok)
    finding(std::string("output invariant broken: ") + what);
}

/** Mostly plausible values, sometimes anything a double can be (0, negative, huge, NaN, Inf). */
double number(FuzzedDataProvider& in, double lo, double hi)
{
  switch (in.ConsumeIntegralInRange<int>(0, 15))
  {
    case 0:
      return std::numeric_limits<double>::quiet_NaN();
    case 1:
      return in.ConsumeBool() ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity();
    case 2:
      return 0.0;
    case 3:
      return in.ConsumeFloatingPoint<double>();
    case 4:
      return -in.ConsumeFloatingPointInRange<double>(lo, hi);
    default:
      return in.ConsumeFloatingPointInRange<double>(lo, hi);
  }
}

int integer(FuzzedDataProvider& in, int lo, int hi)
{
  return in.ConsumeIntegralInRange<int>(0, 15) == 0 ? in.ConsumeIntegral<int>() : in.ConsumeIntegralInRange<int>(lo, hi);
}

Camera camera(FuzzedDataProvider& in)
{
  Camera c;
  c.width = integer(in, 1, 48);
  c.height = integer(in, 1, 48);
  c.fx = number(in, 1.0, 200.0);
  c.fy = in.ConsumeBool() ? c.fx : number(in, 1.0, 200.0);
  c.cx = in.ConsumeBool() ? (static_cast<double>(c.width) - 1.0) / 2.0 : number(in, -10.0, 60.0);
  c.cy = in.ConsumeBool() ? (static_cast<double>(c.height) - 1.0) / 2.0 : number(in, -10.0, 60.0);
  return c;
}

/** Where a field's values are drawn: its valid range (model/config_table.h), narrowed where that range is far wider
 *  than a fuzzer's 48-pixel images need (and sometimes reaching below it, to the values Config refuses). */
std::pair<double, double> span(const ConfigField& f)
{
  static const std::map<std::string, std::pair<double, double>> narrow{
      {"sensor_height", {0.05, 3.0}},      {"ceiling_height", {0.1, 5.0}},       {"max_depth", {0.1, 20.0}},
      {"open_kernel_size", {0, 9}},        {"range_min", {0.0, 2.0}},            {"range_max", {0.5, 12.0}},
      {"scan_beams", {0, 300}},            {"cliff_min_pixels", {0, 5}},         {"confidence_window", {0, 8}},
      {"confidence_distance", {0.001, 1.0}}, {"num_threads", {0, 3}},            {"floor_max_height_error", {0.0, 0.3}},
      {"floor_max_pitch_error", {0.0, 0.2}}, {"floor_max_roll_error", {0.0, 0.2}}, {"floor_min_pixels", {0, 3000}},
      {"floor_learn_time", {0.0, 5.0}},
  };
  const auto it = narrow.find(f.name);
  return it != narrow.end() ? it->second : std::make_pair(f.lo, f.hi);
}

void curve(FuzzedDataProvider& in, Config& k)
{
  if (in.ConsumeBool())
  {
    const std::string text = in.ConsumeRandomLengthString(64);
    k.threshold_curve = parseThresholdCurve(text);  // may throw invalid_argument: documented
  }
  else if (in.ConsumeBool())
  {
    k.threshold_curve.clear();
    const int n = in.ConsumeIntegralInRange<int>(0, 6);
    for (int i = 0; i < n; ++i)
      k.threshold_curve.push_back({number(in, 0.1, 12.0), number(in, 0.001, 1.0)});
  }
}

/** Every field of the table, drawn as its kind says. */
Config config(FuzzedDataProvider& in)
{
  Config k;
  if (in.ConsumeBool())
    return k;  // the defaults, often
  for (const ConfigField& f : configFields())
  {
    const auto [lo, hi] = span(f);
    switch (f.kind)
    {
      case FieldKind::kReal:
        f.setNumber(k, number(in, lo, hi));
        break;
      case FieldKind::kInteger:
        f.setNumber(k, integer(in, static_cast<int>(lo), static_cast<int>(hi)));
        break;
      case FieldKind::kFlag:
        f.setNumber(k, in.ConsumeBool() ? 1.0 : 0.0);
        break;
      case FieldKind::kChoice:
        f.setText(k, f.choices[in.ConsumeIntegralInRange<std::size_t>(0, f.choices.size() - 1)]);
        break;
      case FieldKind::kCurve:
        curve(in, k);
        break;
    }
  }
  return k;
}

/** An image of the decoded type; its size follows the camera unless the input says otherwise. */
cv::Mat image(FuzzedDataProvider& in, const Camera& cam, int& type)
{
  static const int kTypes[] = {CV_8UC1, CV_16UC1, CV_32FC1, CV_8UC3, CV_64FC1, CV_16SC1};
  type = in.ConsumeIntegralInRange<int>(0, 15) == 0 ? kTypes[in.ConsumeIntegralInRange<int>(3, 5)]
                                                    : kTypes[in.ConsumeIntegralInRange<int>(0, 2)];
  int w = cam.width, h = cam.height;
  if (w < 1 || w > 48 || h < 1 || h > 48 || in.ConsumeIntegralInRange<int>(0, 15) == 0)
  {
    w = in.ConsumeIntegralInRange<int>(0, 48);
    h = in.ConsumeIntegralInRange<int>(0, 48);
  }
  if (w == 0 || h == 0)
    return cv::Mat(h, w, type);
  // Sometimes a crop of a larger image: rows not contiguous with each other (any row step).
  const int pad = in.ConsumeBool() ? in.ConsumeIntegralInRange<int>(1, 5) : 0;
  cv::Mat big(h + pad, w + pad, type, cv::Scalar::all(0));
  cv::Mat m = big(cv::Rect(pad, pad / 2, w, h));
  const std::size_t row_bytes = static_cast<std::size_t>(w) * m.elemSize();
  const int fill = in.ConsumeIntegralInRange<int>(0, 3);  // 0: the bytes as they come; else a scene-like ramp
  for (int r = 0; r < h; ++r)
  {
    std::uint8_t* p = m.ptr<std::uint8_t>(r);
    if (fill == 0)
    {
      const std::vector<std::uint8_t> bytes = in.ConsumeBytes<std::uint8_t>(row_bytes);
      std::copy(bytes.begin(), bytes.end(), p);
    }
    else
    {
      for (int u = 0; u < w; ++u)
      {
        const double metres = 0.5 + 6.0 * (h - r) / h + 0.01 * in.ConsumeIntegralInRange<int>(-20, 20);
        if (type == CV_8UC1)
          m.at<std::uint8_t>(r, u) = static_cast<std::uint8_t>(std::min(255.0, metres / 12.0 * 255.0));
        else if (type == CV_16UC1)
          m.at<std::uint16_t>(r, u) = static_cast<std::uint16_t>(metres * 1000.0);
        else if (type == CV_32FC1)
          m.at<float>(r, u) = static_cast<float>(fill == 3 && (u + r) % 7 == 0 ? number(in, 0.0, 10.0) : metres);
      }
    }
  }
  return m;
}

void checkResult(const FrameResult& r, const cv::Mat& depth, const Pipeline& p, const SensorPose& prior)
{
  const Config& c = p.config();
  const FloorFitResult& f = r.floor_fit;
  check(static_cast<int>(f.status) < kNumFloorFitStatus, "a known floor fit status");
  check(c.refine_floor || (f.status == FloorFitStatus::kOff && r.pose.height == prior.height &&
                           r.pose.pitch == prior.pitch && r.pose.roll == prior.roll),
        "refine_floor off: the prior exactly");
  check(std::isfinite(r.pose.height) && r.pose.height > 0.0 && r.pose.height < c.ceiling_height,
        "the pose processed at is a valid pose");
  if (f.accepted())
    check(std::fabs(r.pose.height - prior.height) <= c.floor_max_height_error * (1 + 1e-9) &&
              std::fabs(r.pose.pitch - prior.pitch) <= c.floor_max_pitch_error * (1 + 1e-9) &&
              std::fabs(r.pose.roll - prior.roll) <= c.floor_max_roll_error * (1 + 1e-9),
          "an accepted floor fit moves the pose within the bounds");
  check(f.support <= f.candidates && f.pixels >= 0, "the fit's support is among its candidates");
  check(r.depth.size() == depth.size() && r.depth.type() == depth.type(), "cleaned depth has the input's size/type");
  check(r.labels.size() == depth.size() && r.labels.type() == CV_8UC1, "labels are CV_8UC1 of the input's size");
  std::uint64_t total = 0;
  for (auto n : r.counts)
    total += n;
  check(total == static_cast<std::uint64_t>(depth.total()), "label counts add up to the pixels");
  for (int y = 0; y < r.labels.rows; ++y)
    for (int x = 0; x < r.labels.cols; ++x)
      check(r.labels.at<std::uint8_t>(y, x) < kNumLabels, "labels are 0..4");
  check(r.scan.ranges.size() == r.scan.intensities.size(), "one intensity per range");
  check(static_cast<int>(r.scan.ranges.size()) == p.projector().beams(), "one range per beam");
  for (float i : r.scan.intensities)
    check(i >= 0.0f && i <= 1.0f, "intensities within [0, 1]");
  for (float v : r.scan.ranges)
    check(std::isnan(v) || std::isinf(v) || (v >= r.scan.range_min && v <= r.scan.range_max),
          "finite ranges within [range_min, range_max]");
  if (p.config().cliff_scan)
    check(r.cliff.ranges.size() == r.scan.ranges.size(), "the cliff scan has the beams of the scan");
  else
    check(r.cliff.ranges.empty(), "no cliff scan when cliff_scan is off");
}

/** Bit for bit, NaN equal to NaN (its payload aside). */
bool sameFloats(const std::vector<float>& a, const std::vector<float>& b)
{
  if (a.size() != b.size())
    return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!(a[i] == b[i] || (std::isnan(a[i]) && std::isnan(b[i]))) || std::signbit(a[i]) != std::signbit(b[i]))
      return false;
  return true;
}

bool sameImage(const cv::Mat& a, const cv::Mat& b)
{
  if (a.size() != b.size() || a.type() != b.type())
    return false;
  const std::size_t row = a.cols * a.elemSize();
  for (int y = 0; y < a.rows; ++y)
    if (std::memcmp(a.ptr(y), b.ptr(y), row) != 0)
      return false;
  return true;
}

/** The frame of the SIMD target with the fast paths and that of the scalar twin with their references: every
 *  output the same. */
void checkTwin(const FrameResult& r, const FrameResult& t, const std::string& target)
{
  const auto same = [&](bool ok, const char* what) {
    if (!ok)
      finding("SIMD target " + target + " with the fast paths differs from the references on the scalar target: " +
              what);
  };
  same(sameImage(r.labels, t.labels), "labels");
  same(sameImage(r.depth, t.depth), "cleaned depth");
  same(r.counts == t.counts, "label counts");
  same(sameFloats(r.scan.ranges, t.scan.ranges), "scan ranges");
  same(sameFloats(r.scan.intensities, t.scan.intensities), "scan intensities");
  same(sameFloats(r.cliff.ranges, t.cliff.ranges), "cliff ranges");
  same(r.floor_fit.status == t.floor_fit.status && r.pose.height == t.pose.height && r.pose.pitch == t.pose.pitch &&
           r.pose.roll == t.pose.roll,
       "floor fit");
}

/** Runs step on the target, then twin_step on the scalar target; both must throw invalid_argument or neither. */
template <typename Step, typename TwinStep>
void onBoth(const std::string& target, const Step& step, const TwinStep& twin_step)
{
  bool threw = false, twin_threw = false;
  restrictSimd(target);
  try
  {
    step();
  }
  catch (const std::invalid_argument&)
  {
    threw = true;
  }
  restrictSimd("scalar");
  try
  {
    twin_step();
  }
  catch (const std::invalid_argument&)
  {
    twin_threw = true;
  }
  if (threw != twin_threw)
    finding("SIMD target " + target + (threw ? " refused" : " took") + " what the scalar twin " +
            (twin_threw ? "refused" : "took"));
  if (threw)
    throw std::invalid_argument("refused by both");
}

SensorPose pose(FuzzedDataProvider& in)
{
  return SensorPose{number(in, 0.05, 3.0), number(in, -1.6, 1.6), number(in, -1.6, 1.6)};
}

void run(FuzzedDataProvider& in)
{
  restrictSimd("native");  // whatever the input before left: an input replays alone as it ran
  const int what = in.ConsumeIntegralInRange<int>(0, 9);
  if (what == 0)
  {
    // The threshold curve's text form, round trip.
    const std::vector<CurvePoint> c = parseThresholdCurve(in.ConsumeRandomLengthString(128));
    validateThresholdCurve(c);
    const std::vector<CurvePoint> back = parseThresholdCurve(formatThresholdCurve(c));
    check(back.size() == c.size(), "a formatted curve parses into as many points");
    return;
  }
  if (what == 1)
  {
    // A transform (tf) to a pose, then a frame at it: a pose out of range is refused, not used.
    RigidTransform t;
    for (double& q : t.q)
      q = number(in, -1.0, 1.0);
    for (double& x : t.t)
      x = number(in, -2.0, 2.0);
    double yaw = 0.0;
    const SensorPose sp = poseFromOpticalTransform(t, number(in, -1.0, 1.0), yaw);
    const Camera cam(32, 24, 30.0, 30.0, 15.5, 11.5);
    Pipeline p(cam, Config());
    FrameResult r;
    const cv::Mat depth(24, 32, CV_16UC1, cv::Scalar(1500));
    p.process(depth, sp, r);
    checkResult(r, depth, p, sp);
    return;
  }
  if (what == 2)
  {
    // Floor calibration of an arbitrary float frame.
    const Camera cam = camera(in);
    int type = 0;
    const cv::Mat depth = image(in, cam, type);
    CalibrationOptions o;
    o.iterations = in.ConsumeIntegralInRange<int>(1, 50);
    o.stride = in.ConsumeIntegralInRange<int>(1, 3);
    const FloorPose fp = calibrateFromFloor(depth, cam, o);
    check(!fp.found || (std::isfinite(fp.height) && std::isfinite(fp.pitch) && std::isfinite(fp.roll)),
          "a found floor has a finite pose");
    return;
  }
  // The pipeline: construct, then a few frames with changes between them.
  const Camera cam = camera(in);
  const Config cfg = config(in);
  if (std::getenv("KP_FUZZ_VERBOSE"))  // to see what an artifact decodes to
    std::fprintf(stderr, "camera %s; config: height %g pitch %g roll %g ceiling %g max_depth %g geometry %s "
                 "projection %s kernel %d %s curve '%s' range %g..%g beams %d fov %g window %d distance %g "
                 "min_intensity %g filter %d threads %d\n",
                 cam.describe().c_str(), cfg.sensor_height, cfg.sensor_pitch, cfg.sensor_roll, cfg.ceiling_height,
                 cfg.max_depth, toString(cfg.geometry).c_str(), toString(cfg.projection).c_str(),
                 cfg.open_kernel_size, toString(cfg.open_kernel_shape).c_str(),
                 formatThresholdCurve(cfg.threshold_curve).c_str(), cfg.range_min, cfg.range_max, cfg.scan_beams,
                 cfg.scan_fov, cfg.confidence_window, cfg.confidence_distance, cfg.min_intensity,
                 cfg.intensity_filter, cfg.num_threads);
  static const std::vector<std::string> targets = simdTargets();
  const std::string target = targets[in.ConsumeIntegralInRange<std::size_t>(0, targets.size() - 1)];
  ReferencePaths plain = ReferencePaths::all();
  plain.binning = false;
  Pipeline p(cam, cfg), twin(cam, cfg, plain);
  FramePipeline fp;
  auto shared = std::make_shared<const Config>(cfg);
  FrameResult r, rt;
  const int frames = in.ConsumeIntegralInRange<int>(1, 4);
  for (int f = 0; f < frames && in.remaining_bytes() > 0; ++f)
  {
    int type = 0;
    const cv::Mat depth = image(in, p.camera(), type);
    const bool verbose = std::getenv("KP_FUZZ_VERBOSE") != nullptr;
    try
    {
      switch (in.ConsumeIntegralInRange<int>(0, 3))
      {
        case 0:
        {
          const double pitch = number(in, -0.5, 0.5), roll = number(in, -0.5, 0.5);
          if (verbose)
            std::fprintf(stderr, "frame %d (%s): %dx%d type %d, base pitch %g roll %g\n", f, target.c_str(),
                         depth.cols, depth.rows, type, pitch, roll);
          const double stamp = in.ConsumeBool() ? std::nan("") : number(in, -5.0, 5.0);
          const Config& c = p.config();
          onBoth(
              target,
              [&] {
                p.process(depth, pitch, roll, r, stamp);
                checkResult(r, depth, p, {c.sensor_height, c.sensor_pitch + pitch, c.sensor_roll + roll});
              },
              [&] { twin.process(depth, pitch, roll, rt, stamp); });
          checkTwin(r, rt, target);
          break;
        }
        case 1:
        {
          const SensorPose sp = pose(in);
          if (verbose)
            std::fprintf(stderr, "frame %d (%s): %dx%d type %d, pose %g %g %g\n", f, target.c_str(), depth.cols,
                         depth.rows, type, sp.height, sp.pitch, sp.roll);
          const double stamp = number(in, -5.0, 5.0);
          onBoth(
              target,
              [&] {
                p.process(depth, sp, r, stamp);
                checkResult(r, depth, p, sp);
              },
              [&] { twin.process(depth, sp, rt, stamp); });
          checkTwin(r, rt, target);
          break;
        }
        case 2:
          restrictSimd(target);
          fp.process(shared, p.camera(), depth, pose(in), r);
          break;
        default:
          p.reset();
          twin.reset();
          break;
      }
    }
    catch (const std::invalid_argument&)
    {
      // Documented: a bad frame changes nothing; the next one is processed.
    }
    try
    {
      const int change = in.ConsumeIntegralInRange<int>(0, 3);
      if (change == 1)
      {
        const Config next = config(in);
        onBoth(target, [&] { p.setConfig(next); }, [&] { twin.setConfig(next); });
        shared = std::make_shared<const Config>(next);
      }
      else if (change == 2)
      {
        const Camera next = camera(in);
        onBoth(target, [&] { p.setCamera(next); }, [&] { twin.setCamera(next); });
      }
    }
    catch (const std::invalid_argument&)
    {
    }
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  FuzzedDataProvider in(data, size);
  try
  {
    run(in);
  }
  catch (const std::invalid_argument&)
  {
    // Documented for bad cameras, configs, curves, images and poses.
  }
  catch (const std::exception& e)
  {
    finding(std::string("undocumented exception ") + typeid(e).name() + ": " + e.what());
  }
  catch (...)
  {
    finding("an exception of unknown type");
  }
  return 0;
}
