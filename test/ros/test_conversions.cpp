// The ROS boundary on its own: messages <-> core types (no master needed).
#include <gtest/gtest.h>

#include <cmath>

#include <sensor_msgs/image_encodings.h>
#include <tf2/LinearMath/Matrix3x3.h>
#include <tf2/LinearMath/Quaternion.h>
#include <boost/make_shared.hpp>
#include <opencv2/imgcodecs.hpp>

#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/ros/conversions.h"
#include "kinect_pipeline/ros/kinect_pipeline_ros.h"
#include "kinect_pipeline/ros/parameters.h"

using namespace kinect_pipeline;
using namespace kinect_pipeline::conversions;

namespace
{
sensor_msgs::CameraInfo info(double fx = 365.0)
{
  sensor_msgs::CameraInfo i;
  i.width = 512;
  i.height = 424;
  i.K = {fx, 0, 255.5, 0, 366.0, 211.5, 0, 0, 1};
  return i;
}

template <typename F>
std::string message(F f)
{
  try
  {
    f();
  }
  catch (const std::invalid_argument& e)
  {
    return e.what();
  }
  return "no exception";
}

// The optical frame of a sensor with the given pose in a z-up base frame (same convention as the core).
geometry_msgs::Transform opticalTransform(double height, double pitch, double roll, double yaw)
{
  tf2::Matrix3x3 body;
  body.setRPY(roll, pitch, yaw);
  const tf2::Matrix3x3 body_from_optical(0, 0, 1, -1, 0, 0, 0, -1, 0);
  tf2::Quaternion q;
  (body * body_from_optical).getRotation(q);
  geometry_msgs::Transform t;
  t.translation.x = 0.2;
  t.translation.z = height;
  t.rotation.x = q.x();
  t.rotation.y = q.y();
  t.rotation.z = q.z();
  t.rotation.w = q.w();
  return t;
}
}  // namespace

TEST(Conversions, CameraFromInfo)
{
  const Camera c = cameraFromInfo(info());
  EXPECT_EQ(c.width, 512);
  EXPECT_EQ(c.height, 424);
  EXPECT_DOUBLE_EQ(c.fx, 365.0);
  EXPECT_DOUBLE_EQ(c.fy, 366.0);
  EXPECT_DOUBLE_EQ(c.cx, 255.5);
  EXPECT_DOUBLE_EQ(c.cy, 211.5);
  const std::string m = message([] { cameraFromInfo(info(0.0)); });
  EXPECT_NE(m.find("K[0]"), std::string::npos) << m;
  EXPECT_NE(m.find("uncalibrated"), std::string::npos) << m;
  auto bad = info();
  bad.K[4] = NAN;
  EXPECT_NE(message([&] { cameraFromInfo(bad); }).find("fy"), std::string::npos);
}

TEST(Conversions, CameraFromInfoRefusesAMatrixItWouldMisread)
{
  auto skewed = info();
  skewed.K[1] = 0.5;  // 0.29 px at the rows farthest from cy: within a pixel, taken
  EXPECT_DOUBLE_EQ(cameraFromInfo(skewed).fx, 365.0);
  skewed.K[1] = 2.0;  // 1.16 px
  const std::string m = message([&] { cameraFromInfo(skewed); });
  EXPECT_NE(m.find("K[1] (skew) = 2"), std::string::npos) << m;
  EXPECT_NE(m.find("expected |skew| < 1.73"), std::string::npos) << m;
  auto scaled = info();
  scaled.K[8] = 0.0;
  const std::string n = message([&] { cameraFromInfo(scaled); });
  EXPECT_NE(n.find("[fx s cx; 0 fy cy; 0 0 1]"), std::string::npos) << n;
  EXPECT_NE(n.find("0, 0, 0]"), std::string::npos) << n;
}

