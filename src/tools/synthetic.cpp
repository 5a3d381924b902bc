// Rendered scenes with exact ground truth for the tests and the quality tables (docs/quality.md).
#include "kinect_pipeline/tools/synthetic.h"

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "kinect_pipeline/model/pose.h"

namespace kinect_pipeline
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Vec3
{
  double x, y, z;
};

// Slab test: the ray o + t d meets the box for t in [t_in, t_out].
bool slab(const Vec3& o, const Vec3& d, const Box& b, double& t_in, double& t_out)
{
  t_in = -kInf;
  t_out = kInf;
  const double lo[3] = {b.x0, b.y0, b.z0}, hi[3] = {b.x1, b.y1, b.z1};
  const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
  for (int i = 0; i < 3; ++i)
  {
    if (dd[i] == 0.0)
    {
      if (oo[i] < lo[i] || oo[i] > hi[i])
        return false;
      continue;
    }
    double a = (lo[i] - oo[i]) / dd[i], c = (hi[i] - oo[i]) / dd[i];
    if (a > c)
      std::swap(a, c);
    t_in = std::max(t_in, a);
    t_out = std::min(t_out, c);
  }
  return t_in <= t_out && t_out > 0.0;
}
}  // namespace

void renderScene(const Camera& camera, double height, double pitch, double roll, const Scene& scene, Rendering& out)
{
  camera.validate();
  out.depth.create(camera.height, camera.width, CV_32F);
  out.height.create(camera.height, camera.width, CV_32F);
  out.range.create(camera.height, camera.width, CV_32F);
  out.angle.create(camera.height, camera.width, CV_32F);
  out.object.create(camera.height, camera.width, CV_16S);
  const std::array<double, 9> m = levelFromOptical(pitch, roll);
  const Vec3 o{0.0, 0.0, height};
  const float nanf = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < camera.height; ++v)
  {
    for (int u = 0; u < camera.width; ++u)
    {
      const double xn = (u - camera.cx) / camera.fx, yn = (v - camera.cy) / camera.fy;
      // The ray (xn, yn, 1) in the level frame; depth = t.
      const Vec3 d{m[2] + m[0] * xn + m[1] * yn, m[5] + m[3] * xn + m[4] * yn, m[8] + m[6] * xn + m[7] * yn};
      double best = kInf;
      int id = -1;
      if (scene.floor && d.z < 0.0)
      {
        const double t = -height / d.z;
        const double x = o.x + t * d.x, y = o.y + t * d.y;
        bool in_hole = false;
        for (const Box& hole : scene.holes)
        {
          if (x >= hole.x0 && x <= hole.x1 && y >= hole.y0 && y <= hole.y1)
          {
            // Inside the hole the ray goes on until it leaves the hole's volume (a wall or the bottom).
            const Box vol{hole.x0, hole.x1, hole.y0, hole.y1, -scene.hole_depth, 0.0};
            double t_in, t_out;
            if (slab(o, d, vol, t_in, t_out))
            {
              best = t_out;
              id = 2;
            }
            in_hole = true;
            break;
          }
        }
        if (!in_hole)
        {
          best = t;
          id = 0;
        }
      }
      if (scene.ceiling > 0.0 && d.z > 0.0)
      {
        const double t = (scene.ceiling - height) / d.z;
        if (t > 0.0 && t < best)
        {
          best = t;
          id = 1;
        }
      }
      for (std::size_t i = 0; i < scene.boxes.size(); ++i)
      {
        double t_in, t_out;
        if (slab(o, d, scene.boxes[i], t_in, t_out) && t_in > 0.0 && t_in < best)
        {
          best = t_in;
          id = 10 + static_cast<int>(i);
        }
      }
      out.object.at<short>(v, u) = static_cast<short>(id);
      if (id < 0)
      {
        out.depth.at<float>(v, u) = std::numeric_limits<float>::infinity();
        out.height.at<float>(v, u) = nanf;
        out.range.at<float>(v, u) = nanf;
        out.angle.at<float>(v, u) = nanf;
        continue;
      }
      out.depth.at<float>(v, u) = static_cast<float>(best);
      out.height.at<float>(v, u) = static_cast<float>(o.z + best * d.z);
      out.range.at<float>(v, u) = static_cast<float>(best * std::hypot(d.x, d.y));
      out.angle.at<float>(v, u) = static_cast<float>(std::atan2(d.y, d.x));
    }
  }
}

std::vector<float> renderLidar(const Scene& scene, double z, double angle_min, double increment, int beams,
                               double range_max)
{
  if (beams < 1)
    throw std::invalid_argument("renderLidar: beams = " + std::to_string(beams) + ": expected >= 1");
  std::vector<float> out(beams, std::numeric_limits<float>::infinity());
  const Vec3 o{0.0, 0.0, z};
  for (int i = 0; i < beams; ++i)
  {
    const double a = angle_min + i * increment;
    const Vec3 d{std::cos(a), std::sin(a), 0.0};
    double best = range_max;
    for (const Box& b : scene.boxes)
    {
      double t_in, t_out;
      if (slab(o, d, b, t_in, t_out) && t_in > 0.0 && t_in < best)
        best = t_in;
    }
    if (best < range_max)
      out[i] = static_cast<float>(best);
  }
  return out;
}

