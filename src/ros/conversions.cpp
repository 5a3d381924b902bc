#include "kinect_pipeline/ros/conversions.h"

#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include <sensor_msgs/image_encodings.h>

#include "kinect_pipeline/pose.h"
#include "kinect_pipeline/visualize.h"

namespace kinect_pipeline
{
namespace conversions
{
namespace
{
namespace enc = sensor_msgs::image_encodings;

bool hostIsBigEndian()
{
  const std::uint16_t one = 1;
  std::uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 0;
}
}  // namespace

Camera cameraFromInfo(const sensor_msgs::CameraInfo& info)
{
  const auto& K = info.K;
  if (K[0] == 0.0)
  {
    std::ostringstream s;
    s << "camera_info K[0] (fx) = 0: the camera is uncalibrated (frame '" << info.header.frame_id
      << "'); expected fx > 0";
    throw std::invalid_argument(s.str());
  }
  if (info.width == 0 || info.height == 0)
  {
    std::ostringstream s;
    s << "camera_info size " << info.width << "x" << info.height << ": expected a non-zero width and height";
    throw std::invalid_argument(s.str());
  }
  // Camera's constructor checks the rest (fy > 0, finite values) and names the field.
  return Camera(static_cast<int>(info.width), static_cast<int>(info.height), K[0], K[4], K[2], K[5]);
}

bool isSupportedEncoding(const std::string& e)
{
  return e == enc::TYPE_8UC1 || e == enc::MONO8 || e == enc::TYPE_16UC1 || e == enc::MONO16 || e == enc::TYPE_32FC1;
}

cv::Mat depthFromImage(const sensor_msgs::Image& image, cv::Mat& buffer)
{
  const std::string& e = image.encoding;
  int type;
  std::size_t elem;
  if (e == enc::TYPE_8UC1 || e == enc::MONO8)
  {
    type = CV_8UC1;
    elem = 1;
  }
  else if (e == enc::TYPE_16UC1 || e == enc::MONO16)
  {
    type = CV_16UC1;
    elem = 2;
  }
  else if (e == enc::TYPE_32FC1)
  {
    type = CV_32FC1;
    elem = 4;
  }
  else
  {
    throw std::invalid_argument("depth image encoding '" + e +
                                "': expected 8UC1 or mono8 (normalised), 16UC1 or mono16 (mm), 32FC1 (m)");
  }
  if (image.width == 0 || image.height == 0 || image.data.empty())
  {
    std::ostringstream s;
    s << "depth image is empty (" << image.width << "x" << image.height << ", " << image.data.size() << " bytes)";
    throw std::invalid_argument(s.str());
  }
  if (image.step < image.width * elem)
  {
    std::ostringstream s;
    s << "depth image step " << image.step << " bytes is less than width " << image.width << " x " << elem
      << " bytes per pixel";
    throw std::invalid_argument(s.str());
  }
  if (image.data.size() < static_cast<std::size_t>(image.step) * image.height)
  {
    std::ostringstream s;
    s << "depth image has " << image.data.size() << " bytes, expected step " << image.step << " x height "
      << image.height << " = " << static_cast<std::size_t>(image.step) * image.height;
    throw std::invalid_argument(s.str());
  }
  cv::Mat view(static_cast<int>(image.height), static_cast<int>(image.width), type,
               const_cast<std::uint8_t*>(image.data.data()), image.step);
  if (elem == 1 || static_cast<bool>(image.is_bigendian) == hostIsBigEndian())
    return view;
  // Other byte order: swap into a buffer (kept by the caller, so no allocation once warm).
  buffer.create(view.size(), type);
  for (int r = 0; r < view.rows; ++r)
  {
    const std::uint8_t* in = view.ptr<std::uint8_t>(r);
    std::uint8_t* out = buffer.ptr<std::uint8_t>(r);
    for (int u = 0; u < view.cols; ++u)
      for (std::size_t b = 0; b < elem; ++b)
        out[u * elem + b] = in[u * elem + elem - 1 - b];
  }
  return buffer;
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