// REP 104, as image_geometry reads it: the image is the roi of the full-resolution image K describes, subsampled by
// the binning (image_proc's crop_decimate sends its images this way, K and size left at full resolution).
TEST(Conversions, CameraFromInfoTakesItsRoiAndBinning)
{
  auto decimated = info();
  decimated.binning_x = decimated.binning_y = 2;  // roi all 0: the whole image
  Camera c = cameraFromInfo(decimated);
  EXPECT_EQ(c.width, 256);
  EXPECT_EQ(c.height, 212);
  EXPECT_DOUBLE_EQ(c.fx, 182.5);
  EXPECT_DOUBLE_EQ(c.fy, 183.0);
  EXPECT_DOUBLE_EQ(c.cx, 127.75);
  EXPECT_DOUBLE_EQ(c.cy, 105.75);
  auto cropped = info();
  cropped.binning_x = 1;  // 0 and 1: every pixel
  cropped.roi.x_offset = 100;
  cropped.roi.y_offset = 50;
  cropped.roi.width = 301;
  cropped.roi.height = 201;
  c = cameraFromInfo(cropped);
  EXPECT_EQ(c.width, 301);
  EXPECT_EQ(c.height, 201);
  EXPECT_DOUBLE_EQ(c.fx, 365.0);
  EXPECT_DOUBLE_EQ(c.cx, 155.5);
  EXPECT_DOUBLE_EQ(c.cy, 161.5);
  cropped.binning_x = 2;
  cropped.binning_y = 3;
  c = cameraFromInfo(cropped);
  EXPECT_EQ(c.width, 150);  // rounded down, as crop_decimate sends it
  EXPECT_EQ(c.height, 67);
  EXPECT_DOUBLE_EQ(c.cx, 77.75);
  EXPECT_DOUBLE_EQ(c.fy, 122.0);
  EXPECT_DOUBLE_EQ(c.cy, 161.5 / 3);
  // The skew is held to the image's own pixels: 1.16 full-resolution pixels are 0.58 binned ones.
  decimated.K[1] = 2.0;
  EXPECT_DOUBLE_EQ(cameraFromInfo(decimated).fx, 182.5);
}

TEST(Conversions, CameraFromInfoRefusesAWindowOutsideTheImage)
{
  auto outside = info();
  outside.roi.x_offset = 300;
  outside.roi.width = 300;
  outside.roi.height = 100;
  std::string m = message([&] { cameraFromInfo(outside); });
  EXPECT_NE(m.find("roi (x_offset 300, y_offset 0, width 300, height 100)"), std::string::npos) << m;
  EXPECT_NE(m.find("expected an roi inside the camera_info's 512x424"), std::string::npos) << m;
  auto flat = info();
  flat.roi.y_offset = 10;
  flat.roi.height = 100;
  m = message([&] { cameraFromInfo(flat); });
  EXPECT_NE(m.find("non-zero width and height, or all four 0"), std::string::npos) << m;
  auto coarse = info();
  coarse.binning_x = 600;
  m = message([&] { cameraFromInfo(coarse); });
  EXPECT_NE(m.find("binning 600x0: expected a binning no larger than the roi"), std::string::npos) << m;
}

// A rectified image's camera is P's (image_geometry's fx() is P(0,0)): camera_calibration's P, with which
// image_proc rectifies, differs from K.
TEST(Conversions, ARectifiedImagesCameraIsItsProjections)
{
  auto i = info();
  i.P = {350.0, 0, 250.0, 0, 0, 351.0, 210.0, 0, 0, 0, 1, 0};
  Camera c = rectifiedCameraFromInfo(i);
  EXPECT_DOUBLE_EQ(c.fx, 350.0);
  EXPECT_DOUBLE_EQ(c.fy, 351.0);
  EXPECT_DOUBLE_EQ(c.cx, 250.0);
  EXPECT_DOUBLE_EQ(c.cy, 210.0);
  EXPECT_DOUBLE_EQ(cameraFromInfo(i).fx, 365.0) << "the raw image's is K's";
  i.binning_x = i.binning_y = 2;
  c = rectifiedCameraFromInfo(i);
  EXPECT_EQ(c.width, 256);
  EXPECT_DOUBLE_EQ(c.fx, 175.0);
  EXPECT_DOUBLE_EQ(c.cy, 105.0);
  auto unset = info();  // P all 0 (not calibrated), or not a pinhole's: K's
  EXPECT_DOUBLE_EQ(rectifiedCameraFromInfo(unset).fx, 365.0);
  unset.P = {350.0, 0, 250.0, 0, 0, 351.0, 210.0, 0, 0, 0, 2, 0};
  EXPECT_DOUBLE_EQ(rectifiedCameraFromInfo(unset).fx, 365.0);
}

TEST(Conversions, DepthImagesAreViewedInPlace)
{
  for (auto [encoding, type, elem] : {std::tuple{"16UC1", CV_16UC1, 2}, {"mono16", CV_16UC1, 2}, {"32FC1", CV_32FC1, 4},
                                      {"8UC1", CV_8UC1, 1}, {"mono8", CV_8UC1, 1}})
  {
    sensor_msgs::Image img;
    img.encoding = encoding;
    img.width = 4;
    img.height = 3;
    img.step = 4 * elem + 8;  // padded rows
    img.data.assign(img.step * img.height, 1);
    cv::Mat buffer;
    const cv::Mat m = depthFromImage(img, buffer);
    EXPECT_EQ(m.type(), type);
    EXPECT_EQ(m.data, img.data.data()) << "not zero-copy for " << encoding;
    EXPECT_EQ(m.step[0], img.step);
  }
}

