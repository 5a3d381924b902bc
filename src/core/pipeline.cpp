#include "kinect_pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "kinect_pipeline/morphology.h"

namespace kinect_pipeline
{
namespace
{
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr double kHalfPi = 1.57079632679489661923;

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

int defaultThreads()
{
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

int threadId()
{
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

// Metres per unit of each encoding (8-bit: max_depth / 255).
template <typename T>
float depthScale(double max_depth)
{
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return static_cast<float>(max_depth / 255.0);
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return 0.001f;
  else
    return 1.0f;
}

struct RowCounts
{
  int kept = 0, invalid = 0, floor = 0, ceiling = 0;
};

/**
 * Plane removal of one row: labels, cleaned depth and the depth of kept pixels (+Inf for the others).
 * Branch-free, with restrict pointers, so that the compiler vectorises it.
 * @param rise_row the row's term of the rise per metre of depth (col[u] + rise_row < 0: the ray goes down)
 */
template <typename T>
RowCounts classifyRow(const T* __restrict src, const float* __restrict t, const float* __restrict col, float rise_row,
                      float scale, float floor_h, float ceil_h, int w, std::uint8_t* __restrict lab, T* __restrict dst,
                      float* __restrict z)
{
  using Tr = DepthTraits<T>;
  const T removed = Tr::removed();
  int n_kept = 0, n_invalid = 0, n_floor = 0, n_ceiling = 0;
  for (int u = 0; u < w; ++u)
  {
    const T v = src[u];
    const float d = static_cast<float>(v) * scale;
    const float rise = col[u] + rise_row;
    const float e = d * rise;
    const float above = e + floor_h;  // height above the floor (exact geometry)
    const float band = t[u] * rise;   // -t * |rise| where the ray meets the floor
    const bool down = rise < 0.0f;
    // Exclusive masks combined arithmetically (a select chain would not vectorise).
    const bool inv = Tr::isNoReturn(v);
    const bool ceil = !inv & (e > ceil_h);
    const bool below = !inv & !ceil & down & (above < band);
    const bool floor = !inv & !ceil & !below & down & (above < -band);
    const bool keep = !(inv | ceil | below | floor);
    lab[u] = static_cast<std::uint8_t>(inv * kInvalid + ceil * kAboveCeiling + below * kBelowFloor + floor * kFloor);
    dst[u] = keep ? v : removed;
    z[u] = keep ? d : kInf;
    n_kept += keep;
    n_invalid += inv;
    n_floor += floor;
    n_ceiling += ceil;
  }
  return {n_kept, n_invalid, n_floor, n_ceiling};
}

/**
 * Puts the ranges of one row's pixels into the bins each pixel overlaps (min per bin). fb holds the bin
 * positions of the row's w + 1 column edges, monotone along a row except where a row wraps behind the
 * sensor. Walking in the direction of increasing bins keeps the current bin's minimum in a register.
 */
void binRow(const float* fb, const float* range, int w, int beams, float half_turn_bins, float* bins)
{
  const bool reverse = fb[w] < fb[0];
  int cur = -2;
  float cur_min = kInf;
  auto flush = [&]() {
    if (cur >= 0 && cur < beams && cur_min < bins[cur])
      bins[cur] = cur_min;
  };
  for (int i = 0; i < w; ++i)
  {
    const int u = reverse ? w - 1 - i : i;
    const float r = range[u];
    if (!(r < kInf))
      continue;
    const float a = fb[u], b = fb[u + 1];
    float lo = a < b ? a : b, hi = a < b ? b : a;
    if (hi - lo > half_turn_bins || hi < 0.0f || lo >= static_cast<float>(beams))
      continue;  // outside the scan, or a pixel straddling the direction straight behind the sensor
    const int first = lo < 0.0f ? 0 : static_cast<int>(lo);
    const int last = hi >= static_cast<float>(beams) ? beams - 1 : static_cast<int>(hi);
    if (first != cur)
    {
      flush();
      cur = first;
      cur_min = r;
    }
    else if (r < cur_min)
    {
      cur_min = r;
    }
    while (cur < last)
    {
      flush();
      ++cur;
      cur_min = r;
    }
  }
  flush();
}
}  // namespace

/** Per-thread buffers, sized once per image size / beam count: no allocation per frame. */
struct Pipeline::Scratch
{
  std::vector<float> row, tmp;  // one image row of the input's type (floats are the widest)
  std::vector<float> t;         // threshold of each pixel of the row [m]
  std::vector<float> z;         // depth of kept pixels of the row [m], +Inf for removed ones
  std::vector<float> range;     // beam range of each pixel of the row [m], +Inf for removed ones
  std::vector<float> colmin;    // column projection: nearest kept depth per column [m]
  std::vector<float> edges;     // bin positions of the row's column edges
  std::vector<float> bins;      // nearest range per beam seen by this thread
  std::array<std::uint64_t, kNumLabels> counts{};
};

Pipeline::Pipeline(const Camera& camera, const Config& config)
{
  camera.validate();
  config.validate();
  camera_ = camera;
  config_ = config;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
}

Pipeline::~Pipeline() = default;

void Pipeline::setConfig(const Config& config)
{
  config.validate();
  config_ = config;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
  lut_valid_ = false;
  planes_ = PlaneModel();  // forces the terms to be recomputed
}

void Pipeline::setCamera(const Camera& camera)
{
  camera.validate();
  camera_ = camera;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
  planes_ = PlaneModel();
}

void Pipeline::reset() { confidence_.reset(); }

void Pipeline::prepareBuffers(int threads)
{
  if (static_cast<int>(scratch_.size()) < threads)
    scratch_.resize(threads);
  const std::size_t w = camera_.width;
  for (int i = 0; i < threads; ++i)
  {
    if (!scratch_[i])
      scratch_[i] = std::make_unique<Scratch>();
    Scratch& s = *scratch_[i];
    s.row.resize(w);
    s.tmp.resize(w);
    s.t.resize(w);
    s.z.resize(w);
    s.range.resize(w);
    s.colmin.resize(w);
    s.edges.resize(w + 1);
    s.bins.resize(projector_.beams());
  }
}

void Pipeline::process(const cv::Mat& depth, double base_pitch, double base_roll, FrameResult& out)
{
  if (!std::isfinite(base_pitch) || !std::isfinite(base_roll))
  {
    std::ostringstream s;
    s << "pose: base_pitch = " << base_pitch << " rad, base_roll = " << base_roll << " rad: expected finite values";
    throw std::invalid_argument(s.str());
  }
  process(depth, SensorPose{config_.sensor_height, config_.sensor_pitch + base_pitch, config_.sensor_roll + base_roll},
          out);
}

void Pipeline::process(const cv::Mat& depth, const SensorPose& pose, FrameResult& out)
{
  const auto t0 = Clock::now();
  if (depth.empty())
    throw std::invalid_argument("depth image is empty: expected a " + std::to_string(camera_.width) + "x" +
                                std::to_string(camera_.height) + " image");
  const int type = depth.type();
  if (depth.dims != 2 || (type != CV_8UC1 && type != CV_16UC1 && type != CV_32FC1))
    throw std::invalid_argument("depth image type " + cv::typeToString(type) + " with " +
                                std::to_string(depth.dims) + " dimensions: expected a 2-D 8UC1, 16UC1 or 32FC1 image");
  if (depth.cols != camera_.width || depth.rows != camera_.height)
  {
    std::ostringstream s;
    s << "depth image is " << depth.cols << "x" << depth.rows << " (width x height) but the camera model is "
      << camera_.width << "x" << camera_.height;
    throw std::invalid_argument(s.str());
  }
  const double pitch = pose.pitch, roll = pose.roll, height = pose.height;
  if (!std::isfinite(pitch) || !std::isfinite(roll) || std::fabs(pitch) > kHalfPi + 1e-9 ||
      std::fabs(roll) > kHalfPi + 1e-9)
  {
    std::ostringstream s;
    s << "pose: pitch = " << pitch << " rad, roll = " << roll
      << " rad (sensor + base): expected finite values with |pitch|, |roll| <= pi/2";
    throw std::invalid_argument(s.str());
  }
  if (!(std::isfinite(height) && height > 0.0 && height < config_.ceiling_height))
  {
    std::ostringstream s;
    s << "pose: height = " << height << " m: expected a sensor height > 0 and below ceiling_height = "
      << config_.ceiling_height << " m";
    throw std::invalid_argument(s.str());
  }

  if (planes_.update(camera_, config_, height, pitch, roll))
    projector_.setPose(pitch, roll);
  const Encoding enc = type == CV_8UC1 ? Encoding::kMono8 : (type == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32);
  if (!lut_valid_ || enc != lut_encoding_)
  {
    lut_.build(config_.threshold_curve, enc, config_.max_depth);
    lut_encoding_ = enc;
    lut_valid_ = true;
  }
  out.depth.create(depth.size(), type);
  out.labels.create(depth.size(), CV_8UC1);
  out.times.prepare = msSince(t0);

  switch (type)
  {
    case CV_8UC1:
      run<std::uint8_t>(depth, out);
      break;
    case CV_16UC1:
      run<std::uint16_t>(depth, out);
      break;
    default:
      run<float>(depth, out);
      break;
  }
  out.times.total = msSince(t0);
}

template <typename T>
void Pipeline::run(const cv::Mat& depth, FrameResult& out)
{
  using Tr = DepthTraits<T>;
  const int threads = config_.num_threads > 0 ? config_.num_threads : defaultThreads();
  prepareBuffers(threads);
  const int h = depth.rows, w = depth.cols;
  const int ksize = config_.open_kernel_size;
  const int rad = ksize >= 3 ? ksize / 2 : 0;
  const bool rect = config_.open_kernel_shape == KernelShape::kRect;

  // Stage 1: unknown -> no return, then the opening's erosion (or the whole OpenCV opening for other shapes).
  auto t1 = Clock::now();
  if (rad > 0 && rect)
  {
    eroded_.create(depth.size(), depth.type());
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int r = 0; r < h; ++r)
    {
      Scratch& s = *scratch_[threadId()];
      detail::erodeMappedRow<T>(depth, r, rad, reinterpret_cast<T*>(s.tmp.data()), eroded_.ptr<T>(r));
    }
  }
  else if (rad > 0)
  {
    mapped_.create(depth.size(), depth.type());
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int r = 0; r < h; ++r)
    {
      const T* in = depth.ptr<T>(r);
      T* m = mapped_.ptr<T>(r);
      for (int u = 0; u < w; ++u)
        m[u] = Tr::map(in[u]);
    }
    const int cv_shape = config_.open_kernel_shape == KernelShape::kCross ? cv::MORPH_CROSS : cv::MORPH_ELLIPSE;
    cv::morphologyEx(mapped_, opened_, cv::MORPH_OPEN, cv::getStructuringElement(cv_shape, cv::Size(ksize, ksize)));
  }
  out.times.erode = msSince(t1);

