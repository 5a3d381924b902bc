#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

#include <chrono>
#include <sstream>
#include <stdexcept>

#include <boost/make_shared.hpp>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2/LinearMath/Quaternion.h>

#include "kinect_pipeline/ros/conversions.h"
#include "kinect_pipeline/sensor_model.h"
#include "kinect_pipeline/threshold_curve.h"

namespace kinect_pipeline
{
namespace
{
/** ~sensor_model: the preset's fields onto the parameter server where they are not set there (an explicit
 *  threshold_curve, range_max or cliff_min_pixels wins), before the reconfigure server reads them. */
void applySensorModelParameters(ros::NodeHandle& pnh, const std::string& who)
{
  std::string name;
  if (!pnh.getParam("sensor_model", name) || name.empty())
    return;
  Config preset;
  try
  {
    applySensorModel(name, preset);
  }
  catch (const std::invalid_argument& e)
  {
    ROS_FATAL("%s: %s; not starting", who.c_str(), e.what());
    throw;
  }
  std::string set;
  for (const std::string& field : sensorModelFields())
  {
    if (pnh.hasParam(field))
      continue;
    if (field == "threshold_curve")
      pnh.setParam(field, formatThresholdCurve(preset.threshold_curve));
    else if (field == "range_max")
      pnh.setParam(field, preset.range_max);
    else if (field == "cliff_min_pixels")
      pnh.setParam(field, preset.cliff_min_pixels);
    set += (set.empty() ? "" : ", ") + field;
  }
  ROS_INFO("%s: sensor_model %s (%s): %s from the preset", who.c_str(), name.c_str(),
           sensorModel(name).description.c_str(), set.empty() ? "nothing" : set.c_str());
}
}  // namespace

const char* toString(DropReason r)
{
  switch (r)
  {
    case DropReason::kEncoding:
      return "unsupported encoding";
    case DropReason::kImage:
      return "malformed image";
    case DropReason::kCameraInfo:
      return "bad camera_info";
    case DropReason::kSize:
      return "image size differs from camera_info";
    case DropReason::kNoPose:
      return "no pose";
    case DropReason::kStamp:
      return "stamp out of order";
    case DropReason::kZeroStamp:
      return "zero stamp";
    case DropReason::kProcessing:
      return "refused by the core";
    case DropReason::kInternal:
      return "internal error";
    default:
      return "?";
  }
}

NodeSettings settingsFromConfig(const KinectPipelineConfig& c)
{
  NodeSettings s;
  Config& k = s.core;
  k.sensor_height = c.sensor_height;
  k.sensor_pitch = c.sensor_pitch;
  k.sensor_roll = c.sensor_roll;
  k.ceiling_height = c.ceiling_height;
  k.max_depth = c.max_depth;
  k.geometry = geometryFromString(c.geometry);
  k.projection = projectionFromString(c.projection);
  k.open_kernel_size = c.open_kernel_size;
  k.open_kernel_shape = kernelShapeFromString(c.open_kernel_shape);
  k.threshold_curve = parseThresholdCurve(c.threshold_curve);
  k.range_min = c.range_min;
  k.range_max = c.range_max;
  k.scan_beams = c.scan_beams;
  k.scan_fov = c.scan_fov;
  k.cliff_scan = c.cliff_scan;
  k.cliff_in_scan = c.cliff_in_scan;
  k.surface_band = c.surface_band;
  k.cliff_min_pixels = c.cliff_min_pixels;
  k.confidence_window = c.confidence_window;
  k.confidence_distance = c.confidence_distance;
  k.min_intensity = c.min_intensity;
  k.intensity_filter = c.intensity_filter;
  k.num_threads = c.num_threads;
  k.validate();
  s.pose_source = c.pose_source;
  if (s.pose_source != "tf" && s.pose_source != "imu" && s.pose_source != "pitch_topic" && s.pose_source != "static")
    throw std::invalid_argument("pose_source = '" + s.pose_source + "': expected tf, imu, pitch_topic or static");
  s.pose_fallback = c.pose_fallback;
  if (s.pose_fallback != "static" && s.pose_fallback != "last" && s.pose_fallback != "drop")
    throw std::invalid_argument("pose_fallback = '" + s.pose_fallback + "': expected static, last or drop");
  s.base_frame = c.base_frame;
  s.scan_frame = c.scan_frame;
  if (s.pose_source == "tf" && s.base_frame.empty())
    throw std::invalid_argument("base_frame is empty but pose_source = 'tf' needs a gravity-aligned base frame");
  if (s.scan_frame.empty())
    throw std::invalid_argument("scan_frame is empty: the LaserScan needs a frame");
  if (s.scan_frame == s.base_frame)
    throw std::invalid_argument("scan_frame = base_frame = '" + s.base_frame + "': the node broadcasts base_frame -> "
                                "scan_frame, so they must differ");
  s.base_frame_height = c.base_frame_height;
  s.tf_timeout = c.tf_timeout;
  s.pose_max_age = c.pose_max_age;
  return s;
}

KinectPipelineRos::KinectPipelineRos(ros::NodeHandle nh, ros::NodeHandle pnh, const std::string& name)
  : nh_(nh)
  , pnh_(pnh)
  , name_(name)
  , it_(nh)
  , tf_listener_(tf_buffer_)
  , diagnostics_(nh, pnh)
  , input_freq_(diagnostic_updater::FrequencyStatusParam(&min_freq_, &max_freq_, 0.1, 10))
{
  // Everything a callback touches exists before the first subscription: in a nodelet manager with several
  // threads, callbacks may run before this constructor returns.
  diagnostics_.setHardwareID(name_);
  diagnostics_.add(input_freq_);
  diagnostics_.add("processing", this, &KinectPipelineRos::diagnose);
  applySensorModelParameters(pnh_, name_);
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<KinectPipelineConfig>>(reconfigure_mutex_, pnh_);
  reconfigure_->setCallback([this](KinectPipelineConfig& c, uint32_t level) { reconfigureCb(c, level); });
  // roscpp does not register again with a restarted master: this does, for the whole process.
  const std::string me = ros::this_node::getName();
  master_ = std::make_unique<MasterReconnect>(
      std::vector<std::string>{pnh_.resolveName("set_parameters"), me + "/get_loggers", me + "/set_logger_level",
                               me + "/load_nodelet", me + "/unload_nodelet", me + "/list"},
      [this] { republishParameters(); });
  // Diagnostics keep coming when every frame is dropped or none arrives; only this timer publishes them.
  diagnostics_timer_ =
      nh_.createWallTimer(ros::WallDuration(0.5), [this](const ros::WallTimerEvent&) { diagnostics_.update(); });

  scan_pub_ = nh_.advertise<sensor_msgs::LaserScan>("scan", 10);
  cliff_pub_ = nh_.advertise<sensor_msgs::LaserScan>("cliff_scan", 10);
  depth_pub_ = it_.advertise("image_processed", 1);
  debug_pub_ = it_.advertise("image_labels", 1);
  imu_sub_ = nh_.subscribe("imu", 50, &KinectPipelineRos::imuCb, this);
  pitch_sub_ = nh_.subscribe("base_pitch", 50, &KinectPipelineRos::pitchCb, this);
  // ~image_transport selects the transport (raw, compressedDepth, ...).
  sub_ = it_.subscribeCamera("image", 2, &KinectPipelineRos::imageCb, this,
                             image_transport::TransportHints("raw", ros::TransportHints().tcpNoDelay(), pnh_));
  ROS_INFO("%s: listening on %s (+ camera_info), publishing %s", name_.c_str(), sub_.getTopic().c_str(),
           scan_pub_.getTopic().c_str());
}

void KinectPipelineRos::republishParameters()
{
  boost::recursive_mutex::scoped_lock lock(reconfigure_mutex_);
  if (have_good_config_)
    reconfigure_->updateConfig(last_good_config_);  // back onto the parameter server, and to parameter_updates
}

KinectPipelineRos::~KinectPipelineRos()
{
  // Stop what calls into this object before its members go.
  sub_.shutdown();
  imu_sub_.shutdown();
  pitch_sub_.shutdown();
  diagnostics_timer_.stop();
  master_.reset();
}

void KinectPipelineRos::reconfigureCb(KinectPipelineConfig& config, uint32_t /*level*/)
{
  // Runs under reconfigure_mutex_ (the server's), on the thread of the set_parameters service.
  try
  {
    exchange_.post(std::make_shared<const NodeSettings>(settingsFromConfig(config)));
    last_good_config_ = config;
    have_good_config_ = true;
  }
  catch (const std::invalid_argument& e)
  {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++params_refused_;
      last_problem_ = std::string("parameters refused: ") + e.what();
    }
    ROS_ERROR("%s: parameters refused: %s; keeping the previous values", name_.c_str(), e.what());
    if (have_good_config_)
      config = last_good_config_;  // the server then publishes the values in force
    else
    {
      config = KinectPipelineConfig::__getDefault__();
      exchange_.post(std::make_shared<const NodeSettings>(settingsFromConfig(config)));
      last_good_config_ = config;
      have_good_config_ = true;
    }
  }
}