TEST(Conversions, OtherByteOrderIsSwapped)
{
  sensor_msgs::Image img;
  img.encoding = "16UC1";
  img.width = 2;
  img.height = 1;
  img.step = 4;
  img.is_bigendian = 1;
  img.data = {0x03, 0xE8, 0x07, 0xD0};  // 1000 and 2000, big-endian
  cv::Mat buffer;
  const cv::Mat m = depthFromImage(img, buffer);
  EXPECT_EQ(m.at<std::uint16_t>(0, 0), 1000);
  EXPECT_EQ(m.at<std::uint16_t>(0, 1), 2000);
}

TEST(Conversions, MalformedImagesAreRefusedWithTheValues)
{
  sensor_msgs::Image img;
  img.encoding = "rgb8";
  img.width = 4;
  img.height = 3;
  img.step = 12;
  img.data.resize(36);
  cv::Mat buffer;
  EXPECT_NE(message([&] { depthFromImage(img, buffer); }).find("'rgb8'"), std::string::npos);
  EXPECT_FALSE(isSupportedEncoding("rgb8"));
  img.encoding = "16UC1";
  img.step = 6;
  EXPECT_NE(message([&] { depthFromImage(img, buffer); }).find("step 6"), std::string::npos);
  img.step = 8;
  img.data.resize(20);
  EXPECT_NE(message([&] { depthFromImage(img, buffer); }).find("20 bytes"), std::string::npos);
  img.data.clear();
  EXPECT_NE(message([&] { depthFromImage(img, buffer); }).find("empty"), std::string::npos);
}

TEST(Conversions, PoseFromTheOpticalFramesTransform)
{
  for (double pitch : {0.0, 0.26, -0.3, 1.2})
    for (double roll : {0.0, 0.035, -0.1})
      for (double yaw : {0.0, 0.7})
      {
        double got_yaw;
        const SensorPose p = poseFromOpticalTransform(opticalTransform(1.1, pitch, roll, yaw), 0.05, got_yaw);
        EXPECT_NEAR(p.height, 1.15, 1e-12);
        EXPECT_NEAR(p.pitch, pitch, 1e-9);
        EXPECT_NEAR(p.roll, roll, 1e-9);
        EXPECT_NEAR(got_yaw, yaw, 1e-9);
      }
}

TEST(Conversions, PitchRollOfAnImu)
{
  tf2::Quaternion q;
  q.setRPY(0.02, -0.1, 1.0);
  geometry_msgs::Quaternion m;
  m.x = q.x();
  m.y = q.y();
  m.z = q.z();
  m.w = q.w();
  double pitch, roll;
  pitchRollFromQuaternion(m, pitch, roll);
  EXPECT_NEAR(pitch, -0.1, 1e-9);
  EXPECT_NEAR(roll, 0.02, 1e-9);
}

TEST(Conversions, ScanAndImagesOut)
{
  ScanData s;
  s.angle_min = -0.5f;
  s.angle_max = 0.5f;
  s.angle_increment = 0.25f;
  s.range_min = 0.1f;
  s.range_max = 10.0f;
  s.ranges = {1.0f, INFINITY, -INFINITY, NAN, 2.0f};
  s.intensities = {1.0f, 1.0f, 1.0f, 0.0f, 0.5f};
  std_msgs::Header h;
  h.stamp = ros::Time(12, 34);
  h.frame_id = "kinect2_depth_optical_frame";
  sensor_msgs::LaserScan out;
  toLaserScan(s, h, "kinect2_scan", 0.033, out);
  EXPECT_EQ(out.header.frame_id, "kinect2_scan");  // never the optical frame
  EXPECT_EQ(out.header.stamp, h.stamp);
  EXPECT_FLOAT_EQ(out.angle_min, -0.5f);
  ASSERT_EQ(out.ranges.size(), 5u);
  EXPECT_TRUE(std::isinf(out.ranges[1]) && out.ranges[1] > 0);
  EXPECT_TRUE(std::isinf(out.ranges[2]) && out.ranges[2] < 0);
  EXPECT_TRUE(std::isnan(out.ranges[3]));
  EXPECT_EQ(out.intensities, s.intensities);

  cv::Mat depth(3, 4, CV_16UC1, cv::Scalar(1234)), labels(3, 4, CV_8UC1, cv::Scalar(2));
  sensor_msgs::Image img;
  toImage(depth, h, "16UC1", img);
  EXPECT_EQ(img.step, 8u);
  EXPECT_EQ(img.data.size(), 24u);
  cv::Mat buffer;
  EXPECT_EQ(depthFromImage(img, buffer).at<std::uint16_t>(2, 3), 1234);
  toDebugImage(depth, labels, 12.0, h, img);
  EXPECT_EQ(img.encoding, "rgb8");
  EXPECT_EQ(img.data.size(), 36u);
  EXPECT_EQ(img.data[1], 191);  // floor green
}

