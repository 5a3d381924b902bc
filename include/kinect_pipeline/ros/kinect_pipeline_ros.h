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
#include <optional>
#include <string>

#include <boost/thread/recursive_mutex.hpp>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/publisher.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <std_msgs/Float64.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include "kinect_pipeline/KinectPipelineConfig.h"
#include "kinect_pipeline/io/rectify.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/ros/camera_info_pairing.h"
#include "kinect_pipeline/ros/master_reconnect.h"
#include "kinect_pipeline/ros/parameters.h"
#include "kinect_pipeline/settings_exchange.h"

namespace kinect_pipeline
{

/** Why a frame was dropped (counted and reported in diagnostics). */
enum class DropReason : int
{
  kEncoding = 0,
  kImage,
  kCompressed,
  kCameraInfo,
  kSize,
  kNoPose,
  kStamp,
  kZeroStamp,
  kProcessing,
  kInternal,
  kNoCameraInfo,
  kCount
};
const char* toString(DropReason r);

/** @return the node's --help text: topics, the main parameters (from the .cfg), where the README is. */
std::string usageText();

/**
 * Subscribes a depth image + camera_info, runs the core at the pose of the image's stamp and publishes the
 * scan, the cleaned depth image and (when someone listens) a debug image of the labels.
 *
 * Topics (node namespace, remappable): in `image` (+ its `camera_info`, or the camera from ~intrinsics or
 * ~camera_info_url; `image/compressedDepth` or `image/compressed` with ~image_transport compressedDepth or
 * compressed), `imu`, `base_pitch`; out `scan`, `cliff_scan`, `image_processed`,
 * `image_labels`, `/diagnostics`; tf: base_frame -> scan_frame (pose_source tf), else the image's frame -> scan_frame.
 */
class KinectPipelineRos
{
public:
  /**
   * @param name used in log messages
   * @throw StartupError for parameters it cannot honour or an input transport it cannot load, naming them all
   */
  KinectPipelineRos(ros::NodeHandle nh, ros::NodeHandle pnh, const std::string& name);
  ~KinectPipelineRos();

  /** Frames processed / dropped so far (for tests and diagnostics). */
  std::uint64_t framesOut() const { return frames_out_; }

private:
  /** One input frame, kept whole while its fate is open (see CameraInfoPairing and inOrder()). */
  using Input = DepthInput;
  /** A pose for one frame and where it came from. */
  struct FramePose
  {
    SensorPose pose{0.0, 0.0, 0.0};
    double yaw = 0.0;                 ///< the sensor's heading in base_frame (tf)
    bool have_position = false;       ///< position and yaw are known (tf, or the last tf pose)
    geometry_msgs::Vector3 position;  ///< the sensor in base_frame (tf)
  };
  struct GoodPose
  {
    FramePose pose;
    ros::Time stamp;
    std::string frame_id;  ///< the image frame it is the pose of
    bool from_tf = false;
  };

  std::string checkTransport();
  void subscribe(const std::string& transport);
  void imageCb(const sensor_msgs::ImageConstPtr& image);
  void compressedCb(const sensor_msgs::CompressedImageConstPtr& image);
  void infoCb(const sensor_msgs::CameraInfoConstPtr& info);
  /** An image arrives: counted, then paired with its camera_info (now, later or never), then arrive(). */
  void received(Input in);
  /** What the pairing gave: the paired frames arrive(), the ones given up are dropped. */
  void paired(CameraInfoPairing::Outcome&& out, std::uint64_t epoch);
  /** Called by the diagnostics timer: a warning while images come without any camera_info, or none come. */
  void warnIfWaiting();
  void reconfigureCb(KinectPipelineConfig& config, uint32_t level);
  void imuCb(const sensor_msgs::ImuConstPtr& msg);
  void pitchCb(const std_msgs::Float64ConstPtr& msg);
  void diagnoseRate(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);
  void diagnoseFloor(diagnostic_updater::DiagnosticStatusWrapper& stat);
  /** Wraps a frame callback so that no exception ever leaves it. */
  template <typename F>
  void guarded(F&& work);
  /** A frame arrives with its camera_info: clock and stamp checks, then process() (now, later or never). */
  void arrive(const Input& in, std::uint64_t epoch);
  /** The frame's work once its stamp is accepted. */
  void process(const Input& in);
  /** @return false when the frame must be dropped. */
  bool depthOf(const Input& in, const Camera& cam, cv::Mat& depth, std::string& encoding);
  /**
   * @return true if the frame is to be processed now. A frame older than the last one is held: the next frame
   *         tells whether it was a stray late frame (then dropped as out of order) or the first of a timeline that
   *         jumped back (then the history restarts and it is processed).
   */
  bool inOrder(const Input& in);
  void dropPending();
  /** The history starts over (a jump back of the stamps or the clock): one warning when @p why is not empty. */
  void restart(const std::string& why);
  /** The input rate's window starts now (the first clock, a jump back). */
  void restartRate();
  /** Follows ROS time (frame callback and diagnostics timer): @return the number of jumps back so far. */
  std::uint64_t checkClock();
  /** After a master restart: the parameters in force back onto the (new) parameter server. */
  void republishParameters();
  /** Counts a dropped frame; @p log: also an error line (throttled per reason). */
  void drop(DropReason reason, const std::string& message, bool log = true);
  /** @return false when the frame must be dropped. */
  bool poseFor(const NodeSettings& s, const std_msgs::Header& header, FramePose& pose);
  bool fallback(const NodeSettings& s, const std_msgs::Header& header, const std::string& why, FramePose& pose);
  void warnIfStaticDisagrees(const NodeSettings& s, const SensorPose& fixed);
  void broadcastScanFrame(const NodeSettings& s, const std_msgs::Header& header, const FramePose& pose);
  /**
   * The image rectified by ~rectify (TopicRectification), and its camera: K's where it was rectified here, else the
   * rectified image's (P's where set); false: dropped (a distortion it cannot take, a P the core refuses).
   */
  bool rectify(const NodeSettings& s, const sensor_msgs::CameraInfo& info, Camera& cam, cv::Mat& depth);
  void publish(const NodeSettings& s, const Input& in, const std::string& encoding);
  void record(const SensorPose& prior, double ms);

