// KinectPipelineRos: where each frame's pose comes from, what stands in when it does not come, and the scan's frame.
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>

#include <geometry_msgs/TransformStamped.h>
#include <tf2/LinearMath/Quaternion.h>

#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/ros/conversions.h"
#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

namespace kinect_pipeline
{
namespace
{
constexpr double kDeg = 180.0 / 3.14159265358979323846;
using Clock = std::chrono::steady_clock;
}  // namespace

bool KinectPipelineRos::poseFor(const NodeSettings& s, const std_msgs::Header& header, FramePose& pose)
{
  const Config& k = s.core;
  const SensorPose fixed{k.sensor_height, k.sensor_pitch, k.sensor_roll};
  pose = FramePose{};
  if (s.pose_source == "static")
  {
    pose.pose = fixed;
    return true;
  }
  std::string why;
  if (s.pose_source == "tf")
  {
    // The wait is on the wall clock: tf2's own timeout counts ROS time, which stands still while a bag is paused
    // or has ended (use_sim_time), and would block this callback, and the node's queue, until the clock moves.
    const auto t0 = Clock::now();
    const auto deadline = t0 + std::chrono::duration<double>(s.tf_timeout);
    while (!tf_buffer_.canTransform(s.base_frame, header.frame_id, header.stamp) && Clock::now() < deadline && ros::ok())
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    try
    {
      const geometry_msgs::TransformStamped t = tf_buffer_.lookupTransform(s.base_frame, header.frame_id, header.stamp);
      pose.pose = conversions::poseFromOpticalTransform(t.transform, s.base_frame_height, pose.yaw);
      pose.position = t.transform.translation;
      pose.have_position = true;
    }
    catch (const tf2::TransformException& e)
    {
      why = std::string("no transform ") + s.base_frame + " <- " + header.frame_id + " at the image stamp: " + e.what();
    }
    tf_wait_ms_ = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
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
      pose.pose = SensorPose{k.sensor_height, k.sensor_pitch + topic.pitch, k.sensor_roll + topic.roll};
    else
    {
      std::ostringstream m;
      m << (s.pose_source == "imu" ? "imu" : "base_pitch") << " topic: "
        << (topic.valid ? "last message " + std::to_string(age) + " s from the image stamp" : "nothing received yet")
        << " (pose_max_age " << s.pose_max_age << " s)";
      why = m.str();
    }
  }
  if (!why.empty())
    return fallback(s, header, why, pose);
  last_good_ = GoodPose{pose, header.stamp, header.frame_id, s.pose_source == "tf"};
  if (last_good_->from_tf)
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    static_minus_tf_ = SensorPose{fixed.height - pose.pose.height, fixed.pitch - pose.pose.pitch,
                                  wrapAngle(fixed.roll - pose.pose.roll)};
  }
  static_warned_ = false;  // a fallback from now on is a new one
  return true;
}

bool KinectPipelineRos::fallback(const NodeSettings& s, const std_msgs::Header& header, const std::string& why,
                                 FramePose& pose)
{
  const Config& k = s.core;
  if (last_good_ && last_good_->frame_id != header.frame_id)
    last_good_.reset();  // the pose of another sensor
  const double age = last_good_ ? std::fabs((header.stamp - last_good_->stamp).toSec())
                                : std::numeric_limits<double>::infinity();
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++pose_fallbacks_;
    last_problem_ = why;
  }
  // First the last good pose, for pose_hold_time (the robot does not move its sensor that fast), then the
  // static pose, or nothing.
  if (last_good_ && (age <= s.pose_hold_time || s.pose_fallback == "last"))
  {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++fallbacks_last_;
    }
    ROS_WARN_THROTTLE(5.0, "%s: %s; using the last good pose, %.2f s old (pose_hold_time %.2f s, pose_fallback %s)",
                      name_.c_str(), why.c_str(), age, s.pose_hold_time, s.pose_fallback.c_str());
    pose = last_good_->pose;
    return true;
  }
  if (s.pose_fallback == "static")
  {
    {
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++fallbacks_static_;
    }
    const SensorPose fixed{k.sensor_height, k.sensor_pitch, k.sensor_roll};
    warnIfStaticDisagrees(s, fixed);
    ROS_WARN_THROTTLE(5.0, "%s: %s; using the static pose (pose_fallback = static%s)", name_.c_str(), why.c_str(),
                      last_good_ ? ", the last good pose is older than pose_hold_time" : "");
    pose = last_good_ ? last_good_->pose : FramePose{};  // where the sensor sits on the robot, for the scan frame
    pose.pose = fixed;
    return true;
  }
  std::ostringstream m;
  m << why;
  if (last_good_)
    m << "; the last good pose is " << age << " s old (pose_hold_time " << s.pose_hold_time << " s)";
  drop(DropReason::kNoPose, m.str());
  return false;
}