TEST(Settings, RefusesInconsistentParametersNamingThem)
{
  KinectPipelineConfig c = KinectPipelineConfig::__getDefault__();
  EXPECT_NO_THROW(settingsFromConfig(c));
  c.ceiling_height = 0.5;
  EXPECT_NE(message([&] { settingsFromConfig(c); }).find("ceiling_height"), std::string::npos);
  c = KinectPipelineConfig::__getDefault__();
  c.range_min = 5.0;
  c.range_max = 2.0;
  EXPECT_NE(message([&] { settingsFromConfig(c); }).find("range_max"), std::string::npos);
  c = KinectPipelineConfig::__getDefault__();
  c.threshold_curve = "1:0.1";
  EXPECT_NE(message([&] { settingsFromConfig(c); }).find("threshold_curve"), std::string::npos);
  c = KinectPipelineConfig::__getDefault__();
  c.scan_frame = c.base_frame;
  EXPECT_NE(message([&] { settingsFromConfig(c); }).find("scan_frame"), std::string::npos);
}

TEST(Settings, DefaultsAreTheCoresDefaults)
{
  const NodeSettings s = settingsFromConfig(KinectPipelineConfig::__getDefault__());
  const Config d;
  for (const ConfigField& f : configFields())
    if (std::string(f.name) != "num_threads")
      EXPECT_EQ(f.text(s.core), f.text(d)) << f.name;
  EXPECT_EQ(s.core.num_threads, 1);  // the node's own default: no idle OpenMP thread spinning beside the driver
}

/** A valid value of @p f other than its default, as the .cfg's message would carry it. */
void setOther(const ConfigField& f, dynamic_reconfigure::Config& msg, std::string& want)
{
  const Config d;
  for (auto& p : msg.doubles)
    if (p.name == f.name)
    {
      p.value = f.number(d) == f.lo ? f.lo + 0.01 * (f.hi - f.lo) : 0.9 * f.number(d) + 0.1 * f.lo;
      want = std::to_string(p.value);
    }
  for (auto& p : msg.ints)
    if (p.name == f.name)
      want = std::to_string(p.value += 2);
  for (auto& p : msg.bools)
    if (p.name == f.name)
      want = (p.value = !p.value) ? "true" : "false";
  for (auto& p : msg.strs)
    if (p.name == f.name)
      want = p.value = f.kind == FieldKind::kCurve ? "1:0.05, 4:0.2" : f.choices.back();
}

TEST(Settings, EveryCoreFieldTravelsFromItsParameter)
{
  for (const ConfigField& f : configFields())
  {
    KinectPipelineConfig c = KinectPipelineConfig::__getDefault__();
    dynamic_reconfigure::Config msg;
    c.__toMessage__(msg);
    std::string want;
    setOther(f, msg, want);
    ASSERT_FALSE(want.empty()) << f.name << " is not a parameter of the .cfg";
    c.__fromMessage__(msg);
    const Config got = settingsFromConfig(c).core;
    if (f.kind == FieldKind::kReal)
      EXPECT_EQ(std::to_string(f.number(got)), want) << f.name;
    else
      EXPECT_EQ(f.text(got), want) << f.name;
    EXPECT_NE(f.text(got), f.text(Config{})) << f.name;
  }
}

