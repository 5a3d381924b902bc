// The camera from parameters (~intrinsics, ~camera_info_url), for cameras and bags without a camera_info topic.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <boost/make_shared.hpp>
#include <camera_calibration_parsers/parse.h>
#include <ros/package.h>

#include "kinect_pipeline/ros/conversions.h"
#include "kinect_pipeline/ros/parameters.h"

namespace kinect_pipeline
{
namespace
{
const char* const kUrlExpected =
    "expected file:///absolute/path.yaml or package://PACKAGE/path.yaml: a camera_info YAML as camera_calibration "
    "writes it (image_width, image_height, camera_matrix, ...)";

[[noreturn]] void fail(const std::string& message) { throw std::invalid_argument(message); }

sensor_msgs::CameraInfo fromIntrinsics(const std::string& text)
{
  const std::string said = "~intrinsics = '" + text + "': ";
  std::string spaced = text;
  std::replace(spaced.begin(), spaced.end(), ',', ' ');
  std::istringstream in(spaced);
  std::vector<double> v;
  std::string word;
  while (in >> word)
  {
    try
    {
      std::size_t used = 0;
      v.push_back(std::stod(word, &used));
      if (used != word.size())
        throw std::invalid_argument(word);
    }
    catch (const std::exception&)
    {
      fail(said + "'" + word + "' is not a number; expected six numbers 'fx fy cx cy width height' (pixels)");
    }
  }
  if (v.size() != 6)
    fail(said + std::to_string(v.size()) + " numbers; expected six: 'fx fy cx cy width height' (pixels)");
  for (int i : {4, 5})
    if (!(v[i] >= 1 && v[i] <= 100000) || v[i] != std::floor(v[i]))
    {
      std::ostringstream m;
      m << said << (i == 4 ? "width " : "height ") << v[i] << ": expected a whole number of pixels, 1 .. 100000";
      fail(m.str());
    }
  sensor_msgs::CameraInfo info;
  info.width = static_cast<std::uint32_t>(v[4]);
  info.height = static_cast<std::uint32_t>(v[5]);
  info.K = {v[0], 0.0, v[2], 0.0, v[1], v[3], 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {v[0], 0.0, v[2], 0.0, 0.0, v[1], v[3], 0.0, 0.0, 0.0, 1.0, 0.0};
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  return info;
}

/** The file a camera_info URL names. */
std::string pathOfUrl(const std::string& url)
{
  const std::string said = "~camera_info_url = '" + url + "': ";
  const std::string file = "file://", package = "package://";
  if (url.compare(0, file.size(), file) == 0)
  {
    const std::string path = url.substr(file.size());
    if (path.empty() || path[0] != '/')
      fail(said + "'" + path + "' is not an absolute path; " + kUrlExpected);
    return path;
  }
  if (url.compare(0, package.size(), package) == 0)
  {
    const std::string rest = url.substr(package.size());
    const std::size_t slash = rest.find('/');
    const std::string name = rest.substr(0, slash);
    if (name.empty() || slash == std::string::npos)
      fail(said + std::string("no package and path after package://; ") + kUrlExpected);
    const std::string root = ros::package::getPath(name);
    if (root.empty())
      fail(said + "no ROS package '" + name + "' is found (ROS_PACKAGE_PATH); " + kUrlExpected);
    return root + rest.substr(slash);
  }
  fail(said + (url.front() == '/' ? "a path without its scheme (write file://" + url + "); " : std::string()) +
       kUrlExpected);
}

sensor_msgs::CameraInfo fromUrl(const std::string& url)
{
  const std::string path = pathOfUrl(url);
  const std::string said = "~camera_info_url = '" + url + "': ";
  if (!std::ifstream(path).good())
    fail(said + "cannot read '" + path + "' (no such file, or not readable)");
  sensor_msgs::CameraInfo info;
  std::string camera_name;
  // The parser that camera drivers use (camera_info_manager): YAML (.yaml, .yml) or INI (.ini) by the extension.
  if (!camera_calibration_parsers::readCalibration(path, camera_name, info))
    fail(said + "'" + path + "' is not a camera_info file camera_calibration_parsers can read (the parser's error is " +
         "logged above); " + kUrlExpected);
  return info;
}
}  // namespace

sensor_msgs::CameraInfoConstPtr cameraInfoFromParameters(const std::string& intrinsics, const std::string& url,
                                                         std::string& from)
{
  if (intrinsics.empty() && url.empty())
    return nullptr;
  if (!intrinsics.empty() && !url.empty())
    fail("~intrinsics = '" + intrinsics + "' and ~camera_info_url = '" + url +
         "' are both set: expected one of them (or neither: the camera_info topic)");
  from = intrinsics.empty() ? "~camera_info_url = '" + url + "'" : "~intrinsics = '" + intrinsics + "'";
  auto info = boost::make_shared<sensor_msgs::CameraInfo>(intrinsics.empty() ? fromUrl(url) : fromIntrinsics(intrinsics));
  try
  {
    conversions::cameraFromInfo(*info);  // the core's checks of a camera (fx > 0, a size, finite values)
  }
  catch (const std::invalid_argument& e)
  {
    fail(from + ": " + e.what());
  }
  return info;
}

}  // namespace kinect_pipeline
