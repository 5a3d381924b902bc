// Pipeline (pipeline.h): a frame's input checks and pose, then its stages. Design notes: docs/core_design.md, and
// docs/floor_refinement.md for the floor fit that starts each frame.
//   stage 1  stages/opening/opening.h  unknown pixels to no return, the opening
//   stage 2  the row loop here, each row: labels (stages/labels/by_value.h, stages/labels/per_pixel.h by the rule
//            of stages/labels/rule.h), its below-floor and kept pixels into the thread's beams (stages/scan/binning.h)
//   stage 3  stages/scan/output.h      the threads' bins merged, surface_band, the cliff scan, REP 117, confidence
#include "kinect_pipeline/pipeline.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "base/simd.h"
#include "kinect_pipeline/model/encoding.h"
#include "pipeline/frame_work.h"
#include "stages/frame_common.h"
#include "stages/labels/by_value.h"
#include "stages/opening/opening.h"
#include "stages/scan/binning.h"
#include "stages/scan/output.h"
#include "stages/speckle.h"

namespace kinect_pipeline
{
namespace detail
{
namespace
{
/** What the row loop does with each row, set up once per frame. */
template <typename T>
struct RowStages
{
  const Opening<T>& opening;
  const RowLabeller<T>& labeller;
  const RowBinner& binner;
  bool cliff;   ///< bin the below-floor pixels (cliff_scan or cliff_in_scan)
  float scale;  ///< metres per unit of the encoding
  const float* col;    ///< PlaneModel::colTerm()
  const float* row;    ///< PlaneModel::rowTerm()
  CliffRule cliff_rule;  ///< which of them are cliff evidence
};

/** What the row loop leaves for stage 3. */
struct RowLoop
{
  int team = 1;  ///< threads OpenMP gave: only their scratch holds this frame's bins
  float cov_lo = 0.0f, cov_hi = 0.0f;  ///< the bin positions the image covers (ScanProjector::coverage)
  bool squared = false;                ///< the bins hold squared ranges
};

// Row r: opened, labelled and counted, its below-floor pixels into the thread's cliff bins, its kept span recorded
// (first > last: none) and handed to the binning.
template <typename T, typename Binning>
void labelRow(const cv::Mat& depth, int r, const RowStages<T>& st, const Binning& binning, std::int32_t* spans,
              ThreadScratch& s, const LabelBuffers& buf, FrameResult& out)
{
  const int w = depth.cols;
  const T* src = st.opening.row(depth, r, s.opening);
  T* dst = out.depth.ptr<T>(r);
  std::uint8_t* lab = out.labels.ptr<std::uint8_t>(r);
  const RowCounts c = st.labeller.label(r, src, st.opening.opens() ? depth.ptr<T>(r) : nullptr, w, lab, dst, buf);
  const int below = c.below(w);
  s.counts[kKept] += c.kept;
  s.counts[kInvalid] += c.invalid;
  s.counts[kFloor] += c.floor;
  s.counts[kAboveCeiling] += c.ceiling;
  s.counts[kBelowFloor] += below;
  BinScratch& b = s.bins;
  if (st.cliff && below > 0)
  {
    // Negative obstacles: the row's below-floor pixels at their opened depth, binned like kept ones.
    const int a = c.below_first >= 0 ? c.below_first : firstLabelled(lab, w, kBelowFloor);
    const int e = c.below_last >= 0 ? c.below_last : lastLabelled(lab, w, kBelowFloor);
    belowFloorDepth<T>(src, lab, a, e, st.scale, st.col, st.row[r], st.cliff_rule, b.z.data());
    st.binner.bin(r, a, e, b, SpanDepths{}, MinCountInto{b.cliff_bins.data() + 1, b.cliff_count.data() + 1});
  }
  spans[2 * r] = w;
  spans[2 * r + 1] = -1;
  if (c.kept == 0)
    return;
  // Only the span from the first to the last kept pixel can reach a bin.
  const int a = c.kept_first >= 0 ? c.kept_first : firstLabelled(lab, w, kKept);
  const int e = c.kept_last >= 0 ? c.kept_last : lastLabelled(lab, w, kKept);
  spans[2 * r] = a;
  spans[2 * r + 1] = e;
  binning.keptSpan(r, a, e, dst, b);
}

/**
 * Stage 2, the rows in parallel: each row opened, labelled and binned (labelRow), and each chunk of rows binned by
 * the projection's Binning. One parallel region with the rectangular opening's erosion (each fork costs a
 * wake-up). @param t_eroded set when the erosion is done
 */
template <typename T, typename Binning>
RowLoop labelAndBin(const cv::Mat& depth, const RowStages<T>& st, const Binning& binning, FrameWork& work,
                    FrameResult& out, int threads, Clock::time_point& t_eroded)
{
  const int h = depth.rows;
  RowLoop loop;
  loop.squared = Binning::kSquared;
  int team = 1;
#pragma omp parallel num_threads(threads)
  {
#ifdef _OPENMP
#pragma omp single nowait
    team = omp_get_num_threads();
#endif
    ThreadScratch& s = *work.scratch[threadId()];
    st.opening.erodeRows(depth, s.opening);
#pragma omp single nowait
    t_eroded = Clock::now();
    BinScratch& b = s.bins;
    std::fill(b.bins.begin(), b.bins.end(), kInf);
    if (st.cliff)
    {
      std::fill(b.cliff_bins.begin(), b.cliff_bins.end(), kInf);
      std::fill(b.cliff_count.begin(), b.cliff_count.end(), 0);
    }
    s.counts.fill(0);
    binning.begin(b, h);
    const LabelBuffers buf = s.labelBuffers();
    // Chunks dealt in turn (thread t takes chunks t, t + T, ...): neighbouring chunks cost about the same, so the
    // threads' shares even out without the shared counter of a dynamic schedule (by the bench, 2 threads gave
    // 1.4-1.8x one with a dynamic schedule on a 2-CPU machine, 1.70-1.79x dealt in turn).
#pragma omp for schedule(static, 1)
    for (int chunk = 0; chunk < (h + kRowChunk - 1) / kRowChunk; ++chunk)
    {
      const int r0 = chunk * kRowChunk, r1 = std::min(h, r0 + kRowChunk);
      for (int r = r0; r < r1; ++r)
        labelRow(depth, r, st, binning, work.spans.data(), s, buf, out);
      binning.chunk(r0, r1, b);
    }
    // (implicit barrier: the column projection's bins need every row's column minima)
    binning.end(b);
  }
  loop.team = team;
  binning.coverage(work.team(team), loop.cov_lo, loop.cov_hi);
  return loop;
}

/**
 * Stage 3: the threads' bins and counts merged, surface_band (its second pass over the kept spans counts as
 * classify_scan), the cliff scan, REP 117 and the rolling confidence.
 */
template <typename T>
void scanStage(const cv::Mat& depth, const RowLoop& loop, const RowBinner& binner, const Config& config,
               const CliffRule& cliff_rule, int threads, FrameWork& work, Confidence& confidence, FrameResult& out)
{
  auto t1 = Clock::now();
  const ScanProjector& p = binner.projector();
  const int beams = p.beams();
  ScanData& scan = out.scan;
  scan.angle_min = p.angleMin();
  scan.angle_max = p.angleMax();
  scan.angle_increment = p.angleIncrement();
  scan.range_min = static_cast<float>(config.range_min);
  scan.range_max = static_cast<float>(config.range_max);
  const std::vector<const BinScratch*>& team = work.team(loop.team);
  mergeBins(team, beams, loop.squared, scan.ranges);
  out.counts.fill(0);
  for (int i = 0; i < loop.team; ++i)
    for (int k = 0; k < kNumLabels; ++k)
      out.counts[k] += work.scratch[i]->counts[k];
  if (config.surface_band > 0.0)
  {
    const auto ts = Clock::now();
    surfaceMeans<T>(binner, depth, out.labels, work.spans.data(), config, threads, work.bins, work.band_limit,
                    scan.ranges);
    const double ms = msSince(ts);
    out.times.classify_scan += ms;
    t1 += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(ms));
  }
  ScanData& cl = out.cliff;
  cl.ranges.clear();
  cl.intensities.clear();
  if (config.cliff_scan || config.cliff_in_scan)
    mergeCliff(work.team(loop.team), beams, config, cliff_rule, work.cliff_count, scan.ranges, cl.ranges);
  cl.angle_min = scan.angle_min;
  cl.angle_max = scan.angle_max;
  cl.angle_increment = scan.angle_increment;
  cl.range_min = scan.range_min;
  cl.range_max = scan.range_max;
  for (std::vector<float>* ranges : {&scan.ranges, &cl.ranges})
    rep117(ranges->data(), static_cast<int>(ranges->size()), loop.cov_lo, loop.cov_hi, scan.range_min,
           scan.range_max);
  confidence.apply(scan.ranges, scan.intensities);
  out.times.confidence = msSince(t1);
}

/** @throw std::invalid_argument for a CV_32FC1 image that is plainly millimetres: the median of its valid pixels,
 *  on a subsample of about 4096, above kMillimetreMedian. */
// v: scratch for the samples (cleared; its capacity is kept from frame to frame: no allocation once warm).
void checkMetres(const cv::Mat& depth, std::vector<float>& v)
{
  if (depth.type() != CV_32FC1)
    return;
  v.clear();
  const int step = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(depth.total()) / 4096.0)));
  for (int r = 0; r < depth.rows; r += step)
  {
    const float* row = depth.ptr<float>(r);
    for (int u = 0; u < depth.cols; u += step)
      if (row[u] > 0.0f && std::isfinite(row[u]))
        v.push_back(row[u]);
  }
  if (v.empty())
    return;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  const float median = v[v.size() / 2];
  if (median > kMillimetreMedian)
  {
    std::ostringstream s;
    s << "depth: float32 with a median of " << median << " over its valid pixels: that is millimetres, not metres "
      << "(a float32 depth image is in metres: divide it by 1000, or pass the uint16 millimetres as they are)";
    throw std::invalid_argument(s.str());
  }
}

