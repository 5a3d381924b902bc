#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <boost/make_shared.hpp>
#include <geometry_msgs/TransformStamped.h>
#include <image_transport/camera_common.h>
#include <image_transport/exception.h>
#include <sensor_msgs/LaserScan.h>
#include <tf2/LinearMath/Quaternion.h>

#include "kinect_pipeline/io/compressed_depth.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/simd.h"
#include "kinect_pipeline/ros/conversions.h"

namespace kinect_pipeline
{
namespace
{
constexpr double kDeg = 180.0 / 3.14159265358979323846;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

std::string seconds(const ros::Time& t)
{
  std::ostringstream s;
  s.precision(9);
  s << std::fixed << t.toSec();
  return s.str();
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
    case DropReason::kCompressed:
      return "bad compressedDepth payload";
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
    case DropReason::kNoCameraInfo:
      return "no camera_info";
    default:
      return "?";
  }
}

KinectPipelineRos::KinectPipelineRos(ros::NodeHandle nh, ros::NodeHandle pnh, const std::string& name)
  : nh_(nh)
  , pnh_(pnh)
  , name_(name)
  , it_(nh)
  , tf_listener_(tf_buffer_)
  , diagnostics_(nh, pnh, name)  // a nodelet's statuses carry its own name, not its manager's
  , input_freq_(diagnostic_updater::FrequencyStatusParam(&min_freq_, &max_freq_, 0.1, 10))
{
  // First what may stop the node, before anything runs: every bad parameter at once, and the transport.
  for (const std::string& w : unknownParameterWarnings(pnh_))
    ROS_WARN("%s: %s", name_.c_str(), w.c_str());
  applySensorModelParameters(pnh_, name_);  // the preset's values are then checked as if the user had set them
  startupSettings(pnh_, name_);
  try  // KINECT_PIPELINE_SIMD (kinect_pipeline/simd.h): a target this CPU lacks would refuse every frame
  {
    ROS_INFO("%s: SIMD target %s", name_.c_str(), simdTarget().c_str());
  }
  catch (const std::invalid_argument& e)
  {
    throw StartupError(name_ + ": not starting: " + e.what());
  }
  const std::string transport = checkTransport();
  transport_ = transport;
  image_topic_ = nh_.resolveName("image");
  info_topic_ = image_transport::getCameraInfoTopic(image_topic_);
  if (transport == "compressedDepth" || transport == "compressed")
    image_topic_ += "/" + transport;  // a CompressedImage topic, subscribed and decoded here

  // Everything a callback touches exists before the first subscription: in a nodelet manager with several
  // threads, callbacks may run before this constructor returns.
  diagnostics_.setHardwareID(name_);
  diagnostics_.add("Frequency Status", this, &KinectPipelineRos::diagnoseRate);
  diagnostics_.add("processing", this, &KinectPipelineRos::diagnose);
  diagnostics_.add("floor refinement", this, &KinectPipelineRos::diagnoseFloor);
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<KinectPipelineConfig>>(reconfigure_mutex_, pnh_);
  reconfigure_->setCallback([this](KinectPipelineConfig& c, uint32_t level) { reconfigureCb(c, level); });
  // roscpp does not register again with a restarted master: this does, for the whole process.
  const std::string me = ros::this_node::getName();
  master_ = std::make_unique<MasterReconnect>(
      std::vector<std::string>{pnh_.resolveName("set_parameters"), me + "/get_loggers", me + "/set_logger_level",
                               me + "/load_nodelet", me + "/unload_nodelet", me + "/list"},
      [this] { republishParameters(); });
  // Diagnostics keep coming when every frame is dropped, none arrives, or ROS time jumps back (Updater::update()
  // would wait for ROS time to pass its next deadline again): only this wall timer publishes them.
  started_ = ros::WallTime::now();
  diagnostics_timer_ = nh_.createWallTimer(ros::WallDuration(0.5), [this](const ros::WallTimerEvent&) {
    checkClock();
    warnIfWaiting();
    diagnostics_.force_update();
  });

  scan_pub_ = nh_.advertise<sensor_msgs::LaserScan>("scan", 10);
  cliff_pub_ = nh_.advertise<sensor_msgs::LaserScan>("cliff_scan", 10);
  depth_pub_ = it_.advertise("image_processed", 1);
  debug_pub_ = it_.advertise("image_labels", 1);
  imu_sub_ = nh_.subscribe("imu", 50, &KinectPipelineRos::imuCb, this);
  pitch_sub_ = nh_.subscribe("base_pitch", 50, &KinectPipelineRos::pitchCb, this);
  subscribe(transport);
}

std::string KinectPipelineRos::checkTransport()
{
  std::string transport;
  pnh_.param<std::string>("image_transport", transport, "raw");
  if (transport == "raw" || transport == "compressedDepth" || transport == "compressed")
    return transport;
  std::vector<std::string> loadable;
  for (std::string t : it_.getLoadableTransports())
    loadable.push_back(t.rfind("image_transport/", 0) == 0 ? t.substr(16) : t);
  if (std::find(loadable.begin(), loadable.end(), transport) != loadable.end())
    return transport;
  std::string names;
  for (const std::string& t : loadable)
    names += (names.empty() ? "" : ", ") + t;
  throw StartupError(name_ + ": ~image_transport = '" + transport +
                     "': no image_transport plugin for it is installed (image_transport can load: " + names +
                     "). Expected raw, compressedDepth or compressed (both decoded by kinect_pipeline itself) or an "
                     "installed transport.");
}

void KinectPipelineRos::subscribe(const std::string& transport)
{
  // The image and its camera_info are subscribed apart and paired here (CameraInfoPairing): image_transport's
  // CameraSubscriber pairs by exact stamp only, and says nothing useful when camera_info never comes.
  const ros::TransportHints hints = ros::TransportHints().tcpNoDelay();
  info_sub_ = nh_.subscribe(info_topic_, 5, &KinectPipelineRos::infoCb, this, hints);
  if (transport == "compressedDepth" || transport == "compressed")
  {
    // Debian has image_transport's raw plugin only: compressedDepth (compressed_depth_image_transport) and 16-bit
    // PNG compressed (compressed_image_transport) are decoded here, from the topic their publishers write.
    compressed_sub_ = nh_.subscribe(image_topic_, 2, &KinectPipelineRos::compressedCb, this, hints);
    ROS_INFO("%s: listening on %s (decoded here) + %s, publishing %s", name_.c_str(), image_topic_.c_str(),
             info_topic_.c_str(), scan_pub_.getTopic().c_str());
    return;
  }
  try
  {
    image_sub_ = it_.subscribe("image", 2, &KinectPipelineRos::imageCb, this,
                               image_transport::TransportHints(transport, hints, pnh_));
  }
  catch (const image_transport::TransportLoadException& e)
  {
    throw StartupError(name_ + ": ~image_transport = '" + transport + "' cannot be loaded: " + e.what());
  }
  ROS_INFO("%s: listening on %s (transport %s) + %s, publishing %s", name_.c_str(), image_topic_.c_str(),
           transport.c_str(), info_topic_.c_str(), scan_pub_.getTopic().c_str());
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
  image_sub_.shutdown();
  compressed_sub_.shutdown();
  info_sub_.shutdown();
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
    // The startup check refused bad values already: this is a change at run time.
    if (!have_good_config_)
      throw StartupError(name_ + ": not starting: " + e.what());
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++params_refused_;
      last_problem_ = std::string("parameters refused: ") + e.what();
    }
    ROS_ERROR("%s: parameters refused: %s; keeping the previous values", name_.c_str(), e.what());
    config = last_good_config_;  // the server then publishes the values in force
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

void KinectPipelineRos::drop(DropReason reason, const std::string& message, bool log)
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
  if (say && log)
    ROS_ERROR("%s: frame dropped (%s): %s [%llu dropped for this reason so far]", name_.c_str(), toString(reason),
              message.c_str(), static_cast<unsigned long long>(count));
}

