// Rendered scenes with exact ground truth for the tests and the quality tables (docs/quality.md).
#include "kinect_pipeline/tools/synthetic.h"

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <sstream>
#include <string>

#include "kinect_pipeline/model/config_table.h"
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
/** @throw std::invalid_argument "WHERE: NAME = V: expected EXPECTED" unless @p ok. */
void require(bool ok, const char* where, const std::string& name, double v, const char* expected)
{
  if (ok)
    return;
  std::ostringstream m;
  m << where << ": " << name << " = " << v << ": expected " << expected;
  throw std::invalid_argument(m.str());
}

/** The inputs renderScene can draw: a camera above the floor, a pose within a quarter turn, finite boxes. */
void checkScene(double height, double pitch, double roll, const Scene& s)
{
  const char* where = "renderScene";
  require(std::isfinite(height) && height > 0.0, where, "height", height, "a finite height above the floor > 0 m");
  require(std::fabs(pitch) <= M_PI / 2, where, "pitch", pitch, "a finite angle within +-pi/2 rad");
  require(std::isfinite(roll), where, "roll", roll, "a finite angle");
  require(s.ceiling == 0.0 || (std::isfinite(s.ceiling) && s.ceiling > height), where, "ceiling", s.ceiling,
          "0 (none) or a finite height above the sensor's");
  require(std::isfinite(s.hole_depth) && s.hole_depth > 0.0, where, "hole_depth", s.hole_depth, "a finite depth > 0 m");
  for (const auto* list : {&s.boxes, &s.holes})
    for (std::size_t i = 0; i < list->size(); ++i)
    {
      const Box& b = (*list)[i];
      const bool holes = list == &s.holes;
      const bool ok = b.x0 < b.x1 && b.y0 < b.y1 && (holes || b.z0 < b.z1) &&
                      std::isfinite(b.x0 + b.x1 + b.y0 + b.y1 + (holes ? 0.0 : b.z0 + b.z1));
      require(ok, where, std::string(holes ? "hole " : "box ") + std::to_string(i) + " x0", b.x0,
              holes ? "finite x0 < x1, y0 < y1 [m]" : "finite x0 < x1, y0 < y1, z0 < z1 [m]");
    }
}
}  // namespace

void renderScene(const Camera& camera, double height, double pitch, double roll, const Scene& scene, Rendering& out)
{
  camera.validate();
  checkScene(height, pitch, roll, scene);
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
  require(std::isfinite(sigma0) && sigma0 >= 0.0, "addKinectNoise", "sigma0", sigma0, "a finite sigma >= 0 m");
  require(std::isfinite(k) && k >= 0.0, "addKinectNoise", "k", k, "a finite factor >= 0 m/m^2");
  require(dropout >= 0.0 && dropout <= 1.0, "addKinectNoise", "dropout", dropout, "a fraction in [0, 1]");
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
  require(max_range > 0.0, "addTofArtefacts", "max_range", max_range, "a range > 0 m (+inf: none)");
  require(flying >= 0.0 && flying <= 1.0, "addTofArtefacts", "flying", flying, "a probability in [0, 1]");
  require(edge_jump > 0.0, "addTofArtefacts", "edge_jump", edge_jump, "a jump > 0 m");
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

namespace
{
/** The farthest depth within reach rows above (u, v) that lies more than smear_jump beyond z; z if none. */
float smearSource(const cv::Mat& src, int u, int v, float z, int reach, double smear_jump)
{
  float far = z;
  for (int k = 1; k <= reach && v - k >= 0; ++k)
  {
    const float n = src.at<float>(v - k, u);
    if (std::isfinite(n) && n - z > smear_jump && n > far)
      far = n;
  }
  return far;
}
}  // namespace

void addStereoArtefacts(cv::Mat& depth, std::uint64_t seed, const StereoArtefacts& a)
{
  if (depth.type() != CV_32FC1)
    throw std::invalid_argument("addStereoArtefacts: image type " + cv::typeToString(depth.type()) +
                                ": expected 32FC1");
  if (!(a.focal_baseline > 0.0) || !(a.subpixel >= 0.0) || !(a.smear_rows >= 0) || !(a.max_range > 0.0))
    throw std::invalid_argument("addStereoArtefacts: expected focal_baseline > 0, subpixel >= 0, smear_rows >= 0 "
                                "and max_range > 0");
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // The matching window's reach per column: a coherent band, not salt and pepper (0 where it does not smear).
  std::vector<int> reach(depth.cols);
  for (int& r : reach)
    r = uniform(rng) < a.smear ? static_cast<int>(uniform(rng) * (a.smear_rows + 1)) : 0;
  const cv::Mat src = depth.clone();
  const float inf = std::numeric_limits<float>::infinity();
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 0; u < depth.cols; ++u)
    {
      const double n = normal(rng), drop = uniform(rng);
      float z = src.at<float>(v, u);
      if (!std::isfinite(z))
        continue;
      z = smearSource(src, u, v, z, reach[u], a.smear_jump);
      const double disparity = a.focal_baseline / z - a.bias + a.subpixel * n;
      const double out = disparity > 0.0 ? a.focal_baseline / disparity : inf;
      depth.at<float>(v, u) = drop < a.dropout || !(out <= a.max_range) ? inf : static_cast<float>(out);
    }
  // Wrong matches: small blobs at a random depth within range, drawn after the rest (the same seed, the same frame).
  const int blobs = static_cast<int>(a.speckle * depth.total() / 4.0);
  for (int i = 0; i < blobs; ++i)
  {
    const int u = static_cast<int>(uniform(rng) * (depth.cols - 1)), v = static_cast<int>(uniform(rng) * (depth.rows - 1));
    const float z = static_cast<float>(0.3 + uniform(rng) * (a.max_range - 0.3));
    for (int dv = 0; dv < 2; ++dv)
      for (int du = 0; du < 2; ++du)
        if (std::isfinite(depth.at<float>(v + dv, u + du)))
          depth.at<float>(v + dv, u + du) = z;
  }
}

cv::Mat encodeDepth(const cv::Mat& metres, int type, double max_depth)
{
  {
    Config c;  // the 8-bit scale is Config.max_depth's: the same range
    c.max_depth = max_depth;
    if (const std::string problem = configField("max_depth").rangeProblem(c); !problem.empty())
      throw std::invalid_argument("encodeDepth: " + problem);
  }
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