TEST(Settings, EveryProblemIsNamedAtOnceAsAParameter)
{
  KinectPipelineConfig c = KinectPipelineConfig::__getDefault__();
  c.ceiling_height = 0.5;
  c.range_max = 4.0;  // fine: not named
  c.open_kernel_size = 4;
  c.pose_source = "laser";
  c.geometry = "curved";
  const std::string m = message([&] { settingsFromConfig(c); });
  for (const char* w : {"~ceiling_height = 0.5", "~open_kernel_size = 4", "~pose_source = 'laser'",
                        "~geometry = 'curved'"})
    EXPECT_NE(m.find(w), std::string::npos) << "'" << w << "' not in: " << m;
  EXPECT_EQ(m.find("range_max"), std::string::npos) << m;
  EXPECT_EQ(m.find("Config."), std::string::npos) << m;
}

TEST(Settings, ClosestParameterOfOurs)
{
  // Peers' names by meaning, the rest by spelling.
  EXPECT_EQ(closestParameter("output_frame_id"), "scan_frame");  // depthimage_to_laserscan
  EXPECT_EQ(closestParameter("target_frame"), "scan_frame");     // pointcloud_to_laserscan
  EXPECT_EQ(closestParameter("sensor_mount_height"), "sensor_height");  // laserscan_kinect
  EXPECT_EQ(closestParameter("range_maximum"), "range_max");
  EXPECT_EQ(closestParameter("sensor_pich"), "sensor_pitch");
  EXPECT_EQ(closestParameter("refine_flor"), "refine_floor");
}

// ------------------------------------------------------------------------------ camera_info pairing (issue 28)
namespace
{
sensor_msgs::CameraInfoConstPtr infoAt(double stamp, double fx = 365.0)
{
  auto i = boost::make_shared<sensor_msgs::CameraInfo>(info(fx));
  i->header.stamp = ros::Time(stamp);
  return i;
}

DepthInput imageAt(double stamp)
{
  DepthInput in;
  in.header.stamp = ros::Time(stamp);
  return in;
}

std::vector<double> stamps(const std::vector<DepthInput>& v)
{
  std::vector<double> s;
  for (const DepthInput& in : v)
    s.push_back(in.header.stamp.toSec());
  return s;
}
}  // namespace

TEST(Pairing, ImagesWithoutAnyCameraInfoWaitAndTheOldestIsGivenUp)
{
  CameraInfoPairing p(3);
  for (int k = 1; k <= 5; ++k)
  {
    const auto out = p.image(imageAt(k));
    EXPECT_TRUE(out.paired.empty());
    EXPECT_EQ(stamps(out.given_up), k <= 3 ? std::vector<double>{} : std::vector<double>{k - 3.0});
  }
  EXPECT_EQ(p.waiting(), 3u);
}

TEST(Pairing, SameStampFirstAndImagesNewerThanTheLatestWaitForTheirOwn)
{
  CameraInfoPairing p;
  EXPECT_TRUE(p.image(imageAt(1)).paired.empty());  // its camera_info comes after it
  auto out = p.info(infoAt(1));
  ASSERT_EQ(stamps(out.paired), std::vector<double>{1});
  EXPECT_EQ(out.paired[0].info->header.stamp, ros::Time(1));
  // Images have been finding their own: the next waits for its own rather than taking the latest.
  EXPECT_TRUE(p.image(imageAt(2)).paired.empty());
  out = p.info(infoAt(2));
  ASSERT_EQ(stamps(out.paired), std::vector<double>{2});
  EXPECT_EQ(out.paired[0].info->header.stamp, ros::Time(2));
  EXPECT_EQ(p.paired(InfoMatch::kExactStamp), 2u);
  EXPECT_EQ(p.paired(InfoMatch::kLatest), 0u);
}

TEST(Pairing, AnUnchangingCameraInfoOfOtherStampsIsPairedByRecency)
{
  CameraInfoPairing p;
  p.info(infoAt(0));  // rostopic pub -r 5: stamp 0, the same K every time
  for (int k = 1; k <= 4; ++k)
  {
    const auto out = p.image(imageAt(100 + k));
    ASSERT_EQ(stamps(out.paired), std::vector<double>{100.0 + k});
    EXPECT_EQ(out.paired[0].info->header.stamp, ros::Time(0));
    if (k == 2)
      p.info(infoAt(0));
  }
  EXPECT_EQ(p.paired(InfoMatch::kLatest), 4u);
}

TEST(Pairing, AChangedCameraIsNotUsedForOtherStamps)
{
  CameraInfoPairing p(2);
  p.info(infoAt(0));
  p.info(infoAt(0, 500.0));  // the camera changed: only its own stamp pairs now
  EXPECT_EQ(p.changes(), 1u);
  EXPECT_TRUE(p.image(imageAt(5)).paired.empty());
  auto out = p.info(infoAt(5, 500.0));
  ASSERT_EQ(stamps(out.paired), std::vector<double>{5});
  EXPECT_EQ(out.paired[0].info->K[0], 500.0);
  // The same camera as the one before: an older image whose own camera_info did not come takes the latest.
  EXPECT_EQ(stamps(p.image(imageAt(4)).paired), std::vector<double>{4});
  EXPECT_EQ(p.paired(InfoMatch::kLatest), 1u);
}