std::uint64_t KinectPipelineRos::checkClock()
{
  std::lock_guard<std::mutex> lock(clock_mutex_);
  const ros::Time now = ros::Time::now();
  if (!clock_seen_ && !now.isZero())
  {
    // The first clock (with use_sim_time, /clock may start after the node): the rate window starts here, not
    // at time 0, which would report "Frequency too low" until the window had rolled over.
    clock_seen_ = true;
    restartRate();
  }
  else if (clock_seen_ && now < last_clock_)
  {
    ++clock_epoch_;
    {
      std::lock_guard<std::mutex> stats(stats_mutex_);
      ++clock_resets_;
    }
    restartRate();
    ROS_WARN("%s: ROS time moved backwards, from %.3f to %.3f s (a bag played again with --clock, a simulation "
             "restarted): starting over (stamps, pose, confidence, rate window, learned floor correction)",
             name_.c_str(), last_clock_.toSec(), now.toSec());
    clock_seen_ = !now.isZero();
  }
  last_clock_ = now;
  return clock_epoch_;
}

void KinectPipelineRos::restartRate()
{
  input_freq_.clear();
  ticks_since_rate_restart_ = 0;
  rate_restarted_at_ = std::chrono::steady_clock::now().time_since_epoch().count();
}

void KinectPipelineRos::restart(const std::string& why)
{
  if (!why.empty())
  {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++stamp_resets_;
    }
    restartRate();
    ROS_WARN("%s: %s: starting over (confidence, rate window, learned floor correction, last pose)", name_.c_str(),
             why.c_str());
  }
  pipeline_.reset();
  last_stamp_ = ros::Time();
  last_good_.reset();
  static_warned_ = false;
}

