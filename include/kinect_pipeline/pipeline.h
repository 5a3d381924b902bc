/**
 * @file pipeline.h
 * @brief One depth frame in, a cleaned depth image, per-pixel labels and a laser scan out.
 */
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/stages/floor_fit.h"
#include "kinect_pipeline/stages/scan.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{

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
  std::uint64_t speckles = 0;  ///< Config::speckle_jump: pixels taken as wrong matches (no measurement) before the opening
  SensorPose pose{0.0, 0.0, 0.0};  ///< the pose the frame was processed at (the prior, refined by the floor fit)
  FloorFitResult floor_fit;        ///< what the floor refinement decided (status kOff when refine_floor is false)
  /**
   * The pose had no roll (0 or +-pi, within kRollSnap): each row had one rise, so the frame took the level paths
   * (8- and 16-bit rows labelled by value, the scan's level rows). Otherwise every pixel had its own rise: the roll
   * paths, about twice the time of an 8- or 16-bit frame.
   */
  bool level_rows = false;
  StageTimes times;
};

/**
 * @return the frame in one line, as the Python binding's Result shows it: "Result(512x424 uint16, 512 beams: 498
 *         finite, nearest 0.84 m, 0 cliff; pixels kept 30.1 % invalid 2.0 % ...; 3.120 ms)". Reads the depth image's
 *         size and type, not its pixels.
 */
std::string describe(const FrameResult& r);

namespace detail
{
struct FrameWork;
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
  /**
   * @param paths the fast paths this pipeline's frames replace by their reference (default: none)
   * @throw std::invalid_argument if the camera or config is invalid.
   */
  Pipeline(const Camera& camera, const Config& config, const ReferencePaths& paths = {});
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /** @brief Replaces the config (validated first; on error nothing changes). */
  void setConfig(const Config& config);
  /** @brief Replaces the camera model (validated first; on error nothing changes). */
  void setCamera(const Camera& camera);
  const Config& config() const { return config_; }
  const Camera& camera() const { return camera_; }
  /** @return the fast paths this pipeline replaces by their reference (as constructed). */
  const ReferencePaths& referencePaths() const { return paths_; }

  /**
   * @brief Processes one frame.
   * @param depth CV_8UC1 (normalised, max_depth), CV_16UC1 (mm) or CV_32FC1 (m); its size must match the
   *        camera; any row step
   * @param base_pitch base pitch added to sensor_pitch [rad], + looks down
   * @param base_roll base roll added to sensor_roll [rad], + right side down
   * @param out result; its buffers are reused
   * @param stamp the frame's time [s], for the floor refinement's learned correction; NaN: 1/30 s after the last
   * @throw std::invalid_argument for another type, an empty image, a 32FC1 image that is plainly millimetres
   *        (the median of its valid pixels above 100 m), a size that disagrees with the camera, or a non-finite
   *        pose; nothing is changed then.
   */
  void process(const cv::Mat& depth, double base_pitch, double base_roll, FrameResult& out,
               double stamp = std::numeric_limits<double>::quiet_NaN());

  /**
   * @brief Processes one frame at a pose given whole (e.g. from tf): sensor_height, sensor_pitch and
   *        sensor_roll of the config are not used.
   * @throw std::invalid_argument as process(), and for a non-finite pose, a height <= 0 or >= ceiling_height,
   *        or |pitch| > pi/2. Any roll is taken (turned by whole turns into [-pi, pi]; +-pi: upside down).
   */
  void process(const cv::Mat& depth, const SensorPose& pose, FrameResult& out,
               double stamp = std::numeric_limits<double>::quiet_NaN());

  /** @brief Forgets the confidence history and the floor refinement's learned correction. */
  void reset();

  /** @return the plane model as of the last frame (for tests and debug images). */
  const PlaneModel& planes() const { return planes_; }
  /** @return the floor refinement (its learned correction). */
  const FloorFit& floorFit() const { return floor_fit_; }
  /**
   * @brief Continues the floor refinement from a FloorFit::state() (e.g. of another run of the same frames).
   * @throws std::invalid_argument with FloorFit::stateProblem() under this config; the state is then unchanged
   */
  void restoreFloorFit(const FloorFit::State& s);
  /** @return the scan projector as of the last frame. */
  const ScanProjector& projector() const { return projector_; }

private:
  template <typename T>
  void run(const cv::Mat& depth, FrameResult& out, int threads);

  Camera camera_;
  Config config_;
  ReferencePaths paths_;
  PlaneModel planes_;
  FloorFit floor_fit_;
  ScanProjector projector_;
  Confidence confidence_;
  ThresholdLut lut_;
  Encoding lut_encoding_ = Encoding::kMono8;
  bool lut_valid_ = false;
  std::unique_ptr<detail::FrameWork> work_;  ///< the frames' buffers (src/core/pipeline/frame_work.h)
};

}  // namespace kinect_pipeline
