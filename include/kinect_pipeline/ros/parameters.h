/**
 * @file parameters.h
 * @brief The node's parameters: the settings a frame needs, and the checks made before the node starts.
 *
 * At startup the parameter server is read as it is (dynamic_reconfigure would clamp values outside the .cfg's
 * ranges and keep the defaults of values of the wrong type, silently): every bad value is named at once and the
 * node does not start. At run time the reconfigure callback refuses a bad set and keeps the previous one.
 */
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <ros/node_handle.h>
#include <sensor_msgs/CameraInfo.h>

#include "kinect_pipeline/KinectPipelineConfig.h"
#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/** Everything a frame needs from the parameters, swapped in whole between frames. */
struct NodeSettings
{
  Config core;
  std::string pose_source = "tf";  ///< tf | imu | pitch_topic | static
  std::string base_frame = "base_footprint";
  double base_frame_height = 0.0;
  std::string scan_frame = "kinect2_scan";
  double tf_timeout = 0.03;
  double pose_hold_time = 1.0;           ///< [s] the last good pose stands in this long when the source has nothing
  std::string pose_fallback = "static";  ///< after the hold: static | last | drop
  double pose_max_age = 0.5;             ///< [s] oldest imu / pitch topic message used
  std::string rectify = "auto";          ///< auto | always | never (rectifyWanted, io/rectify.h)
  /** The camera from ~intrinsics or ~camera_info_url; null: from the camera_info topic. */
  sensor_msgs::CameraInfoConstPtr camera_info;
  std::string camera_info_from;  ///< "~intrinsics = '...'" or "~camera_info_url = '...'", for messages
};

/**
 * @brief The camera_info the parameters give, for cameras and bags without a camera_info topic.
 * @param intrinsics "fx fy cx cy width height" (spaces or commas), or empty
 * @param url a camera_info YAML (or INI) as camera_calibration writes it: file:///absolute/path or
 *        package://PACKAGE/path, as camera drivers' ~camera_info_url; or empty
 * @param[out] from which parameter it came from, with its value
 * @return null when both are empty
 * @throw std::invalid_argument naming the parameter, its value and what was expected (both set, a URL of another
 *        scheme, a missing file, a file the parser refuses, intrinsics that are not six numbers or no camera)
 */
sensor_msgs::CameraInfoConstPtr cameraInfoFromParameters(const std::string& intrinsics, const std::string& url,
                                                         std::string& from);

/**
 * @brief Settings from a dynamic_reconfigure config: validated as a whole.
 * @throw std::invalid_argument naming every bad field and its value ("~field = value: expected ..."), joined by "; ".
 */
NodeSettings settingsFromConfig(const KinectPipelineConfig& c);

/** The node cannot start as configured (bad parameters, a transport that cannot be loaded). */
class StartupError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/**
 * @brief Reads the node's parameters from the server as dynamic_reconfigure would, but refusing what it would
 *        silently change: a value of the wrong type (kept at its default) or outside the .cfg's range (clamped).
 * @param[out] config the defaults, overwritten by every parameter on the server that passed these checks
 * @return one message per bad parameter ("~range_max = 2000: expected 0 .. 1000 m"), empty if none
 */
std::vector<std::string> serverParameterProblems(const ros::NodeHandle& pnh, KinectPipelineConfig& config);

/**
 * @brief The startup check: every problem of the parameters on the server, the combinations included.
 * @return the settings to start with
 * @throw StartupError naming every bad parameter and its value
 */
NodeSettings startupSettings(const ros::NodeHandle& pnh, const std::string& node_name);

/**
 * @brief ~sensor_model: the preset's fields onto the parameter server where they are not set there (an explicit
 *        threshold_curve, range_max or cliff_min_pixels wins), before the startup check and the reconfigure server
 *        read them.
 * @throw StartupError for an unknown preset, naming the valid ones
 */
void applySensorModelParameters(const ros::NodeHandle& pnh, const std::string& node_name);

/** Private parameters the node reads besides those of the .cfg. */
const std::vector<std::string>& extraParameterNames();

/**
 * @brief The parameter of ours a user most likely meant: for the names of peer packages (depthimage_to_laserscan's
 *        output_frame_id, pointcloud_to_laserscan's target_frame, laserscan_kinect's sensor_mount_height, ...)
 *        the one of the same meaning, else the nearest by edit distance.
 */
std::string closestParameter(const std::string& name);

/**
 * @brief Warnings for the private parameters on the server that the node does not read, one per parameter,
 *        each naming the closest parameter of ours.
 */
std::vector<std::string> unknownParameterWarnings(const ros::NodeHandle& pnh);

/** @return @p message with the core's "Config." prefixes written as ROS private names ("~"). */
std::string asParameterNames(std::string message);

}  // namespace kinect_pipeline
