/**
 * @file kinect_pipeline_ros.h
 * @brief The ROS 1 skin over the core, shared by the nodelet and the standalone node.
 */
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include <boost/thread/recursive_mutex.hpp>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/publisher.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/Float64.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "kinect_pipeline/KinectPipelineConfig.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/ros/master_reconnect.h"
#include "kinect_pipeline/settings_exchange.h"

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
  std::string pose_fallback = "static";  ///< static | last | drop
  double pose_max_age = 0.5;
};

/**
 * @brief Settings from a dynamic_reconfigure config: validated as a whole.
 * @throw std::invalid_argument naming the field(s) and value(s) for values or combinations the core refuses.
 */
NodeSettings settingsFromConfig(const KinectPipelineConfig& c);

/** Why a frame was dropped (counted and reported in diagnostics). */
enum class DropReason : int
{
  kEncoding = 0,
  kImage,
  kCameraInfo,
  kSize,
  kNoPose,
  kStamp,
  kZeroStamp,
  kProcessing,
  kInternal,
  kCount
};
const char* toString(DropReason r);

/**
 * Subscribes a depth image + camera_info, runs the core at the pose of the image's stamp and publishes the
 * scan, the cleaned depth image and (when someone listens) a debug image of the labels.
 *
 * Topics (node namespace, remappable): in `image` (+ its `camera_info`), `imu`, `base_pitch`; out `scan`,
 * `image_processed`, `image_labels`, `/diagnostics`; tf: broadcasts base_frame -> scan_frame.
 */
class KinectPipelineRos
{
public:
  /** @param name used in log messages */
  KinectPipelineRos(ros::NodeHandle nh, ros::NodeHandle pnh, const std::string& name);
  ~KinectPipelineRos();

  /** Frames processed / dropped so far (for tests and diagnostics). */
  std::uint64_t framesOut() const { return frames_out_; }

private:
  void imageCb(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  void reconfigureCb(KinectPipelineConfig& config, uint32_t level);
  void imuCb(const sensor_msgs::ImuConstPtr& msg);
  void pitchCb(const std_msgs::Float64ConstPtr& msg);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);
  /** The frame's work; imageCb() wraps it so that no exception ever leaves a callback. */
  void processImage(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info);
  /** After a master restart: the parameters in force back onto the (new) parameter server. */
  void republishParameters();
  void drop(DropReason reason, const std::string& message);
  /** @return false when the frame must be dropped; @p why says what happened otherwise (fallbacks). */
  bool poseFor(const NodeSettings& s, const std_msgs::Header& header, SensorPose& pose, double& yaw,
               bool& have_position, geometry_msgs::Vector3& position);

  ros::NodeHandle nh_, pnh_;
  std::string name_;
  image_transport::ImageTransport it_;
  image_transport::CameraSubscriber sub_;
  image_transport::Publisher depth_pub_, debug_pub_;
  ros::Publisher scan_pub_, cliff_pub_;
  ros::Subscriber imu_sub_, pitch_sub_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;

  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<KinectPipelineConfig>> reconfigure_;
  // Only the reconfigure callback (under reconfigure_mutex_) touches these two.
  bool have_good_config_ = false;
  KinectPipelineConfig last_good_config_;

  /** Validated settings from the reconfigure callback to the frame callback (ROS-free, see the core). */
  SettingsExchange<NodeSettings> exchange_;
  std::shared_ptr<const NodeSettings> active_;  // only the frame callback touches it

  /** The base pose of a topic (imu or base_pitch), kept per source. */
  struct TopicPose
  {
    double pitch = 0.0, roll = 0.0;
    ros::Time stamp;
    bool valid = false;
  };
  std::mutex topic_mutex_;  // guards imu_pose_ and pitch_pose_
  TopicPose imu_pose_, pitch_pose_;

  // Only the frame callback touches these.
  FramePipeline pipeline_;
  FrameResult result_;
  cv::Mat swap_buffer_;
  Camera camera_;
  bool last_pose_valid_ = false;
  SensorPose last_pose_{};
  double last_yaw_ = 0.0;
  ros::Time last_pose_stamp_, last_stamp_, last_clock_;

  diagnostic_updater::Updater diagnostics_;
  ros::WallTimer diagnostics_timer_;  // diagnostics keep coming when every frame is dropped
  double min_freq_ = 1.0, max_freq_ = 60.0;
  diagnostic_updater::FrequencyStatus input_freq_;
  std::mutex stats_mutex_;
  std::atomic<std::uint64_t> frames_in_{0}, frames_out_{0};
  std::array<std::uint64_t, static_cast<int>(DropReason::kCount)> drops_{};
  std::array<ros::WallTime, static_cast<int>(DropReason::kCount)> last_drop_log_{};
  std::uint64_t pose_fallbacks_ = 0;
  std::uint64_t params_refused_ = 0, clock_resets_ = 0, camera_changes_ = 0;
  std::string last_problem_;
  double last_ms_ = 0.0, max_ms_ = 0.0, sum_ms_ = 0.0;
  std::array<std::uint64_t, kNumLabels> label_totals_{};

  std::unique_ptr<MasterReconnect> master_;  // last: its timer calls into the members above
};

}  // namespace kinect_pipeline
