// KinectPipelineRos: what /diagnostics says, and the node's --help.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "kinect_pipeline/ros/kinect_pipeline_ros.h"
#include "kinect_pipeline/simd.h"

namespace kinect_pipeline
{
namespace
{
constexpr double kDeg = 180.0 / 3.14159265358979323846;

/** "30 mm lower", "1.00 deg less down": how the true pose differs from the told one, by a correction. */
std::string correctionText(const PoseCorrection& c)
{
  char buf[200];
  std::snprintf(buf, sizeof buf, "the sensor sits %.0f mm %s, looks %.2f deg %s and is rolled %.2f deg %s than told",
                std::fabs(c.height) * 1000.0, c.height >= 0 ? "higher" : "lower", std::fabs(c.pitch) * kDeg,
                c.pitch >= 0 ? "further down" : "less down", std::fabs(c.roll) * kDeg,
                c.roll >= 0 ? "more right side down" : "more left side down");
  return buf;
}

void addCorrection(diagnostic_updater::DiagnosticStatusWrapper& stat, const std::string& what, const PoseCorrection& c)
{
  stat.add(what + " height [mm]", c.height * 1000.0);
  stat.add(what + " pitch [deg]", c.pitch * kDeg);
  stat.add(what + " roll [deg]", c.roll * kDeg);
}

void addPose(diagnostic_updater::DiagnosticStatusWrapper& stat, const std::string& what, const SensorPose& p)
{
  stat.add(what + " height [m]", p.height);
  stat.add(what + " pitch [deg]", p.pitch * kDeg);
  stat.add(what + " roll [deg]", p.roll * kDeg);
}
}  // namespace

void KinectPipelineRos::diagnoseRate(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  if (ros::Time::now().isZero())
  {
    // use_sim_time and no /clock yet: no rate can be measured (the window starts with the first clock).
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for /clock (use_sim_time is true)");
    return;
  }
  // Right after the window restarted, before the next frame, there is nothing to judge yet (not "No events").
  const auto since = std::chrono::steady_clock::now().time_since_epoch().count() - rate_restarted_at_.load();
  if (rate_restarted_at_.load() != 0 && ticks_since_rate_restart_.load() == 0 &&
      std::chrono::steady_clock::duration(since) < std::chrono::seconds(2))
  {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "rate window restarted (the clock or the stamps jumped)");
    return;
  }
  input_freq_.run(stat);
}