void KinectPipelineRos::warnIfStaticDisagrees(const NodeSettings& s, const SensorPose& fixed)
{
  if (static_warned_ || !last_good_ || !last_good_->from_tf)
    return;
  static_warned_ = true;
  const Config& k = s.core;
  const SensorPose& tf = last_good_->pose.pose;
  const double dh = fixed.height - tf.height, dp = fixed.pitch - tf.pitch, dr = wrapAngle(fixed.roll - tf.roll);
  std::ostringstream over;
  over.setf(std::ios::fixed);
  over.precision(2);
  if (std::fabs(dh) > k.floor_max_height_error)
    over << " height by " << dh * 1000.0 << " mm (floor_max_height_error " << k.floor_max_height_error * 1000.0
         << " mm)";
  if (std::fabs(dp) > k.floor_max_pitch_error)
    over << " pitch by " << dp * kDeg << " deg (floor_max_pitch_error " << k.floor_max_pitch_error * kDeg << " deg)";
  if (std::fabs(dr) > k.floor_max_roll_error)
    over << " roll by " << dr * kDeg << " deg (floor_max_roll_error " << k.floor_max_roll_error * kDeg << " deg)";
  if (over.str().empty())
    return;
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++static_disagreements_;
  }
  ROS_WARN("%s: the static pose now standing in for tf (sensor_height %.3f m, sensor_pitch %.2f deg, sensor_roll "
           "%.2f deg) differs from the last tf pose (%.3f m, %.2f deg, %.2f deg) in%s: more than the floor "
           "refinement can correct%s, so the floor may show as obstacles or cliffs. Set sensor_height, sensor_pitch "
           "and sensor_roll to the sensor's mounting, or pose_fallback: drop.",
           name_.c_str(), fixed.height, fixed.pitch * kDeg, fixed.roll * kDeg, tf.height, tf.pitch * kDeg,
           tf.roll * kDeg, over.str().c_str(), k.refine_floor ? "" : " (refine_floor is off: it corrects nothing)");
}

void KinectPipelineRos::broadcastScanFrame(const NodeSettings& s, const std_msgs::Header& header, const FramePose& pose)
{
  geometry_msgs::TransformStamped t;
  t.header.stamp = header.stamp;
  t.child_frame_id = s.scan_frame;
  if (s.pose_source == "tf")
  {
    if (!pose.have_position)
    {
      if (!scan_frame_warned_)
        ROS_WARN("%s: %s is not broadcast until tf has given the sensor's place in %s once", name_.c_str(),
                 s.scan_frame.c_str(), s.base_frame.c_str());
      scan_frame_warned_ = true;
      return;
    }
    // At the sensor, z up, the sensor's heading.
    t.header.frame_id = s.base_frame;
    t.transform.translation = pose.position;
    tf2::Quaternion q;
    q.setRPY(0.0, 0.0, pose.yaw);
    t.transform.rotation.x = q.x();
    t.transform.rotation.y = q.y();
    t.transform.rotation.z = q.z();
    t.transform.rotation.w = q.w();
  }
  else
  {
    // No tf pose: the scan's frame hangs from the image's own frame, levelled by the pose the frame was processed
    // at. Consumers place it wherever the driver's or the URDF's tf places the image's frame.
    if (header.frame_id.empty())
    {
      if (!scan_frame_warned_)
        ROS_WARN("%s: %s is not broadcast: the images have no frame_id to hang it from", name_.c_str(),
                 s.scan_frame.c_str());
      scan_frame_warned_ = true;
      return;
    }
    t.header.frame_id = header.frame_id;
    const RigidTransform r = opticalFromLevel(result_.pose);
    t.transform.rotation.x = r.q[0];
    t.transform.rotation.y = r.q[1];
    t.transform.rotation.z = r.q[2];
    t.transform.rotation.w = r.q[3];
    t.transform.translation.x = t.transform.translation.y = t.transform.translation.z = 0.0;
  }
  tf_broadcaster_.sendTransform(t);
}

}  // namespace kinect_pipeline