void checkImage(const cv::Mat& depth, const Camera& camera, std::vector<float>& scratch)
{
  if (depth.empty())
    throw std::invalid_argument("depth image is empty: expected a " + std::to_string(camera.width) + "x" +
                                std::to_string(camera.height) + " image");
  const int type = depth.type();
  if (depth.dims != 2 || (type != CV_8UC1 && type != CV_16UC1 && type != CV_32FC1))
    throw std::invalid_argument("depth image type " + cv::typeToString(type) + " with " +
                                std::to_string(depth.dims) + " dimensions: expected a 2-D 8UC1, 16UC1 or 32FC1 image");
  checkMetres(depth, scratch);
  if (depth.cols != camera.width || depth.rows != camera.height)
  {
    std::ostringstream s;
    s << "depth image is " << depth.cols << "x" << depth.rows << " (width x height) but the camera model is "
      << camera.width << "x" << camera.height;
    throw std::invalid_argument(s.str());
  }
}

void checkPose(const SensorPose& pose, double ceiling_height)
{
  const double pitch = pose.pitch, roll = pose.roll, height = pose.height;
  if (!std::isfinite(pitch) || !std::isfinite(roll) || std::fabs(pitch) > kPi / 2 + 1e-9)
  {
    std::ostringstream s;
    s << "pose: pitch = " << pitch << " rad, roll = " << roll
      << " rad (sensor + base): expected finite values with |pitch| <= pi/2 (any roll)";
    throw std::invalid_argument(s.str());
  }
  if (!(std::isfinite(height) && height > 0.0 && height < ceiling_height))
  {
    std::ostringstream s;
    s << "pose: height = " << height << " m: expected a sensor height > 0 and below ceiling_height = "
      << ceiling_height << " m";
    throw std::invalid_argument(s.str());
  }
}
}  // namespace
}  // namespace detail

