/**
 * @file synthetic.h
 * @brief Ray-cast renderer of simple scenes with exact ground truth, and a Kinect v2 noise model.
 *
 * Independent of the pipeline's own geometry code (it intersects rays with boxes and planes in double
 * precision), so tests and tools can check the pipeline against it.
 */
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/sensor_model.h"

namespace kinect_pipeline
{

/** Axis-aligned box in the gravity-aligned frame on the floor under the sensor (x fwd, y left, z up) [m]. */
struct Box
{
  double x0, x1, y0, y1, z0, z1;
};

/** A scene: a floor at z = 0 (with rectangular holes down to hole_depth), boxes, and a ceiling if > 0. */
struct Scene
{
  bool floor = true;
  std::vector<Box> boxes;
  std::vector<Box> holes;       ///< footprints (x0..x1, y0..y1) where the floor is missing; z ignored
  double hole_depth = 0.5;      ///< depth of the holes' bottom below the floor [m]
  double ceiling = 0.0;         ///< height of a real ceiling [m]; 0 = none
};

/** Ground truth of a rendered frame, one value per pixel. */
struct Rendering
{
  cv::Mat depth;   ///< CV_32F, depth along the optical axis [m], +Inf where the ray hits nothing
  cv::Mat height;  ///< CV_32F, height of the hit above the floor [m], NaN where nothing is hit
  cv::Mat range;   ///< CV_32F, horizontal distance of the hit from the sensor [m], NaN where nothing is hit
  cv::Mat angle;   ///< CV_32F, bearing of the hit, atan2(y, x) counter-clockwise from forward [rad], NaN if none
  cv::Mat object;  ///< CV_16S: -1 nothing, 0 floor, 1 ceiling, 2 hole bottom, 10 + i box i
};

/**
 * @brief Renders a scene seen by a camera at height @p height with total pitch and roll.
 * @param pitch [rad], + looks down; @param roll [rad], + right side down (rotation order: roll, then pitch)
 */
void renderScene(const Camera& camera, double height, double pitch, double roll, const Scene& scene,
                 Rendering& out);

/**
 * @brief A planar 2-D LiDAR at height @p z (level, at the sensor's x = y = 0) seeing the scene's boxes.
 * @return one range per beam [m], beam i at angle angle_min + i * increment (counter-clockwise from forward);
 *         +Inf where no box is hit within @p range_max
 */
std::vector<float> renderLidar(const Scene& scene, double z, double angle_min, double increment, int beams,
                               double range_max);

/**
 * @brief The depthimage_to_laserscan way, as a baseline for comparisons: per column, the nearest valid depth
 *        within @p band_rows rows around the principal point's row, range z * sqrt(1 + xn^2), no floor removal;
 *        beams one per column, right to left.
 * @param depth_m CV_32F metres (+Inf / NaN unknown)
 * @return ranges [m] (+Inf where the band saw nothing)
 */
std::vector<float> bandScan(const cv::Mat& depth_m, const Camera& camera, int band_rows);

/**
 * @brief Adds Kinect-v2-like depth noise in place: sigma(z) = sigma0 + k * (z - 0.4)^2 (Gaussian), then sets a
 *        fraction of pixels to unknown (+Inf). Seeded: the same seed gives the same frame.
 * @param depth CV_32F metres
 */
void addKinectNoise(cv::Mat& depth, std::uint64_t seed, double sigma0 = 0.0015, double k = 0.0019,
                    double dropout = 0.01);

/**
 * @brief Time-of-flight artefacts of a Kinect v2, in place: pixels beyond @p max_range become unknown (+Inf),
 *        and where a pixel's depth jumps by more than @p edge_jump from a neighbour's, it becomes with probability
 *        @p flying a "flying pixel" somewhere between the two surfaces (uniformly). Seeded.
 * @param depth CV_32F metres
 */
void addTofArtefacts(cv::Mat& depth, std::uint64_t seed, double max_range = 8.0, double flying = 0.5,
                     double edge_jump = 0.3);

/**
 * @brief Converts float metres (+Inf/NaN unknown) into an encoding's image: 8-bit normalised with
 *        @p max_depth (rounded, saturating at 255; unknown -> 0), 16UC1 mm (rounded; unknown -> 0), or a copy.
 * @param type CV_8UC1, CV_16UC1 or CV_32FC1
 */
cv::Mat encodeDepth(const cv::Mat& metres, int type, double max_depth);

}  // namespace kinect_pipeline
