#include "kinect_pipeline/io/depth_image.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

namespace kinect_pipeline
{

bool hostIsBigEndian()
{
  const std::uint16_t one = 1;
  std::uint8_t first;
  std::memcpy(&first, &one, 1);
  return first == 0;
}

bool isSupportedDepthEncoding(const std::string& e)
{
  return e == "8UC1" || e == "mono8" || e == "16UC1" || e == "mono16" || e == "32FC1";
}

Camera cameraFromIntrinsics(std::uint32_t width, std::uint32_t height, const std::array<double, 9>& K,
                            const std::string& frame_id)
{
  if (K[0] == 0.0)
  {
    std::ostringstream s;
    s << "camera_info K[0] (fx) = 0: the camera is uncalibrated (frame '" << frame_id << "'); expected fx > 0";
    throw std::invalid_argument(s.str());
  }
  if (width == 0 || height == 0)
  {
    std::ostringstream s;
    s << "camera_info size " << width << "x" << height << ": expected a non-zero width and height";
    throw std::invalid_argument(s.str());
  }
  if (K[3] != 0.0 || K[6] != 0.0 || K[7] != 0.0 || K[8] != 1.0)
  {
    std::ostringstream s;
    s << "camera_info K = [" << K[0];
    for (std::size_t i = 1; i < K.size(); ++i)
      s << (i % 3 ? ", " : "; ") << K[i];
    s << "]: expected a pinhole camera's [fx s cx; 0 fy cy; 0 0 1] (K[3], K[6], K[7] = 0 and K[8] = 1)";
    throw std::invalid_argument(s.str());
  }
  // Camera's constructor checks the rest (fy > 0, finite values) and names the field.
  const Camera cam(static_cast<int>(width), static_cast<int>(height), K[0], K[4], K[2], K[5]);
  // The core's camera has no skew (K[1]): taken without it, a pixel's column is off by skew (v - cy) / fy, which
  // must stay under a pixel (a calibration's skew of a few hundredths moves none).
  const double rows = std::max(std::fabs(cam.cy), std::fabs(cam.height - 1 - cam.cy));  // pixel centres
  if (!(std::fabs(K[1]) * rows / cam.fy < 1.0))
  {
    std::ostringstream s;
    s << "camera_info K[1] (skew) = " << K[1] << ": without it (this package's camera has none) the rows farthest "
      << "from cy = " << cam.cy << " would be " << std::fabs(K[1]) * rows / cam.fy << " px off; expected |skew| < "
      << cam.fy / rows << " (under a pixel)";
    throw std::invalid_argument(s.str());
  }
  return cam;
}

cv::Mat depthFromBuffer(const ImageBuffer& image, cv::Mat& buffer)
{
  const std::string& e = image.encoding;
  int type;
  std::size_t elem;
  if (e == "8UC1" || e == "mono8")
  {
    type = CV_8UC1;
    elem = 1;
  }
  else if (e == "16UC1" || e == "mono16")
  {
    type = CV_16UC1;
    elem = 2;
  }
  else if (e == "32FC1")
  {
    type = CV_32FC1;
    elem = 4;
  }
  else
  {
    throw std::invalid_argument("depth image encoding '" + e +
                                "': expected 8UC1 or mono8 (normalised), 16UC1 or mono16 (mm), 32FC1 (m)");
  }
  if (image.width == 0 || image.height == 0 || image.size == 0)
  {
    std::ostringstream s;
    s << "depth image is empty (" << image.width << "x" << image.height << ", " << image.size << " bytes)";
    throw std::invalid_argument(s.str());
  }
  if (image.step < image.width * elem)
  {
    std::ostringstream s;
    s << "depth image step " << image.step << " bytes is less than width " << image.width << " x " << elem
      << " bytes per pixel";
    throw std::invalid_argument(s.str());
  }
  if (image.size < static_cast<std::size_t>(image.step) * image.height)
  {
    std::ostringstream s;
    s << "depth image has " << image.size << " bytes, expected step " << image.step << " x height " << image.height
      << " = " << static_cast<std::size_t>(image.step) * image.height;
    throw std::invalid_argument(s.str());
  }
  cv::Mat view(static_cast<int>(image.height), static_cast<int>(image.width), type,
               const_cast<std::uint8_t*>(image.data), image.step);
  if (elem == 1 || image.is_bigendian == hostIsBigEndian())
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

}  // namespace kinect_pipeline
