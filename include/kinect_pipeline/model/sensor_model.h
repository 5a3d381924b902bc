/**
 * @file sensor_model.h
 * @brief Presets of the depth cameras robots carry (the `sensor_model` parameter): each sensor's published depth
 *        noise model and the threshold curve made from it, its rated range, typical intrinsics and the usual
 *        topics of its ROS driver. The one table of them: the binding, the tools and the node read it.
 */
#pragma once

#include <string>
#include <vector>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/**
 * Depth noise of a sensor and the threshold curve made from it:
 *   sigma(z) = sigma0 + quad * (z - z0)^2          (random error, 1 sigma [m] at depth z [m])
 *   step(z)  = step2 * z^2                         (quantisation of a disparity-based sensor [m]; 0 for time of flight)
 *   t(z)     = margin + k * sigma(z) + steps * step(z)
 */
struct NoiseModel
{
  double sigma0 = 0.0;  ///< [m]
  double quad = 0.0;    ///< [m / m^2]
  double z0 = 0.0;      ///< [m]
  double step2 = 0.0;   ///< [1 / m]: depth step = step2 * z^2
  double k = 4.5;       ///< sigmas in the threshold
  double steps = 0.0;   ///< depth steps in the threshold
  double margin = 0.02; ///< [m]

  /** @return sigma(z) [m]. */
  double sigma(double z) const { return sigma0 + quad * (z - z0) * (z - z0); }
  /** @return t(z) [m], unrounded. */
  double threshold(double z) const { return margin + k * sigma(z) + steps * step2 * z * z; }
};

/** One sensor preset. */
struct SensorModel
{
  std::string name;         ///< the parameter value, e.g. "kinect_v2"
  std::string description;  ///< what it is, e.g. "Microsoft Kinect v2 (time of flight)"
  std::string source;       ///< where the noise model comes from
  NoiseModel noise;
  double range_max = 10.0;  ///< the sensor's rated range [m]: the scan's range_max
  Camera camera;            ///< typical depth intrinsics at its usual resolution
  std::string driver;       ///< the usual ROS driver
  std::string camera_ns;    ///< its usual camera namespace ("" = none)
  std::string image;        ///< its depth image topic in that namespace (camera_info beside it)
  std::vector<CurvePoint> curve;  ///< a curve given as it is (the Kinect v2's, rounded by hand); empty: from noise
  double speckle_jump = 0.0;      ///< Config::speckle_jump: its wrong matches removed (stereo cameras); 0 = off

  /** @return the threshold curve: @c curve, else t(z) at the default curve's depths rounded to millimetres. */
  std::vector<CurvePoint> thresholdCurve() const;
  /** @return cliff_min_pixels covering the solid angle the default (3 px of a Kinect v2) covers. */
  int cliffMinPixels() const;
  /** @return the depth image's full topic: "/" camera_ns "/" image, e.g. "/camera/depth/image_raw". */
  std::string depthTopic() const;
  /** @return its camera_info's topic: "camera_info" beside the image, e.g. "/camera/depth/camera_info". */
  std::string infoTopic() const;
};

/** @return every preset, the default (kinect_v2) first. */
const std::vector<SensorModel>& sensorModels();

/**
 * @return the preset called @p name.
 * @throw std::invalid_argument naming it and the valid names.
 */
const SensorModel& sensorModel(const std::string& name);

/** The name of the default preset, whose curve is the default threshold_curve. */
inline const char* kDefaultSensorModel = "kinect_v2";

/**
 * @brief The Config fields a preset sets: threshold_curve, range_max, cliff_min_pixels, speckle_jump. Fields named in
 *        @p keep (given explicitly) are left as they are.
 * @throw std::invalid_argument for an unknown name.
 */
void applySensorModel(const std::string& name, Config& config, const std::vector<std::string>& keep = {});

/** The Config fields applySensorModel() sets. */
const std::vector<std::string>& sensorModelFields();

/** @return the depth noise of the Kinect v2 model, sigma0 + k * (z - 0.4)^2 [m], at depth @p z [m]. */
inline double kinectSigma(double z, double sigma0 = 0.0015, double k = 0.0019)
{
  return sigma0 + k * (z - 0.4) * (z - 0.4);
}

}  // namespace kinect_pipeline