  // Stage 2, one fused loop over rows: dilation, plane removal, labels, cleaned depth, beam binning.
  t1 = Clock::now();
  const float scale = depthScale<T>(config_.max_depth);
  const float* col = planes_.colTerm().data();
  const float* rowterm = planes_.rowTerm().data();
  const float floor_h = planes_.floorOffset();
  const float ceil_h = planes_.ceilingOffset();
  const int beams = projector_.beams();
  const float half_turn_bins = 3.14159265f / projector_.angleIncrement();
  const ThresholdLut& lut = lut_;
  const bool column = projector_.projection() == Projection::kColumn;

#pragma omp parallel num_threads(threads)
  {
    Scratch& s = *scratch_[threadId()];
    std::fill(s.bins.begin(), s.bins.end(), kInf);
    s.counts.fill(0);
    T* row = reinterpret_cast<T*>(s.row.data());
    T* tmp = reinterpret_cast<T*>(s.tmp.data());
    float* z = s.z.data();
    float* bins = s.bins.data();
    if (column)
      std::fill(s.colmin.begin(), s.colmin.end(), kInf);

#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < h; ++r)
    {
      const T* src;
      if (rad > 0 && rect)
      {
        detail::rectRow<T, false>(eroded_, r, rad, tmp, row);
        src = row;
      }
      else if (rad > 0)
      {
        src = opened_.ptr<T>(r);
      }
      else
      {
        const T* in = depth.ptr<T>(r);
        for (int u = 0; u < w; ++u)
          row[u] = Tr::map(in[u]);
        src = row;
      }

      T* dst = out.depth.ptr<T>(r);
      std::uint8_t* lab = out.labels.ptr<std::uint8_t>(r);
      float* t = s.t.data();
      // The threshold lookup is a gather, which SSE cannot vectorise: keep it in its own short loop.
      for (int u = 0; u < w; ++u)
      {
        if constexpr (std::is_same_v<T, std::uint8_t>)
          t[u] = lut.forValue(src[u]);
        else
          t[u] = lut.forDepth(static_cast<float>(src[u]) * scale);
      }
      RowCounts c = classifyRow<T>(src, t, col, rowterm[r], scale, floor_h, ceil_h, w, lab, dst, z);
      const int n_kept = c.kept;
      s.counts[kKept] += c.kept;
      s.counts[kInvalid] += c.invalid;
      s.counts[kFloor] += c.floor;
      s.counts[kAboveCeiling] += c.ceiling;
      s.counts[kBelowFloor] += w - c.kept - c.invalid - c.floor - c.ceiling;
      if (n_kept == 0)
        continue;

      if (column)
      {
        // The column projection's bin and range factor depend on the column only: keep the nearest depth
        // per column and bin the columns once per frame.
        float* cm = s.colmin.data();
        for (int u = 0; u < w; ++u)
          cm[u] = z[u] < cm[u] ? z[u] : cm[u];
        continue;
      }
      const float* fb = projector_.rowEdgeBins(r, s.edges.data());
      float* range = s.range.data();
      projector_.rowRanges(r, z, range);
      binRow(fb, range, w, beams, half_turn_bins, bins);
    }
    if (column)
    {
      const float* fb = projector_.rowEdgeBins(0, s.edges.data());
      float* range = s.range.data();
      projector_.rowRanges(0, s.colmin.data(), range);
      binRow(fb, range, w, beams, half_turn_bins, bins);
    }
  }
  out.times.classify_scan = msSince(t1);

