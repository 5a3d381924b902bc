/**
 * @file calibration.h
 * @brief The sensor's height, pitch and roll from frames of a flat floor (robot standing still).
 */
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"

namespace kinect_pipeline
{

/** Options of the floor search. */
struct CalibrationOptions
{
  double max_tilt = 0.7;          ///< the floor's normal is within this angle of the image's "up" [rad] (40 deg)
  double min_fraction = 0.05;     ///< the floor must hold at least this fraction of the valid pixels
  double min_height = 0.05;       ///< the sensor is at least this high above the floor [m]
  double max_height = 5.0;        ///< and at most this high [m]
  double max_range = 6.0;         ///< pixels farther than this are not used [m]
  int iterations = 400;           ///< RANSAC hypotheses
  int stride = 2;                 ///< use every stride-th pixel in both directions
  std::uint64_t seed = 1;         ///< RANSAC seed: the same frames give the same answer
};

/** The pose the floor gives, in the pipeline's conventions. */
struct FloorPose
{
  bool found = false;         ///< false: no floor found (then the rest is 0)
  double height = 0.0;        ///< optical centre above the floor [m]
  double pitch = 0.0;         ///< [rad], + looks down
  double roll = 0.0;          ///< [rad], + right side down
  double height_std = 0.0;    ///< 1-sigma uncertainty of the fit [m]
  double pitch_std = 0.0;     ///< [rad]
  double roll_std = 0.0;      ///< [rad]
  double floor_fraction = 0.0;  ///< floor pixels / valid pixels used
  int floor_pixels = 0;
  double rms = 0.0;           ///< RMS distance of the floor pixels from the plane [m]
};

/**
 * @brief Finds the floor in a depth frame and returns the pose it implies. The floor is the lowest plane whose
 *        normal points up in the image (within max_tilt) and that holds enough pixels: it need not be most of the
 *        view. RANSAC with depth-dependent inlier bands (Kinect v2 noise), then a weighted least-squares refit.
 * @param depth_m CV_32F metres (0, NaN, Inf unknown)
 * @throw std::invalid_argument for another type or a size that disagrees with the camera.
 */
FloorPose calibrateFromFloor(const cv::Mat& depth_m, const Camera& camera, const CalibrationOptions& options = {});

}  // namespace kinect_pipeline