void KinectPipelineRos::imuCb(const sensor_msgs::ImuConstPtr& msg)
{
  double pitch, roll;
  conversions::pitchRollFromQuaternion(msg->orientation, pitch, roll);
  std::lock_guard<std::mutex> lock(topic_mutex_);
  imu_pose_.pitch = pitch;
  imu_pose_.roll = roll;
  imu_pose_.stamp = msg->header.stamp.isZero() ? ros::Time::now() : msg->header.stamp;
  imu_pose_.valid = true;
}

void KinectPipelineRos::pitchCb(const std_msgs::Float64ConstPtr& msg)
{
  std::lock_guard<std::mutex> lock(topic_mutex_);
  pitch_pose_.pitch = msg->data;
  pitch_pose_.roll = 0.0;
  pitch_pose_.stamp = ros::Time::now();  // Float64 has no header: its arrival time stands for its stamp
  pitch_pose_.valid = true;
}

void KinectPipelineRos::drop(DropReason reason, const std::string& message)
{
  // Throttled per reason (one line per reason every 5 s), so that one bad input does not hide another.
  const int i = static_cast<int>(reason);
  std::uint64_t count = 0;
  bool say = false;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    count = ++drops_[i];
    last_problem_ = std::string(toString(reason)) + ": " + message;
    const ros::WallTime now = ros::WallTime::now();
    if (last_drop_log_[i].isZero() || (now - last_drop_log_[i]).toSec() >= 5.0)
    {
      last_drop_log_[i] = now;
      say = true;
    }
  }
  if (say)
    ROS_ERROR("%s: frame dropped (%s): %s [%llu dropped for this reason so far]", name_.c_str(), toString(reason),
              message.c_str(), static_cast<unsigned long long>(count));
}

