#include "kinect_pipeline/ros/conversions.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include <sensor_msgs/image_encodings.h>

#include "kinect_pipeline/io/compressed_depth.h"
#include "kinect_pipeline/io/depth_image.h"
#include "kinect_pipeline/io/visualize.h"
#include "kinect_pipeline/model/pose.h"

namespace kinect_pipeline
{
namespace conversions
{
namespace
{
namespace enc = sensor_msgs::image_encodings;
}  // namespace

// The checks and their messages live in the core (depth_image.h), shared with the Python tools.
namespace
{
Camera cameraOf(const sensor_msgs::CameraInfo& info, const std::array<double, 9>& K)
{
  const ImageWindow window{info.binning_x,    info.binning_y,  info.roi.x_offset,
                           info.roi.y_offset, info.roi.width, info.roi.height};
  return cameraFromIntrinsics(info.width, info.height, K, info.header.frame_id, window);
}
}  // namespace

Camera cameraFromInfo(const sensor_msgs::CameraInfo& info)
{
  std::array<double, 9> K;
  std::copy(info.K.begin(), info.K.end(), K.begin());
  return cameraOf(info, K);
}

Camera rectifiedCameraFromInfo(const sensor_msgs::CameraInfo& info)
{
  std::array<double, 12> P;
  std::copy(info.P.begin(), info.P.end(), P.begin());
  const std::optional<std::array<double, 9>> K = rectifiedIntrinsics(P);
  return K ? cameraOf(info, *K) : cameraFromInfo(info);
}

cv::Mat depthFromCompressed(const sensor_msgs::CompressedImage& image, cv::Size expected)
{
  return decodeDepthImage(image.format, image.data.data(), image.data.size(), expected);
}

bool isSupportedEncoding(const std::string& e)
{
  return isSupportedDepthEncoding(e);
}

cv::Mat depthFromImage(const sensor_msgs::Image& image, cv::Mat& buffer)
{
  return depthFromBuffer({image.encoding, image.width, image.height, image.step, image.is_bigendian != 0,
                          image.data.data(), image.data.size()},
                         buffer);
}

RigidTransform fromMsg(const geometry_msgs::Transform& t)
{
  RigidTransform r;
  r.q = {t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w};
  r.t = {t.translation.x, t.translation.y, t.translation.z};
  return r;
}

SensorPose poseFromOpticalTransform(const geometry_msgs::Transform& t, double base_frame_height, double& yaw)
{
  return kinect_pipeline::poseFromOpticalTransform(fromMsg(t), base_frame_height, yaw);
}

void pitchRollFromQuaternion(const geometry_msgs::Quaternion& q, double& pitch, double& roll)
{
  const auto rpy = rollPitchYaw({q.x, q.y, q.z, q.w});
  roll = rpy[0];
  pitch = rpy[1];
}

void toLaserScan(const ScanData& scan, const std_msgs::Header& header, const std::string& frame_id,
                 double scan_time, sensor_msgs::LaserScan& out)
{
  out.header.stamp = header.stamp;
  out.header.seq = header.seq;
  out.header.frame_id = frame_id;
  out.angle_min = scan.angle_min;
  out.angle_max = scan.angle_max;
  out.angle_increment = scan.angle_increment;
  out.time_increment = 0.0f;  // every beam comes from the same exposure
  out.scan_time = static_cast<float>(scan_time);
  out.range_min = scan.range_min;
  out.range_max = scan.range_max;
  out.ranges = scan.ranges;
  out.intensities = scan.intensities;
}

void toImage(const cv::Mat& depth, const std_msgs::Header& header, const std::string& encoding, sensor_msgs::Image& out)
{
  out.header = header;
  out.height = depth.rows;
  out.width = depth.cols;
  out.encoding = encoding;
  out.is_bigendian = hostIsBigEndian();
  out.step = static_cast<std::uint32_t>(depth.cols * depth.elemSize());
  out.data.resize(static_cast<std::size_t>(out.step) * depth.rows);
  for (int r = 0; r < depth.rows; ++r)
    std::memcpy(out.data.data() + static_cast<std::size_t>(r) * out.step, depth.ptr(r), out.step);
}

void toDebugImage(const cv::Mat& depth, const cv::Mat& labels, double max_depth, const std_msgs::Header& header,
                  sensor_msgs::Image& out)
{
  cv::Mat rgb;
  colourLabels(depth, labels, max_depth, rgb);
  toImage(rgb, header, enc::RGB8, out);
}

}  // namespace conversions
}  // namespace kinect_pipeline
