#include "kinect_pipeline/io/visualize.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace kinect_pipeline
{

void colourLabels(const cv::Mat& depth, const cv::Mat& labels, double max_depth, cv::Mat& rgb)
{
  const int type = depth.type();
  if (type != CV_8UC1 && type != CV_16UC1 && type != CV_32FC1)
    throw std::invalid_argument("colourLabels: depth type " + cv::typeToString(type) + ": expected 8UC1, 16UC1 or 32FC1");
  if (labels.type() != CV_8UC1 || labels.size() != depth.size())
    throw std::invalid_argument("colourLabels: labels must be 8UC1 of the depth's size");
  if (!(max_depth > 0.0))
    throw std::invalid_argument("colourLabels: max_depth must be > 0 m");
  rgb.create(depth.size(), CV_8UC3);
  const double scale = type == CV_8UC1 ? max_depth / 255.0 : (type == CV_16UC1 ? 0.001 : 1.0);
  for (int r = 0; r < depth.rows; ++r)
  {
    const std::uint8_t* lab = labels.ptr<std::uint8_t>(r);
    std::uint8_t* out = rgb.ptr<std::uint8_t>(r);
    for (int u = 0; u < depth.cols; ++u)
    {
      const int l = lab[u] < kLabelColours.size() ? lab[u] : 1;
      if (l != 0)
      {
        std::copy(kLabelColours[l].begin(), kLabelColours[l].end(), out + 3 * u);
        continue;
      }
      double z = type == CV_8UC1 ? depth.at<std::uint8_t>(r, u) * scale
                 : type == CV_16UC1 ? depth.at<std::uint16_t>(r, u) * scale
                                    : depth.at<float>(r, u);
      z = std::isfinite(z) ? std::min(std::max(z, 0.0), max_depth) : max_depth;
      const auto g = static_cast<std::uint8_t>(std::lround(255.0 * (1.0 - z / max_depth)));
      out[3 * u] = out[3 * u + 1] = out[3 * u + 2] = g;
    }
  }
}

}  // namespace kinect_pipeline