Pipeline::Pipeline(const Camera& camera, const Config& config, const ReferencePaths& paths)
    : paths_(paths), work_(std::make_unique<detail::FrameWork>())
{
  detail::simdFromEnvironment();
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
  // The learned floor correction belongs to a mounting: a new static pose or refinement setting starts afresh.
  if (config.sensor_height != config_.sensor_height || config.sensor_pitch != config_.sensor_pitch ||
      config.sensor_roll != config_.sensor_roll || config.refine_floor != config_.refine_floor)
    floor_fit_.reset();
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

void Pipeline::restoreFloorFit(const FloorFit::State& s)
{
  if (const std::string problem = FloorFit::stateProblem(s, config_); !problem.empty())
    throw std::invalid_argument(problem);
  floor_fit_.restore(s);
}

void Pipeline::reset()
{
  confidence_.reset();
  floor_fit_.reset();
}

void Pipeline::process(const cv::Mat& depth, double base_pitch, double base_roll, FrameResult& out, double stamp)
{
  if (!std::isfinite(base_pitch) || !std::isfinite(base_roll))
  {
    std::ostringstream s;
    s << "pose: base_pitch = " << base_pitch << " rad, base_roll = " << base_roll << " rad: expected finite values";
    throw std::invalid_argument(s.str());
  }
  process(depth, SensorPose{config_.sensor_height, config_.sensor_pitch + base_pitch, config_.sensor_roll + base_roll},
          out, stamp);
}

void Pipeline::process(const cv::Mat& input, const SensorPose& prior, FrameResult& out, double stamp)
{
  using detail::Clock;
  const auto t0 = Clock::now();
  detail::checkImage(input, camera_, work_->samples);
  detail::checkPose(prior, config_.ceiling_height);
  const SensorPose wrapped{prior.height, prior.pitch, wrapAngle(prior.roll)};  // sensor + base roll may pass pi
  if (const std::string problem = rollProblem(wrapped.roll, config_.geometry, "pose: roll (sensor + base)");
      !problem.empty())
    throw std::invalid_argument(problem);
  const int threads = config_.num_threads > 0 ? config_.num_threads : detail::defaultThreads();
  const bool despeckle = config_.speckle_jump > 0.0;
  out.speckles = despeckle ? detail::removeSpeckles(input, config_.speckle_jump, work_->despeckled, threads) : 0;
  const cv::Mat& depth = despeckle ? work_->despeckled : input;
  const int type = depth.type();
  const Encoding enc = type == CV_8UC1 ? Encoding::kMono8 : (type == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32);
  if (!lut_valid_ || enc != lut_encoding_)
  {
    lut_.build(config_.threshold_curve, enc, config_.max_depth);
    lut_encoding_ = enc;
    if (enc == Encoding::kMono8)
      work_->value_terms = detail::valueTerms<std::uint8_t>(lut_.valueTable(), detail::depthScale<std::uint8_t>(config_.max_depth));
    else if (enc == Encoding::kMono16)
      work_->value_terms = detail::valueTerms<std::uint16_t>(lut_.valueTable(), detail::depthScale<std::uint16_t>(config_.max_depth));
    lut_valid_ = true;
  }
  const auto t_fit = Clock::now();
  out.pose = floor_fit_.refine(depth, camera_, config_, lut_, wrapped, stamp, out.floor_fit);
  if (planes_.update(camera_, config_, out.pose.height, out.pose.pitch, out.pose.roll))
    projector_.setPose(out.pose.pitch, out.pose.roll);
  out.level_rows = planes_.oneRisePerRow();
  if (config_.refine_floor && config_.floor_profile_max > 0.0)
  {
    floor_fit_.learnProfile(depth, config_, lut_, planes_, out.floor_fit);
    planes_.setProfile(floor_fit_.profile().bias.data(), FloorProfile::kBands, FloorProfile::kBandWidth);
  }
  else
    planes_.setProfile(nullptr, 0, 0.0f);
  out.times.floor_fit = detail::msSince(t_fit);
  out.depth.create(depth.size(), type);
  out.labels.create(depth.size(), CV_8UC1);
  out.times.prepare = detail::msSince(t0);

  switch (type)
  {
    case CV_8UC1:
      run<std::uint8_t>(depth, out, threads);
      break;
    case CV_16UC1:
      run<std::uint16_t>(depth, out, threads);
      break;
    default:
      run<float>(depth, out, threads);
      break;
  }
  out.times.total = detail::msSince(t0);
}

template <typename T>
void Pipeline::run(const cv::Mat& depth, FrameResult& out, int threads)
{
  using namespace detail;
  FrameWork& work = *work_;
  work.prepare(threads, camera_.width, camera_.height, projector_.beams());
  const float scale = depthScale<T>(config_.max_depth);

  // Stage 1: the opening where it is done on the whole image (OpenCV's; else row by row in stage 2).
  const auto t1 = Clock::now();
  Opening<T> opening(config_, paths_, work.opening);
  opening.openWhole(depth, threads);

  // Stage 2: the rule's terms at this pose, the labelling, the binning of the projection (chosen here, once).
  const RuleTerms terms{{scale, planes_.floorOffset(), planes_.ceilingOffset(), planes_.lift()},
                        planes_.colTerm().data(), planes_.rowTerm().data(), &lut_, planes_.oneRisePerRow(),
                        planes_.monotoneColumns() && !paths_.labels, !paths_.portable};
  const RowLabeller<T> labeller(terms, work.value_terms, paths_);
  const RowBinner binner(projector_, camera_.width, paths_);
  const RowStages<T> stages{opening,
                            labeller,
                            binner,
                            config_.cliff_scan || config_.cliff_in_scan,
                            scale,
                            planes_.colTerm().data(),
                            planes_.rowTerm().data(),
                            CliffRule::at(config_, planes_.floorOffset(), CliffRule::kSearchDepth, planes_.lift())};
  Clock::time_point t2 = t1;
  const RowLoop loop =
      projector_.projection() == Projection::kColumn
          ? labelAndBin(depth, stages, ColumnBinning<T>(binner, scale), work, out, threads, t2)
          : labelAndBin(depth, stages, HorizontalBinning<T>(binner, out.depth, work.spans.data(), scale), work, out,
                        threads, t2);
  out.times.erode = std::chrono::duration<double, std::milli>(t2 - t1).count();
  out.times.classify_scan = msSince(t2);

  // Stage 3: the scan.
  scanStage<T>(depth, loop, binner, config_, stages.cliff_rule, threads, work, confidence_, out);
}

std::string describe(const FrameResult& r)
{
  const int type = r.depth.type();
  const char* dtype = type == CV_8UC1 ? "uint8" : type == CV_16UC1 ? "uint16" : "float32";  // numpy's names
  int finite = 0;
  float nearest = std::numeric_limits<float>::infinity();
  for (const float v : r.scan.ranges)
    if (std::isfinite(v))
    {
      ++finite;
      nearest = std::min(nearest, v);
    }
  int cliffs = 0;
  for (const float v : r.cliff.ranges)
    cliffs += std::isfinite(v) ? 1 : 0;
  double total = 0.0;
  for (const std::uint64_t n : r.counts)
    total += static_cast<double>(n);
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s << "Result(" << r.depth.cols << "x" << r.depth.rows << " " << dtype << ", " << r.scan.ranges.size()
    << " beams: " << finite << " finite";
  if (finite)
    s << std::setprecision(2) << ", nearest " << nearest << " m";
  s << ", " << cliffs << " cliff; pixels";
  for (int k = 0; k < kNumLabels; ++k)
    s << " " << kLabelNames[k] << " " << std::setprecision(1)
      << (total > 0 ? 100.0 * static_cast<double>(r.counts[k]) / total : 0.0) << " %";
  s << "; " << std::setprecision(3) << r.times.total << " ms)";
  return s.str();
}

}  // namespace kinect_pipeline