bool KinectPipelineRos::poseFor(const NodeSettings& s, const std_msgs::Header& header, SensorPose& pose, double& yaw,
                                bool& have_position, geometry_msgs::Vector3& position)
{
  const Config& k = s.core;
  const SensorPose fixed{k.sensor_height, k.sensor_pitch, k.sensor_roll};
  have_position = false;
  yaw = 0.0;
  std::string why;
  if (s.pose_source == "static")
  {
    pose = fixed;
    return true;
  }
  if (s.pose_source == "tf")
  {
    try
    {
      const geometry_msgs::TransformStamped t =
          tf_buffer_.lookupTransform(s.base_frame, header.frame_id, header.stamp, ros::Duration(s.tf_timeout));
      pose = conversions::poseFromOpticalTransform(t.transform, s.base_frame_height, yaw);
      position = t.transform.translation;
      have_position = true;
      last_pose_ = pose;
      last_yaw_ = yaw;
      last_pose_stamp_ = header.stamp;
      last_pose_valid_ = true;
      return true;
    }
    catch (const tf2::TransformException& e)
    {
      why = std::string("no transform ") + s.base_frame + " <- " + header.frame_id + " at the image stamp: " + e.what();
    }
  }
  else
  {
    TopicPose topic;
    {
      std::lock_guard<std::mutex> lock(topic_mutex_);
      topic = s.pose_source == "imu" ? imu_pose_ : pitch_pose_;
    }
    const double age = topic.valid ? std::fabs((header.stamp - topic.stamp).toSec()) : 1e9;
    if (topic.valid && age <= s.pose_max_age)
    {
      pose = SensorPose{k.sensor_height, k.sensor_pitch + topic.pitch, k.sensor_roll + topic.roll};
      return true;
    }
    std::ostringstream m;
    m << (s.pose_source == "imu" ? "imu" : "base_pitch") << " topic: "
      << (topic.valid ? "last message " + std::to_string(age) + " s from the image stamp" : "nothing received yet")
      << " (pose_max_age " << s.pose_max_age << " s)";
    why = m.str();
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++pose_fallbacks_;
    last_problem_ = why;
  }
  if (s.pose_fallback == "static")
  {
    ROS_WARN_THROTTLE(5.0, "%s: %s; using the static pose (pose_fallback = static)", name_.c_str(), why.c_str());
    pose = fixed;
    return true;
  }
  if (s.pose_fallback == "last" && last_pose_valid_ &&
      std::fabs((header.stamp - last_pose_stamp_).toSec()) <= s.pose_max_age)
  {
    ROS_WARN_THROTTLE(5.0, "%s: %s; using the last pose (pose_fallback = last)", name_.c_str(), why.c_str());
    pose = last_pose_;
    yaw = last_yaw_;
    return true;
  }
  drop(DropReason::kNoPose, why);
  return false;
}

