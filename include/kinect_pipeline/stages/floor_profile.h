/**
 * @file floor_profile.h
 * @brief The floor's profile beyond the plane: how far beyond (or nearer than) the predicted plane the sensor sees
 *        the floor, per band of range, learned from the frames.
 *
 * A real depth sensor's floor is not the plane: a stereo camera's depth bias grows with range (a few centimetres
 * at 3-4 m, far more at grazing angles), a floor may be gently curved. The profile is the median depth residual of
 * the frame's floor pixels per band of the plane's depth, learned as a recency-weighted mean over frames, bounded
 * in height by Config::floor_profile_max; the prediction is the plane plus the profile (PlaneModel::setProfile).
 * It learns only from pixels within floor_profile_max in height of the floor it predicts so far, never from
 * vertical surfaces: a stair, a hole or an obstacle lies beyond that, and a band's median ignores a minority of
 * anything else. Design notes: docs/floor_refinement.md ("The floor profile").
 */
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/threshold_curve.h"

namespace kinect_pipeline
{

/** The floor profile after one frame (FloorFitResult::profile). */
struct FloorProfileBands
{
  static constexpr int kBands = 16;           ///< bands of the plane's depth
  static constexpr float kBandWidth = 0.5f;  ///< [m]: band k holds the plane's depths [k, k + 1) kBandWidth
  std::array<float, kBands> bias{};           ///< the learned depth of the floor beyond the plane's [m]
  std::array<float, kBands> weight{};         ///< its weight: frames that taught it, by recency (the prior: 1)
  std::array<int, kBands> samples{};          ///< this frame's floor samples per band (0: it taught that band nothing)
  static constexpr double kLearnPeriod = 0.1;  ///< [s]: the profile learns from a frame at most this often
  double since_learned = kLearnPeriod;         ///< [s] since the profile last learned
};

/** Learns the floor profile. No allocation per frame once the camera is known; one frame at a time. */
class FloorProfile
{
public:
  static constexpr int kBands = FloorProfileBands::kBands;
  static constexpr float kBandWidth = FloorProfileBands::kBandWidth;

  /**
   * @brief Learns from one frame at the pose it is processed at.
   * @param planes the frame's planes (the rise terms and the plane's floor offset; its profile is not used)
   * @param dt time since the last frame [s] (the weights decay by exp(-dt / floor_learn_time))
   * @param out the profile after this frame
   */
  void learn(const cv::Mat& depth, const Config& config, const ThresholdLut& lut, const PlaneModel& planes,
             double dt, FloorProfileBands& out);
  /** @return the profile now. */
  const FloorProfileBands& bands() const { return bands_; }
  /** @brief Continues from bands() of another run. */
  void restore(const FloorProfileBands& b) { bands_ = b; }
  /** @brief Forgets it (no bias, the prior's weight). */
  void reset();

private:
  template <typename T>
  void sample(const cv::Mat& depth, const Config& config, const ThresholdLut& lut, const PlaneModel& planes);

  FloorProfileBands bands_ = initial();
  static FloorProfileBands initial();
  std::vector<float> residual_, sorted_;  // per sample: depth minus the plane's depth [m]
  std::vector<std::uint8_t> band_;        // per sample: its band
  std::array<int, kBands> seen_{};        // per band: the sampled pixels with a depth
  int count_ = 0;
};

}  // namespace kinect_pipeline