  // Stage 3: reduce the threads' bins, apply REP 117, rolling confidence.
  t1 = Clock::now();
  ScanData& scan = out.scan;
  scan.angle_min = projector_.angleMin();
  scan.angle_max = projector_.angleMax();
  scan.angle_increment = projector_.angleIncrement();
  scan.range_min = static_cast<float>(config_.range_min);
  scan.range_max = static_cast<float>(config_.range_max);
  scan.ranges.assign(beams, kInf);
  out.counts.fill(0);
  for (int i = 0; i < threads; ++i)
  {
    const Scratch& s = *scratch_[i];
    for (int b = 0; b < beams; ++b)
      scan.ranges[b] = std::min(scan.ranges[b], s.bins[b]);
    for (int k = 0; k < kNumLabels; ++k)
      out.counts[k] += s.counts[k];
  }
  float cov_lo, cov_hi;
  projector_.coverage(cov_lo, cov_hi);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int b = 0; b < beams; ++b)
  {
    float& r = scan.ranges[b];
    if (b + 1 <= cov_lo || b > cov_hi)
      r = nan;  // no pixel of the image looks in this direction at this pose
    else if (r < scan.range_min)
      r = -kInf;
    else if (r > scan.range_max)
      r = kInf;
  }
  confidence_.apply(scan.ranges, scan.intensities);
  out.times.confidence = msSince(t1);
}

}  // namespace kinect_pipeline
