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

namespace
{
[[noreturn]] void badWindow(const ImageWindow& w, const std::string& expected)
{
  std::ostringstream s;
  s << "camera_info roi (x_offset " << w.x_offset << ", y_offset " << w.y_offset << ", width " << w.width
    << ", height " << w.height << "), binning " << w.binning_x << "x" << w.binning_y << ": expected " << expected;
  throw std::invalid_argument(s.str());
}

void checkK(std::uint32_t width, std::uint32_t height, const std::array<double, 9>& K, const std::string& frame_id)
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
}

// The window with its binning at least 1 and its ROI the whole image where all four are 0 (REP 104), checked.
ImageWindow resolved(std::uint32_t width, std::uint32_t height, const ImageWindow& w)
{
  ImageWindow r = w;
  r.binning_x = std::max(w.binning_x, 1u);
  r.binning_y = std::max(w.binning_y, 1u);
  if (w.x_offset == 0 && w.y_offset == 0 && w.width == 0 && w.height == 0)
  {
    r.width = width;
    r.height = height;
  }
  else if (w.width == 0 || w.height == 0)
    badWindow(w, "an roi of non-zero width and height, or all four 0 (the whole image)");
  if (std::uint64_t{r.x_offset} + r.width > width || std::uint64_t{r.y_offset} + r.height > height)
    badWindow(w, "an roi inside the camera_info's " + std::to_string(width) + "x" + std::to_string(height));
  if (r.width / r.binning_x == 0 || r.height / r.binning_y == 0)
    badWindow(w, "a binning no larger than the roi (at least one pixel)");
  return r;
}
}  // namespace

Camera cameraFromIntrinsics(std::uint32_t width, std::uint32_t height, const std::array<double, 9>& K,
                            const std::string& frame_id, const ImageWindow& window)
{
  checkK(width, height, K, frame_id);
  // The image's pixel j is the full image's column x_offset + b j (image_geometry's reading of REP 104).
  const ImageWindow w = resolved(width, height, window);
  const double bx = w.binning_x, by = w.binning_y;
  // Camera's constructor checks the rest (fy > 0, finite values) and names the field.
  const Camera cam(static_cast<int>(w.width / w.binning_x), static_cast<int>(w.height / w.binning_y), K[0] / bx,
                   K[4] / by, (K[2] - w.x_offset) / bx, (K[5] - w.y_offset) / by);
  // The core's camera has no skew (K[1]): taken without it, a pixel's column is off by skew (v - cy) / fy, which
  // must stay under a pixel (a calibration's skew of a few hundredths moves none).
  const double skew = K[1] / bx;
  const double rows = std::max(std::fabs(cam.cy), std::fabs(cam.height - 1 - cam.cy));  // pixel centres
  if (!(std::fabs(skew) * rows / cam.fy < 1.0))
  {
    std::ostringstream s;
    s << "camera_info K[1] (skew) = " << K[1] << ": without it (this package's camera has none) the rows farthest "
      << "from cy = " << cam.cy << " would be " << std::fabs(skew) * rows / cam.fy << " px off; expected |skew| < "
      << cam.fy / rows * bx << " (under a pixel)";
    throw std::invalid_argument(s.str());
  }
  return cam;
}

std::optional<std::array<double, 9>> rectifiedIntrinsics(const std::array<double, 12>& P)
{
  const bool finite = std::all_of(P.begin(), P.end(), [](double v) { return std::isfinite(v); });
  if (!finite || !(P[0] > 0.0) || !(P[5] > 0.0) || P[4] != 0.0 || P[8] != 0.0 || P[9] != 0.0 || P[10] != 1.0)
    return std::nullopt;
  return std::array<double, 9>{P[0], P[1], P[2], 0.0, P[5], P[6], 0.0, 0.0, 1.0};
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