template <typename F>
void KinectPipelineRos::guarded(F&& work)
{
  // A perception node must not stop serving because of one frame: nothing may leave a callback.
  try
  {
    work();
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

void KinectPipelineRos::imageCb(const sensor_msgs::ImageConstPtr& image)
{
  guarded([&] { received(Input{image->header, nullptr, image, nullptr}); });
}

void KinectPipelineRos::compressedCb(const sensor_msgs::CompressedImageConstPtr& image)
{
  guarded([&] { received(Input{image->header, nullptr, nullptr, image}); });
}

void KinectPipelineRos::infoCb(const sensor_msgs::CameraInfoConstPtr& info)
{
  guarded([&] {
    std::lock_guard<std::mutex> lock(frame_mutex_);
    {
      std::lock_guard<std::mutex> stats(stats_mutex_);
      ++infos_in_;
    }
    CameraInfoPairing::Outcome out = pairing_.info(info);
    if (!out.paired.empty() || !out.given_up.empty())
      paired(std::move(out), checkClock());
  });
}

void KinectPipelineRos::received(Input in)
{
  std::lock_guard<std::mutex> lock(frame_mutex_);
  // The clock first: a rate window it restarts must count this frame.
  const std::uint64_t epoch = checkClock();
  ++frames_in_;
  input_freq_.tick();
  ++ticks_since_rate_restart_;
  exchange_.take(active_);  // settings change between frames only, and whole
  if (active_ && active_->camera_info)
  {
    in.info = active_->camera_info;  // ~intrinsics or ~camera_info_url: no camera_info topic needed
    {
      std::lock_guard<std::mutex> stats(stats_mutex_);
      ++paired_param_;
      camera_from_ = active_->camera_info_from;
    }
    return arrive(in, epoch);
  }
  if (pairing_.infos() == 0)
  {
    std::lock_guard<std::mutex> stats(stats_mutex_);
    if (images_without_info_++ == 0)
      first_without_info_ = ros::WallTime::now();
  }
  paired(pairing_.image(std::move(in)), epoch);
}

void KinectPipelineRos::paired(CameraInfoPairing::Outcome&& out, std::uint64_t epoch)
{
  for (const Input& lost : out.given_up)
  {
    const auto& latest = pairing_.latest();
    // Without any camera_info the timer's warning says it (warnIfWaiting()); counted here either way.
    drop(DropReason::kNoCameraInfo,
         "no camera_info for the image of stamp " + seconds(lost.header.stamp) + " on " + info_topic_ +
             (latest ? " (the latest has stamp " + seconds(latest->header.stamp) + " and the camera changed, so "
                                                                                   "it is not used for other stamps)"
                     : std::string(" (none received yet)")),
         latest != nullptr);
  }
  {
    std::lock_guard<std::mutex> stats(stats_mutex_);
    paired_exact_ = pairing_.paired(InfoMatch::kExactStamp);
    paired_latest_ = pairing_.paired(InfoMatch::kLatest);
  }
  for (Input& in : out.paired)
  {
    const bool exact = in.info->header.stamp == in.header.stamp;
    {
      std::lock_guard<std::mutex> stats(stats_mutex_);
      camera_from_ = info_topic_ + (exact ? " (same stamp)" : " (the latest; its stamps differ from the images')");
    }
    if (!exact && !recency_said_)
    {
      recency_said_ = true;
      ROS_INFO("%s: the camera_info on %s has other stamps than the images (image %s, camera_info %s s): each image "
               "is paired with the latest camera_info while it does not change (K, D, size, frame); counted in "
               "/diagnostics",
               name_.c_str(), info_topic_.c_str(), seconds(in.header.stamp).c_str(),
               seconds(in.info->header.stamp).c_str());
    }
    exchange_.take(active_);
    arrive(in, epoch);
  }
}

void KinectPipelineRos::warnIfWaiting()
{
  std::uint64_t without = 0, in = frames_in_.load();
  ros::WallTime first;
  const ros::WallTime now = ros::WallTime::now();
  {
    std::lock_guard<std::mutex> stats(stats_mutex_);
    without = infos_in_ == 0 ? images_without_info_ : 0;
    first = first_without_info_;
    const bool due = last_wait_warning_.isZero() || (now - last_wait_warning_).toSec() >= 10.0;
    const double since = (now - (without ? first : started_)).toSec();
    // Images without camera_info are said within seconds; no image at all only after a while (a driver starting).
    if (!due || (without == 0 && in > 0) || since < (without ? 2.0 : 10.0))
      return;
    last_wait_warning_ = now;
  }
  if (without > 0)
  {
    ROS_WARN("%s: %llu image(s) on %s in %.1f s but no sensor_msgs/CameraInfo on %s: waiting for it, no scan "
             "without the camera's intrinsics. If the camera or bag has none, give ~camera_info_url (a camera_info "
             "YAML as camera_calibration writes it, file:///...) or ~intrinsics 'fx fy cx cy width height' "
             "(README, 'No CameraInfo?')",
             name_.c_str(), static_cast<unsigned long long>(without), image_topic_.c_str(), (now - first).toSec(),
             info_topic_.c_str());
    return;
  }
  // No image at all (the diagnostics timer may not ask the master: it must not block while the master is away).
  ROS_WARN("%s: no image on %s (~image_transport %s) in %.0f s; if the camera publishes another transport (%s "
           "and /compressedDepth: decoded here), set ~image_transport (launch image_transport:=...) to it",
           name_.c_str(), image_topic_.c_str(), transport_.c_str(), (now - started_).toSec(),
           (nh_.resolveName("image") + "/compressed").c_str());
}

void KinectPipelineRos::arrive(const Input& in, std::uint64_t epoch)
{
  if (!active_)
    return;
  if (epoch != clock_epoch_seen_)
  {
    // ROS time jumped back (warned by checkClock()): the stamps start over with it, as tf2's buffer does.
    // A frame held as older than the last one may be the new timeline's first, seen before its clock.
    clock_epoch_seen_ = epoch;
    std::optional<Input> held;
    held.swap(pending_);
    restart("");
    if (held && held->header.stamp < in.header.stamp)
      process(*held);
    else if (held)
    {
      pending_ = std::move(held);
      dropPending();
    }
  }
  if (in.header.stamp.isZero())
  {
    return drop(DropReason::kZeroStamp, "image stamp is 0 (frame_id '" + in.header.frame_id +
                                            "'): the driver did not stamp it, so neither its pose nor the scan's "
                                            "time is known; expected the capture time");
  }
  if (inOrder(in))
    process(in);
}

bool KinectPipelineRos::inOrder(const Input& in)
{
  const ros::Time stamp = in.header.stamp;
  if (!last_stamp_.isZero() && stamp == sequence_start_ && stamp <= last_stamp_)
  {
    // The first stamp of this sequence again: a bag played in a loop (with a single frame, nothing else tells).
    // A held frame older than it is the new pass's first (the sequence began with the bag's second frame when
    // the first was published before this node was connected): it is served, not dropped.
    std::optional<Input> first;
    if (pending_ && pending_->header.stamp < stamp)
      first.swap(pending_);
    else if (pending_)
      dropPending();
    restart("the image stamps jumped back from " + seconds(last_stamp_) + " to " +
            seconds(first ? first->header.stamp : stamp) + " s, the first stamp of this sequence " +
            "(a bag played again or in a loop)");
    if (first)
      process(*first);
    return last_stamp_.isZero() || stamp > last_stamp_;
  }
  if (pending_)
  {
    if (stamp <= last_stamp_ && stamp > pending_->header.stamp)
    {
      // Two frames in order, both older than the last one: the stamps jumped back (a bag played in a loop with
      // wall time, a camera restarted). The held frame is the first of the new timeline.
      const Input first = *pending_;
      pending_.reset();
      restart("the image stamps jumped back from " + seconds(last_stamp_) + " to " + seconds(first.header.stamp) +
              " s (a bag played again or in a loop, a driver restarted)");
      process(first);
      return last_stamp_.isZero() || stamp > last_stamp_;
    }
    dropPending();  // a stray late frame, or this one is older still
  }
  if (last_stamp_.isZero() || stamp > last_stamp_)
    return true;
  pending_ = in;
  pending_previous_ = last_stamp_;
  return false;
}

void KinectPipelineRos::dropPending()
{
  std::ostringstream m;
  m << "stamp " << seconds(pending_->header.stamp) << " is not newer than the previous frame's "
    << seconds(pending_previous_) << " (expected increasing stamps)";
  pending_.reset();
  drop(DropReason::kStamp, m.str());
}

bool KinectPipelineRos::depthOf(const Input& in, const Camera& cam, cv::Mat& depth, std::string& encoding)
{
  if (in.image)
  {
    try
    {
      depth = conversions::depthFromImage(*in.image, swap_buffer_);
    }
    catch (const std::invalid_argument& e)
    {
      drop(conversions::isSupportedEncoding(in.image->encoding) ? DropReason::kImage : DropReason::kEncoding,
           e.what());
      return false;
    }
    encoding = in.image->encoding;
    return true;
  }
  try
  {
    depth = conversions::depthFromCompressed(*in.compressed, cv::Size(cam.width, cam.height));
  }
  catch (const std::invalid_argument& e)
  {
    drop(DropReason::kCompressed, e.what());
    return false;
  }
  encoding = depth.type() == CV_16UC1 ? "16UC1" : "32FC1";
  return true;
}

void KinectPipelineRos::process(const Input& in)
{
  const auto t0 = Clock::now();
  const NodeSettings& s = *active_;
  Camera cam;
  try
  {
    cam = conversions::cameraFromInfo(*in.info);
  }
  catch (const std::invalid_argument& e)
  {
    return drop(DropReason::kCameraInfo, e.what());
  }
  cv::Mat depth;
  std::string encoding;
  if (!depthOf(in, cam, depth, encoding))
    return;
  if (depth.cols != cam.width || depth.rows != cam.height)
  {
    std::ostringstream m;
    m << "depth image is " << depth.cols << "x" << depth.rows << " but its camera_info says " << cam.width << "x"
      << cam.height << " (its roi and binning applied)";
    return drop(DropReason::kSize, m.str());
  }
  if (!rectify(s, *in.info, cam, depth))
    return;

  FramePose pose;
  tf_wait_ms_ = 0.0;
  if (!poseFor(s, in.header, pose))
    return;
  try
  {
    // Re-configured only when the settings object or the camera changed (a camera may change its resolution).
    pipeline_.process(std::shared_ptr<const Config>(active_, &active_->core), cam, depth, pose.pose, result_,
                      in.header.stamp.toSec());
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
    ROS_INFO("%s: camera %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f; SIMD target %s", name_.c_str(), cam.width, cam.height,
             cam.fx, cam.fy, cam.cx, cam.cy, simdTarget().c_str());
    camera_ = cam;
  }
  publish(s, in, encoding);
  broadcastScanFrame(s, in.header, pose);
  ++frames_out_;
  record(pose.pose, msSince(t0));
}

bool KinectPipelineRos::rectify(const NodeSettings& s, const sensor_msgs::CameraInfo& info, Camera& cam,
                                cv::Mat& depth)
{
  try
  {
    // Assigned into the member: no allocation per frame once it holds a lens of this size.
    lens_.model = info.distortion_model;
    lens_.D.assign(info.D.begin(), info.D.end());
    std::copy(info.R.begin(), info.R.end(), lens_.R.begin());
    depth = rectification_.apply(s.rectify, image_topic_, cam, lens_, depth);
  }
  catch (const std::invalid_argument& e)
  {
    drop(DropReason::kCameraInfo, std::string(e.what()) + " to rectify the images (~rectify " + s.rectify +
                                      "; never if they are rectified already)");
    return false;
  }
  try
  {
    if (!rectification_.rectifies())  // a rectified image's camera is P's (the same as K's for most drivers)
      cam = conversions::rectifiedCameraFromInfo(info);
  }
  catch (const std::invalid_argument& e)
  {
    drop(DropReason::kCameraInfo, std::string(e.what()) + " (of its P: the rectified image's camera)");
    return false;
  }
  if (rectification_.decidedAnew())
  {
    if (rectification_.distorts())
      ROS_INFO("%s: the images on %s rectified (camera_info distortion_model '%s', ~rectify %s): %s", name_.c_str(),
               image_topic_.c_str(), info.distortion_model.c_str(), s.rectify.c_str(), rectification_.why().c_str());
    std::lock_guard<std::mutex> stats(stats_mutex_);
    rectified_ = rectification_.why();
  }
  return true;
}

void KinectPipelineRos::publish(const NodeSettings& s, const Input& in, const std::string& encoding)
{
  const std_msgs::Header& header = in.header;
  const double scan_time = last_stamp_.isZero() ? 0.0 : (header.stamp - last_stamp_).toSec();
  if (last_stamp_.isZero())
    sequence_start_ = header.stamp;
  last_stamp_ = header.stamp;
  auto scan = boost::make_shared<sensor_msgs::LaserScan>();
  conversions::toLaserScan(result_.scan, header, s.scan_frame, scan_time, *scan);
  scan_pub_.publish(scan);
  if (!result_.cliff.ranges.empty())
  {
    auto cliff = boost::make_shared<sensor_msgs::LaserScan>();
    conversions::toLaserScan(result_.cliff, header, s.scan_frame, scan_time, *cliff);
    cliff_pub_.publish(cliff);
  }
  if (depth_pub_.getNumSubscribers() > 0)
  {
    auto out = boost::make_shared<sensor_msgs::Image>();
    conversions::toImage(result_.depth, header, encoding, *out);
    depth_pub_.publish(out);
  }
  if (debug_pub_.getNumSubscribers() > 0)
  {
    auto out = boost::make_shared<sensor_msgs::Image>();
    conversions::toDebugImage(result_.depth, result_.labels, s.core.max_depth, header, *out);
    debug_pub_.publish(out);
  }
}

void KinectPipelineRos::record(const SensorPose& prior, double ms)
{
  // The processing time leaves out the wait for tf, which is reported on its own.
  const double work = std::max(0.0, ms - tf_wait_ms_);
  std::lock_guard<std::mutex> lock(stats_mutex_);
  last_ms_ = work;
  max_ms_ = std::max(max_ms_, work);
  sum_ms_ += work;
  last_wait_ms_ = tf_wait_ms_;
  max_wait_ms_ = std::max(max_wait_ms_, tf_wait_ms_);
  for (int k = 0; k < kNumLabels; ++k)
    label_totals_[k] += result_.counts[k];
  speckle_total_ += result_.speckles;
  rolled_frames_ += result_.level_rows ? 0 : 1;
  last_fit_ = result_.floor_fit;
  ++floor_counts_[static_cast<int>(last_fit_.status)];
  last_prior_ = prior;
  last_used_ = result_.pose;
  refine_on_ = active_->core.refine_floor;
}

}  // namespace kinect_pipeline
