/**
 * @file floor_fit.h
 * @brief The floor refinement: the prior pose (config + base motion, or tf) corrected from the frame itself.
 *
 * No robot knows its pose exactly. Before the planes are predicted, the floor is fitted to the frame's own pixels
 * that can be floor under the configured pose uncertainty (a robust, deterministic fit started at the prior), the
 * fit is accepted only when the frame supports it, and what persists (a mounting error, an IMU's bias) is learned
 * slowly so that it still holds when no floor is in view. Design notes: docs/floor_refinement.md.
 */
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/stages/floor_profile.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{

/** What the floor fit of one frame decided. */
enum class FloorFitStatus : std::uint8_t
{
  kOff = 0,          ///< Config::refine_floor is false: the prior pose, as given
  kAccepted,         ///< the frame was processed at the fitted pose
  kTooFewPixels,     ///< fewer than floor_min_pixels image pixels lie on the fitted floor
  kSpreadTooLarge,   ///< the residuals are wider than the depth noise allows for a floor
  kOutOfBounds,      ///< the correction exceeds floor_max_height/pitch/roll_error
  kIllConditioned,   ///< the floor in view is too small to fix the pitch or roll (e.g. one narrow strip)
  kNotBetter,        ///< the fitted floor explains the frame's candidates worse than the prior's does
};
constexpr int kNumFloorFitStatus = 7;

/**
 * @return "off", "accepted", "too few pixels", "spread too large", "out of bounds", "ill-conditioned" or "not better
 *         than the prior".
 */
std::string toString(FloorFitStatus s);

/** The floor fit of one frame (FrameResult::floor_fit). */
struct FloorFitResult
{
  FloorFitStatus status = FloorFitStatus::kOff;
  bool accepted() const { return status == FloorFitStatus::kAccepted; }
  int row_step = 0;    ///< the fit samples every row_step-th row,
  int col_step = 0;    ///< every col_step-th pixel of it (from an offset that changes from row to row)
  int candidates = 0;  ///< sampled pixels within the band where the floor can be under the pose uncertainty
  int support = 0;     ///< of those, the pixels within t(d) of the fitted floor
  int pixels = 0;      ///< the image pixels the support stands for (support * row_step * col_step)
  double spread = 0.0; ///< RMS of the support's residuals in units of t(d) (pure noise: about 1/3)
  /// the fit's largest move of the floor where it is seen, in units of t(d); an accepted fit below 0.1 is noise:
  /// the frame keeps the prior (plus the learned correction)
  double shift = 0.0;
  PoseCorrection fit;      ///< the fitted pose minus the prior (also when declined)
  PoseCorrection std;      ///< the standard deviations of the fitted floor's terms (height [m], slopes [rad])
  PoseCorrection applied;  ///< the pose the frame was processed at minus the prior
  PoseCorrection learned;  ///< the slowly learned correction after this frame (applied to the next prior)
  /// the floor profile after this frame (FloorFit::learnProfile(); all zero while it is off)
  FloorProfileBands profile;
};

/**
 * Refines a prior pose from a depth frame. Keeps the learned correction between frames; no allocation per frame
 * once the camera is known. Not thread-safe (one frame at a time, as Pipeline).
 */
class FloorFit
{
public:
  /**
   * @brief The pose to process @p depth at.
   * @param depth the input frame (CV_8UC1 normalised with max_depth, CV_16UC1 mm or CV_32FC1 m), camera-sized
   * @param lut the threshold table of the frame's encoding
   * @param prior the pose told by the robot (validated by the caller)
   * @param stamp the frame's time [s] (any epoch), for the learned correction's time constant; NaN: frames are
   *        taken 1/30 s apart
   * @param out what the fit decided; out.status == kOff and the prior returned when config.refine_floor is false
   */
  SensorPose refine(const cv::Mat& depth, const Camera& camera, const Config& config, const ThresholdLut& lut,
                    const SensorPose& prior, double stamp, FloorFitResult& out);

  /**
   * @brief Learns the floor profile (stages/floor_profile.h) from the frame at the pose refine() returned.
   * @param planes the frame's planes at that pose
   * @param out out.profile: the profile after this frame
   */
  void learnProfile(const cv::Mat& depth, const Config& config, const ThresholdLut& lut, const PlaneModel& planes,
                    FloorFitResult& out);
  /** @return the floor profile now. */
  const FloorProfileBands& profile() const { return profile_.bands(); }

  /** @brief Forgets the learned correction and the floor profile (a jump back in time, a new mounting). */
  void reset();
  /** @return the learned correction now. */
  const PoseCorrection& learned() const { return learned_; }

  /** What the fit carries from frame to frame: the learned correction and the last frame's stamp. */
  struct State
  {
    PoseCorrection learned;
    double last_stamp = std::numeric_limits<double>::quiet_NaN();  ///< [s]; NaN: no stamped frame yet
    /// the learned correction's weight per term [1/m^2, 1/rad^2]; NaN: none yet (the prior's, 1/bound^2)
    PoseCorrection weight{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::quiet_NaN()};
    FloorProfileBands profile;  ///< the floor profile (its bias and weight per band)
  };
  /** @return the state after the last frame (to continue elsewhere, e.g. a resumed replay). */
  State state() const;
  /** @brief Continues from a state(): the next frame is processed as it would have been after that frame. */
  void restore(const State& s);
  /**
   * @return what a state() could not hold under @p config, naming the field, its value and what was expected
   *         (empty: none): a learned correction beyond the config's bounds or not finite, a stamp or weight that
   *         is not finite (NaN: none) or negative, a floor profile's bias, weight or time that is not finite.
   */
  static std::string stateProblem(const State& s, const Config& config);

  /** A sampled pixel that can be floor, in the gravity-aligned frame at the sensor under the corrected prior. */
  struct Point
  {
    float x, y;   ///< forward and leftward offset from the sensor [m]
    float e;      ///< height above the prior's floor [m]
    float band;   ///< t(d) as a height: the pipeline removes it as floor within +-band of the floor [m]
  };
  /** @return the sampled pixels of the last frame (for tests; allocates). */
  std::vector<Point> points() const;

private:
  struct Plane;
  template <typename T>
  void sample(const cv::Mat& depth, const Camera& camera, const Config& config, const ThresholdLut& lut,
              const SensorPose& prior);
  Plane fitPlane(const Config& config) const;
  float nearestFloor() const;
  void decide(const Plane& plane, const Config& config, const SensorPose& prior, FloorFitResult& out) const;
  void learn(const FloorFitResult& out, const Config& config, double stamp);
  static PoseCorrection priorWeight(const Config& config);

  int col_step_ = 1;
  int count_ = 0;  // sampled pixels in the band; the arrays are padded with weightless points to whole vectors
  std::vector<float> x_, y_, e_, band_, inv_sigma_, range2_;
  std::vector<float> col_x_, col_y_, col_z_;  // the ray's level-frame terms of each sampled column
  PoseCorrection learned_;
  PoseCorrection weight_;  // the learned correction's weight per term (learn())
  bool has_weight_ = false;
  double last_stamp_ = 0.0;
  bool has_stamp_ = false;
  double last_dt_ = 0.0;  // [s] between the last two frames (learn())
  FloorProfile profile_;
};

/**
 * @brief The sensor pose whose floor is the plane z = a + b x + c y, given in the gravity-aligned frame at the
 *        sensor under @p prior (x forward, y left, z up; the prior's floor is z = -prior.height).
 */
SensorPose poseFromFloorPlane(const SensorPose& prior, double a, double b, double c);

}  // namespace kinect_pipeline
