/**
 * @file pipeline.h
 * @brief One depth frame in, a cleaned depth image, per-pixel labels and a laser scan out.
 */
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/camera.h"
#include "kinect_pipeline/config.h"
#include "kinect_pipeline/encoding.h"
#include "kinect_pipeline/floor_fit.h"
#include "kinect_pipeline/plane_model.h"
#include "kinect_pipeline/scan.h"
#include "kinect_pipeline/threshold_curve.h"

namespace kinect_pipeline
{

/** Per-pixel labels of FrameResult::labels. */
enum Label : std::uint8_t
{
  kKept = 0,          ///< an obstacle (or person) between the floor and the ceiling plane
  kInvalid = 1,       ///< no depth (after the opening filled what it could)
  kFloor = 2,         ///< within t(d) of the predicted floor
  kAboveCeiling = 3,  ///< beyond the predicted ceiling plane
  kBelowFloor = 4,    ///< more than t(d) beyond the floor: a hole, a stair down
};
constexpr int kNumLabels = 5;

/** Wall-clock time of each stage of the last frame [ms]. */
struct StageTimes
{
  double prepare = 0.0;         ///< input checks, floor fit, plane and scan terms
  double floor_fit = 0.0;       ///< the floor refinement alone (part of prepare)
  double erode = 0.0;           ///< unknown -> no return, then the opening's erosion
  double classify_scan = 0.0;   ///< the fused loop: dilation, plane removal, labels, beam binning
  double confidence = 0.0;      ///< bin reduction, range limits, rolling confidence
  double total = 0.0;
};

/** What one frame gives. Reused between frames: no allocation when sizes do not change. */
struct FrameResult
{
  cv::Mat depth;   ///< cleaned depth, the input's type; removed pixels: 255 (8-bit), 0 (16UC1), NaN (32FC1)
  cv::Mat labels;  ///< CV_8UC1, see Label
  ScanData scan;
  /**
   * Negative obstacles (Config::cliff_scan): per beam of `scan`, the horizontal range of the nearest pixel
   * labelled kBelowFloor, if at least cliff_min_pixels of them fall in the beam; +Inf none, NaN outside what
   * the image sees; no intensities. Empty when cliff_scan is off.
   */
  ScanData cliff;
  std::array<std::uint64_t, kNumLabels> counts{};  ///< pixels per label
  SensorPose pose{0.0, 0.0, 0.0};  ///< the pose the frame was processed at (the prior, refined by the floor fit)
  FloorFitResult floor_fit;        ///< what the floor refinement decided (status kOff when refine_floor is false)
  StageTimes times;
};

namespace detail
{
/**
 * The threshold table's terms of the proof that the labels of a row without roll are monotone in the pixel value
 * (8- and 16-bit; see ValueProof in pipeline.cpp), over the values below the encoding's no-return value.
 */
struct ValueTerms
{
  bool nondecreasing = false;  ///< the table never decreases
  double gap_min = 0.0;        ///< smallest growth of depth - threshold from one value to the next [m]
  /// smallest growth of depth - threshold from a value to any value kValueWindow or more above it [m]
  double gap_window = 0.0;
  static constexpr int kValueWindow = 4;
  double d_max = 0.0, t_max = 0.0;  ///< depth and threshold of the largest value [m]
};

/**
 * The fewest values an 8- or 16-bit pixel's raw value must lie above its opened value for the rescue (the raw
 * depth deciding where the opening moved a pixel) to relabel it, when the thresholds of the raw values it may
 * relabel are t or more: pixels nearer than that are not looked at. The rescue needs fl(fl(raw s) - fl(v s)) >
 * t(raw) >= t, and raw - v <= k - 1 gives at most (k - 1 + 4 u no_return) s on the left (u = 2^-24: three roundings
 * of values up to no_return); the float product t / s, a few roundings off, is taken 1e-6 smaller (relative).
 * @param t [m], @param inv_scale values per metre (1 / s), @param no_return the encoding's no-return value
 */
inline int rescueMove(float t, float inv_scale, int no_return)
{
  const float steps = t * inv_scale * (1.0f - 1e-6f) - (4.0f * static_cast<float>(no_return) / 16777216.0f + 1e-4f);
  return steps >= 1.0f ? static_cast<int>(steps) + 1 : 1;  // steps >= 1: the conversion is its floor
}
}  // namespace detail

/**
 * The per-frame processing of thesis section 4.4.1, with exact geometry by default.
 *
 * Not thread-safe: one frame at a time per instance (the frame itself is split over OpenMP threads).
 * Keeps the beams' confidence history between frames.
 */
class Pipeline
{
public:
  /** @throw std::invalid_argument if the camera or config is invalid. */
  Pipeline(const Camera& camera, const Config& config);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /** @brief Replaces the config (validated first; on error nothing changes). */
  void setConfig(const Config& config);
  /** @brief Replaces the camera model (validated first; on error nothing changes). */
  void setCamera(const Camera& camera);
  const Config& config() const { return config_; }
  const Camera& camera() const { return camera_; }