TEST(Pairing, AnImageOlderThanTheLatestCameraInfoTakesItWhenItsOwnDidNotCome)
{
  CameraInfoPairing p;
  p.image(imageAt(1));
  p.info(infoAt(1));  // exact stamps so far
  EXPECT_TRUE(p.image(imageAt(2)).paired.empty());
  const auto out = p.info(infoAt(3));  // 2's camera_info was lost; 3's came, the camera unchanged
  ASSERT_EQ(stamps(out.paired), std::vector<double>{2});
  EXPECT_EQ(out.paired[0].info->header.stamp, ros::Time(3));
}

TEST(CameraParameters, IntrinsicsAndUrlsAreReadOrRefusedNamingTheValue)
{
  std::string from;
  EXPECT_EQ(cameraInfoFromParameters("", "", from), nullptr);
  const auto i = cameraInfoFromParameters("211.5, 211.5 212 120.5 424 240", "", from);
  ASSERT_NE(i, nullptr);
  EXPECT_EQ(i->width, 424u);
  EXPECT_EQ(i->height, 240u);
  EXPECT_EQ(i->K[0], 211.5);
  EXPECT_EQ(i->K[5], 120.5);
  EXPECT_EQ(from, "~intrinsics = '211.5, 211.5 212 120.5 424 240'");
  std::string m = message([&] { cameraInfoFromParameters("211 211 212 120", "", from); });
  EXPECT_NE(m.find("~intrinsics = '211 211 212 120': 4 numbers; expected six"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("211 211 212 120 424 24x", "", from); });
  EXPECT_NE(m.find("'24x' is not a number"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("0 211 212 120 424 240", "", from); });
  EXPECT_NE(m.find("~intrinsics = '0 211 212 120 424 240': camera_info K[0] (fx) = 0"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("211 211 212 120 424 240", "file:///a.yaml", from); });
  EXPECT_NE(m.find("both set"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("", "/tmp/a.yaml", from); });
  EXPECT_NE(m.find("~camera_info_url = '/tmp/a.yaml': a path without its scheme (write file:///tmp/a.yaml)"),
            std::string::npos)
      << m;
  m = message([&] { cameraInfoFromParameters("", "http://cam/calib.yaml", from); });
  EXPECT_NE(m.find("expected file:///absolute/path.yaml or package://"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("", "file:///nonexistent/kp_calib.yaml", from); });
  EXPECT_NE(m.find("cannot read '/nonexistent/kp_calib.yaml'"), std::string::npos) << m;
  m = message([&] { cameraInfoFromParameters("", "package://no_such_package_kp/c.yaml", from); });
  EXPECT_NE(m.find("no ROS package 'no_such_package_kp'"), std::string::npos) << m;
}

TEST(Conversions, PngCompressedSixteenBitDepthIsDecodedAndOtherFormatsNamed)
{
  cv::Mat depth(4, 6, CV_16UC1);
  for (int k = 0; k < 24; ++k)
    depth.at<std::uint16_t>(k / 6, k % 6) = static_cast<std::uint16_t>(500 + 97 * k);
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", depth, png));
  sensor_msgs::CompressedImage msg;
  msg.format = "16UC1; png compressed ";
  msg.data = png;
  const cv::Mat got = depthFromCompressed(msg, cv::Size(6, 4));
  EXPECT_EQ(cv::norm(got, depth, cv::NORM_INF), 0.0);
  msg.format = "mono16; png compressed";
  EXPECT_EQ(cv::norm(depthFromCompressed(msg, cv::Size()), depth, cv::NORM_INF), 0.0);
  msg.format = "16UC1; jpeg compressed ";
  std::string m = message([&] { depthFromCompressed(msg, cv::Size()); });
  EXPECT_NE(m.find("'16UC1; jpeg compressed ': not a depth image this package reads; it reads '16UC1; png compressed'"),
            std::string::npos)
      << m;
  msg.format = "bgr8; jpeg compressed bgr8";
  EXPECT_NE(message([&] { depthFromCompressed(msg, cv::Size()); }).find("not a depth image"), std::string::npos);
}
