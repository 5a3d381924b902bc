/**
 * @file types.h
 * @brief The core's basic types, shared by every layer above it: the sensor's pose, a correction of it, and the
 *        per-pixel labels. Depends on nothing of the package (docs/core_design.md, "Layers").
 */
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace kinect_pipeline
{
constexpr double kPi = 3.14159265358979323846;

/** The angle a [rad] turned by whole turns into [-pi, pi] (exactly a where it lies there already). */
inline double wrapAngle(double a) { return std::remainder(a, 2.0 * kPi); }

/** The sensor's pose relative to the floor for one frame (sensor mounting and base motion together). */
struct SensorPose
{
  double height;  ///< optical centre above the floor [m], > 0
  double pitch;   ///< [rad], + looks down, |pitch| <= pi/2
  double roll;    ///< [rad], + right side down, |roll| <= pi (+-pi: upside down)
};

/** A correction of a sensor pose, added term by term: height [m], pitch and roll [rad]. */
struct PoseCorrection
{
  double height = 0.0;
  double pitch = 0.0;
  double roll = 0.0;
};

/**
 * Which of a Pipeline's fast paths its frames replace by their plain reference (Pipeline's constructor; default:
 * none), for tests, checks and users that compare the two. Each fast path gives the reference's bits, but for the
 * border-crossing binning, whose ranges may differ where a pixel's centre lies within float rounding of a bin's
 * border. Per Pipeline: two pipelines of one process may take different paths. Docs: docs/core_design.md.
 */
struct ReferencePaths
{
  bool labels = false;    ///< every row labelled pixel by pixel by the rule (no labelling by value thresholds, a
                          ///< floor profile's offsets looked up pixel by pixel, not by runs of one lift step)
  bool binning = false;   ///< every row binned by its pixel centres' bearings (no binning from the bins' borders)
  bool opening = false;   ///< cv::morphologyEx for every opening (no row kernels, no streamed 3x3 opening)
  bool portable = false;  ///< the plain loops instead of the SIMD kernels written with Highway (the labelling by
                          ///< value's row split, the pixels' thresholds by a gather and the scan's pull; the same
                          ///< bits: kinect_pipeline/simd.h)
  /** @return all four on: the reference path. */
  static ReferencePaths all() { return {true, true, true, true}; }
};

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
/** The labels' names, indexed by value: the one list the binding, the tools and the node use. */
constexpr std::array<const char*, kNumLabels> kLabelNames = {"kept", "invalid", "floor", "above_ceiling",
                                                             "below_floor"};

}  // namespace kinect_pipeline