  /**
   * @brief Processes one frame.
   * @param depth CV_8UC1 (normalised, max_depth), CV_16UC1 (mm) or CV_32FC1 (m); its size must match the
   *        camera; any row step
   * @param base_pitch base pitch added to sensor_pitch [rad], + looks down
   * @param base_roll base roll added to sensor_roll [rad], + right side down
   * @param out result; its buffers are reused
   * @param stamp the frame's time [s], for the floor refinement's learned correction; NaN: 1/30 s after the last
   * @throw std::invalid_argument for another type, an empty image, a size that disagrees with the camera,
   *        or a non-finite pose; nothing is changed then.
   */
  void process(const cv::Mat& depth, double base_pitch, double base_roll, FrameResult& out,
               double stamp = std::numeric_limits<double>::quiet_NaN());

  /**
   * @brief Processes one frame at a pose given whole (e.g. from tf): sensor_height, sensor_pitch and
   *        sensor_roll of the config are not used.
   * @throw std::invalid_argument as process(), and for a non-finite pose, a height <= 0 or >= ceiling_height,
   *        or |pitch|, |roll| > pi/2.
   */
  void process(const cv::Mat& depth, const SensorPose& pose, FrameResult& out,
               double stamp = std::numeric_limits<double>::quiet_NaN());

  /** @brief Forgets the confidence history and the floor refinement's learned correction. */
  void reset();

  /** @return the plane model as of the last frame (for tests and debug images). */
  const PlaneModel& planes() const { return planes_; }
  /** @return the floor refinement (its learned correction). */
  const FloorFit& floorFit() const { return floor_fit_; }
  /** @brief Continues the floor refinement from a FloorFit::state() (e.g. of another run of the same frames). */
  void restoreFloorFit(const FloorFit::State& s) { floor_fit_.restore(s); }
  /** @return the scan projector as of the last frame. */
  const ScanProjector& projector() const { return projector_; }

private:
  struct Scratch;
  template <typename T>
  void run(const cv::Mat& depth, FrameResult& out);
  struct SpanBuffers;
  Scratch& teamScratch(int& team);
  template <typename Acc, typename Src>
  void binSpan(int r, int a, int b, const SpanBuffers& buf, const Src& src, const Acc& acc) const;
  template <typename Acc, typename Src>
  void binSpan(int r, int a, int b, int n, const SpanPlan& plan, const SpanBuffers& buf, const Src& src,
               const Acc& acc) const;
  template <typename T>
  void surfaceMeans(const cv::Mat& depth, FrameResult& out, int threads);
  void prepareBuffers(int threads);

  Camera camera_;
  Config config_;
  PlaneModel planes_;
  FloorFit floor_fit_;
  ScanProjector projector_;
  Confidence confidence_;
  ThresholdLut lut_;
  Encoding lut_encoding_ = Encoding::kMono8;
  bool lut_valid_ = false;
  detail::ValueTerms value_terms_;  ///< rebuilt with the table (8- and 16-bit)
  cv::Mat eroded_, mapped_, opened_;
  std::vector<std::int32_t> spans_;  ///< first and last kept column of each row (first > last: none)
  std::vector<std::int32_t> cliff_count_;  ///< below-floor pixels per beam of the frame
  std::vector<float> band_limit_;          ///< surface_band: farthest range counted per beam (+ padding) [m]
  std::vector<std::unique_ptr<Scratch>> scratch_;
};

}  // namespace kinect_pipeline