void KinectPipelineRos::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(stats_mutex_);
  std::uint64_t dropped = 0;
  for (auto d : drops_)
    dropped += d;
  const std::uint64_t out = frames_out_;
  if (out == 0 && infos_in_ == 0 && images_without_info_ > 0)
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN,
                  "waiting for camera_info on %s: %llu image(s) without it (no camera_info topic? set "
                  "~camera_info_url or ~intrinsics)",
                  info_topic_.c_str(), static_cast<unsigned long long>(images_without_info_));
  else if (out == 0 && dropped == 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no frame yet");
  else if (dropped > 0 && !last_problem_.empty())
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%llu frame(s) dropped; last: %s",
                  static_cast<unsigned long long>(dropped), last_problem_.c_str());
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "processing");
  stat.add("frames in", static_cast<unsigned long long>(frames_in_.load()));
  stat.add("frames out", static_cast<unsigned long long>(out));
  stat.add("images without camera_info", static_cast<unsigned long long>(images_without_info_));
  stat.add("camera_info received", static_cast<unsigned long long>(infos_in_));
  stat.add("camera_info paired: same stamp", static_cast<unsigned long long>(paired_exact_));
  stat.add("camera_info paired: latest (stamps differ, camera unchanged)", static_cast<unsigned long long>(paired_latest_));
  stat.add("camera from parameters (frames)", static_cast<unsigned long long>(paired_param_));
  stat.add("camera from", camera_from_.empty() ? std::string("(no frame yet)") : camera_from_);
  stat.add("rectified", rectified_.empty() ? std::string("(no frame yet)") : rectified_);
  stat.add("SIMD target", simdTarget());  // kinect_pipeline/simd.h; KINECT_PIPELINE_SIMD restricts it
  for (int i = 0; i < static_cast<int>(DropReason::kCount); ++i)
    stat.add(std::string("dropped: ") + toString(static_cast<DropReason>(i)), static_cast<unsigned long long>(drops_[i]));
  stat.add("pose fallbacks", static_cast<unsigned long long>(pose_fallbacks_));
  stat.add("pose fallbacks: last good pose", static_cast<unsigned long long>(fallbacks_last_));
  stat.add("pose fallbacks: static pose", static_cast<unsigned long long>(fallbacks_static_));
  stat.add("static pose far from tf (warned)", static_cast<unsigned long long>(static_disagreements_));
  if (static_minus_tf_)
    addPose(stat, "static minus tf pose:", *static_minus_tf_);
  stat.add("parameters refused", static_cast<unsigned long long>(params_refused_));
  stat.add("clock jumps back", static_cast<unsigned long long>(clock_resets_));
  stat.add("stamp jumps back", static_cast<unsigned long long>(stamp_resets_));
  stat.add("camera model changes", static_cast<unsigned long long>(camera_changes_));
  stat.add("master reconnections", static_cast<unsigned long long>(master_ ? master_->reconnections() : 0));
  stat.add("master registration failures", static_cast<unsigned long long>(master_ ? master_->failures() : 0));
  stat.add("processing time last [ms]", last_ms_);
  stat.add("processing time max [ms]", max_ms_);
  stat.add("processing time mean [ms]", out ? sum_ms_ / out : 0.0);
  stat.add("tf wait last [ms]", last_wait_ms_);
  stat.add("tf wait max [ms]", max_wait_ms_);
  // A roll not 0 or +-pi (an IMU's, a tilted mount's) labels every pixel on its own: about twice the time.
  stat.add("frames with roll (pixel by pixel)", static_cast<unsigned long long>(rolled_frames_));
  std::uint64_t total = 0;
  for (auto n : label_totals_)
    total += n;
  for (int k = 0; k < kNumLabels; ++k)
  {
    std::string name = kLabelNames[k];  // the core's list; "above_ceiling" reads "fraction above ceiling"
    std::replace(name.begin(), name.end(), '_', ' ');
    stat.add("fraction " + name, total ? static_cast<double>(label_totals_[k]) / total : 0.0);
  }
  stat.add("fraction taken as wrong matches (speckle_jump)", total ? static_cast<double>(speckle_total_) / total : 0.0);
}

namespace
{
// The learned floor profile as "2.25 m: +1.2 cm, 2.75 m: +2.0 cm" over the bands that hold one ("none" else).
std::string profileText(const FloorProfileBands& p)
{
  std::ostringstream s;
  s.setf(std::ios::fixed);
  for (int k = 0; k < FloorProfileBands::kBands; ++k)
    if (p.bias[k] != 0.0f)
      s << (s.tellp() > 0 ? ", " : "") << std::setprecision(2) << (k + 0.5) * FloorProfileBands::kBandWidth
        << " m: " << std::showpos << std::setprecision(1) << 100.0 * p.bias[k] << std::noshowpos << " cm";
  return s.tellp() > 0 ? s.str() : "none";
}
}  // namespace

void KinectPipelineRos::diagnoseFloor(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const FloorFitResult& f = last_fit_;
  std::uint64_t fits = 0;
  for (auto n : floor_counts_)
    fits += n;
  const std::string learned = "learned correction: " + correctionText(f.learned);
  if (fits == 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "no frame yet");
  else if (!refine_on_)
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "off (refine_floor false): the pose as given");
  else if (f.status == FloorFitStatus::kOutOfBounds)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                 "last fit out of bounds: the floor in view is farther from the told pose than floor_max_*_error "
                 "allow (fix the mounting: URDF or sensor_*); " + learned);
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "last fit " + toString(f.status) + "; " + learned);
  stat.add("last status", toString(f.status));
  for (int i = 0; i < kNumFloorFitStatus; ++i)
    stat.add("fits " + toString(static_cast<FloorFitStatus>(i)), static_cast<unsigned long long>(floor_counts_[i]));
  stat.add("candidate samples", f.candidates);
  stat.add("support samples", f.support);
  stat.add("support pixels", f.pixels);
  stat.add("residual spread [t(d)]", f.spread);
  stat.add("fit shift [t(d)]", f.shift);  // below 0.1: noise, the frame keeps the prior
  addCorrection(stat, "correction", f.applied);
  addCorrection(stat, "learned", f.learned);
  stat.add("floor profile (band centre: floor beyond the plane)", profileText(f.profile));
  addPose(stat, "told pose", last_prior_);
  addPose(stat, "pose used", last_used_);
  stat.add("to fix the mounting", learned);
}