std::vector<float> bandScan(const cv::Mat& depth_m, const Camera& camera, int band_rows)
{
  if (depth_m.type() != CV_32FC1 || depth_m.cols != camera.width || depth_m.rows != camera.height)
    throw std::invalid_argument("bandScan: expected a 32FC1 image of the camera's size");
  std::vector<float> out(camera.width, std::numeric_limits<float>::infinity());
  const int centre = static_cast<int>(std::lround(camera.cy));
  const int r0 = std::max(0, centre - band_rows / 2), r1 = std::min(camera.height - 1, centre + (band_rows - 1) / 2);
  for (int u = 0; u < camera.width; ++u)
  {
    float best = std::numeric_limits<float>::infinity();
    for (int r = r0; r <= r1; ++r)
    {
      const float z = depth_m.at<float>(r, u);
      if (z > 0.0f && z < best)
        best = z;
    }
    const double xn = (u - camera.cx) / camera.fx;
    out[camera.width - 1 - u] = static_cast<float>(best * std::sqrt(1.0 + xn * xn));
  }
  return out;
}

void addKinectNoise(cv::Mat& depth, std::uint64_t seed, double sigma0, double k, double dropout)
{
  if (depth.type() != CV_32FC1)
    throw std::invalid_argument("addKinectNoise: image type " + cv::typeToString(depth.type()) + ": expected 32FC1");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int v = 0; v < depth.rows; ++v)
  {
    float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u)
    {
      const double n = normal(rng), drop = uniform(rng);
      if (!std::isfinite(row[u]))
        continue;
      const double z = row[u];
      const double sigma = kinectSigma(z, sigma0, k);
      row[u] = drop < dropout ? std::numeric_limits<float>::infinity() : static_cast<float>(z + sigma * n);
    }
  }
}

void addTofArtefacts(cv::Mat& depth, std::uint64_t seed, double max_range, double flying, double edge_jump)
{
  if (depth.type() != CV_32FC1)
    throw std::invalid_argument("addTofArtefacts: image type " + cv::typeToString(depth.type()) + ": expected 32FC1");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const cv::Mat src = depth.clone();
  const float inf = std::numeric_limits<float>::infinity();
  for (int v = 0; v < depth.rows; ++v)
  {
    for (int u = 0; u < depth.cols; ++u)
    {
      const double p = uniform(rng), f = uniform(rng);
      const float z = src.at<float>(v, u);
      if (!std::isfinite(z))
        continue;
      // The farthest 4-neighbour across a jump: the pixel then mixes light from both surfaces.
      float far = z;
      const int du[4] = {1, -1, 0, 0}, dv[4] = {0, 0, 1, -1};
      for (int k = 0; k < 4; ++k)
      {
        const int uu = u + du[k], vv = v + dv[k];
        if (uu < 0 || vv < 0 || uu >= depth.cols || vv >= depth.rows)
          continue;
        const float n = src.at<float>(vv, uu);
        if (std::isfinite(n) && n - z > edge_jump && n > far)
          far = n;
      }
      float out = z;
      if (far > z && p < flying)
        out = static_cast<float>(z + f * (far - z));
      depth.at<float>(v, u) = out > max_range ? inf : out;
    }
  }
}

cv::Mat encodeDepth(const cv::Mat& metres, int type, double max_depth)
{
  if (metres.type() != CV_32FC1)
    throw std::invalid_argument("encodeDepth: image type " + cv::typeToString(metres.type()) + ": expected 32FC1");
  if (type == CV_32FC1)
    return metres.clone();
  cv::Mat out(metres.size(), type);
  for (int v = 0; v < metres.rows; ++v)
  {
    const float* in = metres.ptr<float>(v);
    for (int u = 0; u < metres.cols; ++u)
    {
      const float z = in[u];
      const bool known = std::isfinite(z) && z > 0.0f;
      if (type == CV_8UC1)
        out.at<std::uint8_t>(v, u) = known ? static_cast<std::uint8_t>(std::min(255.0, std::round(z / max_depth * 255.0))) : 0;
      else if (type == CV_16UC1)
        out.at<std::uint16_t>(v, u) = known && z < 65.5f ? static_cast<std::uint16_t>(std::lround(z * 1000.0)) : 0;
      else
        throw std::invalid_argument("encodeDepth: type " + cv::typeToString(type) + ": expected 8UC1, 16UC1 or 32FC1");
    }
  }
  return out;
}

}  // namespace kinect_pipeline