void KinectPipelineRos::imageCb(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::CameraInfoConstPtr& info)
{
  // A perception node must not stop serving because of one frame: nothing may leave this callback.
  try
  {
    processImage(image, info);
  }
  catch (const std::exception& e)
  {
    drop(DropReason::kInternal, std::string("unexpected exception: ") + e.what());
  }
  catch (...)
  {
    drop(DropReason::kInternal, "unexpected exception of unknown type");
  }
}

void KinectPipelineRos::processImage(const sensor_msgs::ImageConstPtr& image,
                                     const sensor_msgs::CameraInfoConstPtr& info)
{
  const auto t0 = std::chrono::steady_clock::now();
  ++frames_in_;
  input_freq_.tick();
  exchange_.take(active_);  // settings change between frames only, and whole
  if (!active_)
    return;
  const NodeSettings& s = *active_;

  // The clock jumped back (a bag played again with use_sim_time, a simulation restarted): start over, as
  // tf2_ros's listener does with its buffer.
  const ros::Time now = ros::Time::now();
  if (!last_clock_.isZero() && now < last_clock_)
  {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++clock_resets_;
    }
    ROS_WARN("%s: ROS time moved backwards (%.3f -> %.3f s): forgetting the last stamp, pose and confidence history",
             name_.c_str(), last_clock_.toSec(), now.toSec());
    last_stamp_ = ros::Time();
    last_pose_valid_ = false;
    pipeline_.reset();
  }
  last_clock_ = now;

  if (image->header.stamp.isZero())
  {
    return drop(DropReason::kZeroStamp, "image stamp is 0 (frame_id '" + image->header.frame_id +
                                            "'): the driver did not stamp it, so neither its pose nor the scan's "
                                            "time is known; expected the capture time");
  }
  if (!last_stamp_.isZero() && image->header.stamp <= last_stamp_)
  {
    std::ostringstream m;
    m.precision(9);
    m << std::fixed << "stamp " << image->header.stamp.toSec() << " is not newer than the previous frame's "
      << last_stamp_.toSec() << " (expected increasing stamps)";
    return drop(DropReason::kStamp, m.str());
  }
  Camera cam;
  cv::Mat depth;
  try
  {
    cam = conversions::cameraFromInfo(*info);
  }
  catch (const std::invalid_argument& e)
  {
    return drop(DropReason::kCameraInfo, e.what());
  }
  try
  {
    depth = conversions::depthFromImage(*image, swap_buffer_);
  }
  catch (const std::invalid_argument& e)
  {
    return drop(conversions::isSupportedEncoding(image->encoding) ? DropReason::kImage : DropReason::kEncoding, e.what());
  }
  if (depth.cols != cam.width || depth.rows != cam.height)
  {
    std::ostringstream m;
    m << "depth image is " << depth.cols << "x" << depth.rows << " but its camera_info says " << cam.width << "x"
      << cam.height;
    return drop(DropReason::kSize, m.str());
  }

  SensorPose pose;
  double yaw;
  bool have_position;
  geometry_msgs::Vector3 position;
  if (!poseFor(s, image->header, pose, yaw, have_position, position))
    return;

  try
  {
    // Re-configured only when the settings object or the camera changed (a camera may change its resolution).
    pipeline_.process(std::shared_ptr<const Config>(active_, &active_->core), cam, depth, pose, result_);
  }
  catch (const std::invalid_argument& e)
  {
    return drop(DropReason::kProcessing, e.what());
  }
  if (cam != camera_)
  {
    if (camera_.width > 0)
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++camera_changes_;
    }
    ROS_INFO("%s: camera %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f", name_.c_str(), cam.width, cam.height, cam.fx, cam.fy,
             cam.cx, cam.cy);
    camera_ = cam;
  }

  const double scan_time = last_stamp_.isZero() ? 0.0 : (image->header.stamp - last_stamp_).toSec();
  last_stamp_ = image->header.stamp;
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  conversions::toLaserScan(result_.scan, image->header, s.scan_frame, scan_time, *scan);
  scan_pub_.publish(scan);
  if (!result_.cliff.ranges.empty())
  {
    auto cliff = boost::make_shared<sensor_msgs::LaserScan>();
    conversions::toLaserScan(result_.cliff, image->header, s.scan_frame, scan_time, *cliff);
    cliff_pub_.publish(cliff);
  }
  if (depth_pub_.getNumSubscribers() > 0)
  {
    auto out = boost::make_shared<sensor_msgs::Image>();
    conversions::toImage(result_.depth, image->header, image->encoding, *out);
    depth_pub_.publish(out);
  }
  if (debug_pub_.getNumSubscribers() > 0)
  {
    auto out = boost::make_shared<sensor_msgs::Image>();
    conversions::toDebugImage(result_.depth, result_.labels, s.core.max_depth, image->header, *out);
    debug_pub_.publish(out);
  }
  if (have_position)
  {
    geometry_msgs::TransformStamped t;
    t.header.stamp = image->header.stamp;
    t.header.frame_id = s.base_frame;
    t.child_frame_id = s.scan_frame;
    t.transform.translation = position;
    tf2::Quaternion q;
    q.setRPY(0.0, 0.0, yaw);
    t.transform.rotation.x = q.x();
    t.transform.rotation.y = q.y();
    t.transform.rotation.z = q.z();
    t.transform.rotation.w = q.w();
    tf_broadcaster_.sendTransform(t);
  }
  ++frames_out_;
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    last_ms_ = ms;
    max_ms_ = std::max(max_ms_, ms);
    sum_ms_ += ms;
    for (int k = 0; k < kNumLabels; ++k)
      label_totals_[k] += result_.counts[k];
  }
}