  ros::NodeHandle nh_, pnh_;
  std::string name_;
  image_transport::ImageTransport it_;
  image_transport::Subscriber image_sub_;
  ros::Subscriber compressed_sub_, info_sub_;
  std::string image_topic_, info_topic_, transport_;
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

  // Only the frame callbacks (image and camera_info, one at a time under frame_mutex_) touch these.
  std::mutex frame_mutex_;
  CameraInfoPairing pairing_;
  bool recency_said_ = false;  // that images are paired with the latest camera_info was said
  ros::Time sequence_start_;   // the first stamp since the history started (a bag's loop starts there again)
  FramePipeline pipeline_;
  FrameResult result_;
  cv::Mat swap_buffer_;
  TopicRectification rectification_;
  CameraLens lens_;  // the frame's camera_info lens (rectify())
  Camera camera_;
  std::optional<GoodPose> last_good_;
  bool static_warned_ = false;       // the static pose's disagreement with tf was said in this fallback
  bool scan_frame_warned_ = false;   // that scan_frame cannot be broadcast was said
  ros::Time last_stamp_;
  std::optional<Input> pending_;     // a frame older than the last one, until the next frame tells what it was
  ros::Time pending_previous_;       // last_stamp_ when it came
  std::uint64_t clock_epoch_seen_ = 0;
  double tf_wait_ms_ = 0.0;

  std::mutex clock_mutex_;  // guards the three below
  ros::Time last_clock_;
  std::uint64_t clock_epoch_ = 0;
  bool clock_seen_ = false;

  diagnostic_updater::Updater diagnostics_;
  ros::WallTimer diagnostics_timer_;  // diagnostics keep coming when every frame is dropped, whatever ROS time does
  double min_freq_ = 1.0, max_freq_ = 60.0;
  diagnostic_updater::FrequencyStatus input_freq_;
  std::atomic<std::uint64_t> ticks_since_rate_restart_{0};
  std::atomic<std::int64_t> rate_restarted_at_{0};  // steady clock ticks; 0: never
  std::mutex stats_mutex_;
  std::atomic<std::uint64_t> frames_in_{0}, frames_out_{0};
  std::array<std::uint64_t, static_cast<int>(DropReason::kCount)> drops_{};
  std::array<ros::WallTime, static_cast<int>(DropReason::kCount)> last_drop_log_{};
  std::uint64_t pose_fallbacks_ = 0, fallbacks_last_ = 0, fallbacks_static_ = 0, static_disagreements_ = 0;
  std::uint64_t params_refused_ = 0, clock_resets_ = 0, stamp_resets_ = 0, camera_changes_ = 0;
  // camera_info: images that came while none had come (and no camera from parameters), and how frames were paired.
  std::uint64_t images_without_info_ = 0, infos_in_ = 0, paired_exact_ = 0, paired_latest_ = 0, paired_param_ = 0;
  std::string camera_from_;               // where the last frame's camera came from
  std::string rectified_;                 // whether and why the frames are rectified (TopicRectification::why)
  ros::WallTime first_without_info_, last_wait_warning_, started_;
  std::string last_problem_;
  double last_ms_ = 0.0, max_ms_ = 0.0, sum_ms_ = 0.0, last_wait_ms_ = 0.0, max_wait_ms_ = 0.0;
  std::array<std::uint64_t, kNumLabels> label_totals_{};
  std::uint64_t speckle_total_ = 0;  // pixels taken as wrong matches (Config::speckle_jump)
  std::uint64_t rolled_frames_ = 0;  // frames on the roll paths (FrameResult::level_rows false)
  // The floor refinement, as of the last frame.
  std::array<std::uint64_t, kNumFloorFitStatus> floor_counts_{};
  FloorFitResult last_fit_;
  SensorPose last_prior_{0.0, 0.0, 0.0}, last_used_{0.0, 0.0, 0.0};
  bool refine_on_ = true;
  std::optional<SensorPose> static_minus_tf_;  // the static pose minus the last tf pose

  std::unique_ptr<MasterReconnect> master_;  // last: its timer calls into the members above
};

}  // namespace kinect_pipeline