std::string usageText()
{
  std::ostringstream u;
  u << "kinect_pipeline_node: a depth image in, a LaserScan of the nearest obstacle per direction (and a cliff scan,\n"
       "a cleaned depth image) out. The floor and a ceiling plane are predicted from the sensor's pose and refined\n"
       "from the frame's own floor.\n\n"
       "usage: rosrun kinect_pipeline kinect_pipeline_node [image:=TOPIC] [_NAME:=VALUE ...]\n"
       "       roslaunch kinect_pipeline kinect_pipeline.launch [camera:=kinect2] [manager:=MANAGER] ...\n\n"
       "Subscribed (node namespace, remappable):\n"
       "  image, camera_info   sensor_msgs/Image (8UC1/mono8, 16UC1/mono16 mm, 32FC1 m) + CameraInfo (or the camera\n"
       "                       from _camera_info_url:=file:///cam.yaml or _intrinsics:='fx fy cx cy width height');\n"
       "                       _image_transport:=compressedDepth or compressed: image/compressedDepth or\n"
       "                       image/compressed (CompressedImage; 16-bit PNG), decoded here\n"
       "  imu                  sensor_msgs/Imu, base pitch and roll (pose_source imu)\n"
       "  base_pitch           std_msgs/Float64, base pitch [rad] (pose_source pitch_topic)\n"
       "  /tf, /tf_static      the image's frame in base_frame (pose_source tf)\n"
       "Published:\n"
       "  scan, cliff_scan     sensor_msgs/LaserScan in scan_frame (REP 117)\n"
       "  image_processed      the cleaned depth image; image_labels: an rgb8 picture of the labels\n"
       "  /diagnostics         rate, drops, processing time, the floor refinement and its learned correction\n"
       "  /tf                  base_frame -> scan_frame (pose_source tf); else the image's frame -> scan_frame\n\n"
       "Main parameters (private: _name:=value, or a YAML file through the launch file's params:=):\n";
  const KinectPipelineConfig& d = KinectPipelineConfig::__getDefault__();
  const std::vector<std::string> main{"pose_source", "base_frame", "scan_frame", "sensor_height", "sensor_pitch",
                                      "ceiling_height", "range_min", "range_max", "refine_floor", "pose_hold_time",
                                      "pose_fallback", "camera_info_url", "intrinsics", "num_threads"};
  for (const std::string& name : main)
    for (const auto& p : KinectPipelineConfig::__getParamDescriptions__())
      if (p->name == name)
      {
        boost::any v;
        p->getValue(d, v);
        std::ostringstream def;
        if (p->type == "double")
          def << boost::any_cast<double>(v);
        else if (p->type == "int")
          def << boost::any_cast<int>(v);
        else if (p->type == "bool")
          def << (boost::any_cast<bool>(v) ? "true" : "false");
        else
          def << boost::any_cast<std::string>(v);
        u << "  " << name << " (" << p->type << ", default " << def.str() << "): " << p->description << "\n";
      }
  u << "  image_transport (str, default raw): raw, compressedDepth, compressed (decoded here) or an installed "
       "transport\n\n"
       "Every parameter, with unit and range, and the launch files: README.md, 'ROS interface'";
  for (const char* readme : {KP_README_INSTALLED, KP_README_SOURCE})
    if (std::ifstream(readme).good())
    {
      u << ": " << readme;
      break;
    }
  u << "\n";
  return u.str();
}

}  // namespace kinect_pipeline