void KinectPipelineRos::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(stats_mutex_);
  std::uint64_t dropped = 0;
  for (auto d : drops_)
    dropped += d;
  const std::uint64_t out = frames_out_;
  if (out == 0 && dropped == 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no frame yet");
  else if (dropped > 0 && !last_problem_.empty())
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%llu frame(s) dropped; last: %s",
                  static_cast<unsigned long long>(dropped), last_problem_.c_str());
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "processing");
  stat.add("frames in", static_cast<unsigned long long>(frames_in_.load()));
  stat.add("frames out", static_cast<unsigned long long>(out));
  for (int i = 0; i < static_cast<int>(DropReason::kCount); ++i)
    stat.add(std::string("dropped: ") + toString(static_cast<DropReason>(i)), static_cast<unsigned long long>(drops_[i]));
  stat.add("pose fallbacks", static_cast<unsigned long long>(pose_fallbacks_));
  stat.add("parameters refused", static_cast<unsigned long long>(params_refused_));
  stat.add("clock jumps back", static_cast<unsigned long long>(clock_resets_));
  stat.add("camera model changes", static_cast<unsigned long long>(camera_changes_));
  stat.add("master reconnections", static_cast<unsigned long long>(master_ ? master_->reconnections() : 0));
  stat.add("master registration failures", static_cast<unsigned long long>(master_ ? master_->failures() : 0));
  stat.add("processing time last [ms]", last_ms_);
  stat.add("processing time max [ms]", max_ms_);
  stat.add("processing time mean [ms]", out ? sum_ms_ / out : 0.0);
  std::uint64_t total = 0;
  for (auto n : label_totals_)
    total += n;
  const char* names[kNumLabels] = {"kept", "invalid", "floor", "above ceiling", "below floor"};
  for (int k = 0; k < kNumLabels; ++k)
    stat.add(std::string("fraction ") + names[k], total ? static_cast<double>(label_totals_[k]) / total : 0.0);
}

}  // namespace kinect_pipeline
