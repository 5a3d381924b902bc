// Floor calibration (MSAC plane + least squares): how to use it and read its warnings in docs/tools.md, "Calibration".
#include "kinect_pipeline/tools/calibration.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <stdexcept>

#include "kinect_pipeline/model/plane_fit.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/stages/floor_fit.h"

namespace kinect_pipeline
{
namespace
{
struct Pt
{
  double x, y, z, w;  // optical frame [m], weight 1/sigma^2
};

struct Plane
{
  double n[3];  // unit normal towards the camera ("up")
  double d;     // camera's distance above the plane: n . p + d = 0 for p on the plane
};

// The up vector seen in the optical frame is row 2 of levelFromOptical (pose.h): see planeOf().
bool planeFrom3(const Pt& a, const Pt& b, const Pt& c, Plane& out)
{
  const double u[3] = {b.x - a.x, b.y - a.y, b.z - a.z}, v[3] = {c.x - a.x, c.y - a.y, c.z - a.z};
  double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (len < 1e-9)
    return false;
  for (double& x : n)
    x /= len;
  double d = -(n[0] * a.x + n[1] * a.y + n[2] * a.z);
  if (d < 0)  // make the camera (origin) lie on the positive side: n points towards it
  {
    for (double& x : n)
      x = -x;
    d = -d;
  }
  out = {{n[0], n[1], n[2]}, d};
  return true;
}

double band(double z) { return 3.0 * kinectSigma(z) + 0.01; }

double signedDistance(const Plane& p, const Pt& q) { return p.n[0] * q.x + p.n[1] * q.y + p.n[2] * q.z + p.d; }

struct Hyp
{
  Plane p;
  int support = 0;
  double score = -1.0;
};

/** MSAC over planes through three of the points @p from, facing up within max_tilt, at a plausible height: inliers
 *  count by how well they fit (1 - (e / band)^2), so a plane that only grazes many points in their wide far bands
 *  loses to one that fits its points tightly. */
Hyp bestPlane(const std::vector<Pt>& pts, const std::vector<std::size_t>& from, const CalibrationOptions& o,
              std::mt19937_64& rng)
{
  const double cos_tilt = std::cos(o.max_tilt);
  Hyp best;
  if (from.size() < 3)
    return best;
  std::uniform_int_distribution<std::size_t> draw(0, from.size() - 1);
  for (int it = 0; it < o.iterations; ++it)
  {
    Plane p;
    if (!planeFrom3(pts[from[draw(rng)]], pts[from[draw(rng)]], pts[from[draw(rng)]], p))
      continue;
    if (-p.n[1] < cos_tilt || p.d < o.min_height || p.d > o.max_height)  // up is (0, -1, 0) in the image
      continue;
    Hyp h{p, 0, 0.0};
    for (std::size_t i : from)
    {
      const double e = std::fabs(signedDistance(p, pts[i])) / band(pts[i].z);
      if (e < 1.0)
      {
        h.score += 1.0 - e * e;
        ++h.support;
      }
    }
    if (h.score > best.score)
      best = h;
  }
  return best;
}

// The image's points closer than max_range in the optical frame, every stride-th row and column, weighted by the
// depth noise 1 / sigma(z)^2.
std::vector<Pt> cloudOf(const cv::Mat& depth_m, const Camera& camera, const CalibrationOptions& o)
{
  std::vector<Pt> pts;
  const int stride = std::max(1, o.stride);
  for (int r = 0; r < depth_m.rows; r += stride)
    for (int u = 0; u < depth_m.cols; u += stride)
    {
      const float z = depth_m.at<float>(r, u);
      if (!(z > 0.1f && z < o.max_range))
        continue;
      const double s = kinectSigma(z);
      pts.push_back({(u - camera.cx) / camera.fx * z, (r - camera.cy) / camera.fy * z, z, 1.0 / (s * s)});
    }
  return pts;
}

// Whether a plane is within the options' tilt and height limits of a floor.
bool floorLike(const Plane& p, const CalibrationOptions& o)
{
  const double up[3] = {0.0, -1.0, 0.0};
  return !(p.n[0] * up[0] + p.n[1] * up[1] + p.n[2] * up[2] < std::cos(o.max_tilt) || p.d < o.min_height ||
           p.d > o.max_height);
}

/**
 * The floor among the planes of bestPlane over a subsample of the nearer points (their noise is small: far points
 * would support tilted planes). @return false where no plane has enough support, else the floor: the lowest such
 * plane, not the one holding the most pixels (a desk often does): the search goes on among the points below the
 * plane found, as long as a plane there holds at least min_fraction of them all.
 */
bool searchFloor(const std::vector<Pt>& pts, const CalibrationOptions& o, Plane& floor)
{
  std::mt19937_64 rng(o.seed);
  std::vector<std::size_t> sample, near;
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (pts[i].z < 4.0)
      near.push_back(i);
  if (near.size() < 50)
  {
    near.resize(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i)
      near[i] = i;
  }
  const std::size_t step = std::max<std::size_t>(1, near.size() / 6000);
  for (std::size_t i = 0; i < near.size(); i += step)
    sample.push_back(near[i]);
  const Hyp top = bestPlane(pts, sample, o, rng);
  if (top.support < std::max(10, static_cast<int>(o.min_fraction * sample.size())))
    return false;
  const int needed = std::max(10, static_cast<int>(o.min_fraction * sample.size()));
  Hyp chosen = top;
  for (int round = 0; round < 4; ++round)
  {
    std::vector<std::size_t> below;
    for (std::size_t i : sample)
      if (signedDistance(chosen.p, pts[i]) < -band(pts[i].z))
        below.push_back(i);
    if (static_cast<int>(below.size()) < needed)
      break;
    const Hyp lower = bestPlane(pts, below, o, rng);
    if (lower.support < needed || lower.p.d < chosen.p.d + 0.05)
      break;
    chosen = lower;
  }
  floor = chosen.p;
  return true;
}

/** The floor plane of a sensor pose in the optical frame: "up" is the level frame's z seen from the optical frame. */
Plane planeOf(const SensorPose& s)
{
  const std::array<double, 9> m = levelFromOptical(s.pitch, s.roll);
  return {{m[6], m[7], m[8]}, s.height};
}

/** The sensor pose whose floor is plane p. */
SensorPose poseOf(const Plane& p)
{
  SensorPose s{p.d, 0.0, 0.0};
  pitchRollFromUp(p.n, s.pitch, s.roll);
  return s;
}

/** A weighted least-squares plane: its inliers and the normal equations of its last pass. */
struct Refit
{
  Plane p;
  std::vector<const Pt*> in;
  PlaneSums sums;  ///< in the level frame of the pose the last pass started from
};

/**
 * Weighted least-squares refits on the inliers of p (weights 1 / sigma(z)^2), three times, re-selecting the
 * inliers: the plane z = a + b x + c y of plane_fit.h (the floor fit's) in the level frame of the pose p gives, as
 * the floor fit does, the pose whose floor that plane is. @return false where fewer than 10 inliers remain.
 */
bool refitPlane(const std::vector<Pt>& pts, const Plane& start, Refit& f)
{
  Plane p = start;
  for (int pass = 0; pass < 3; ++pass)
  {
    f.in.clear();
    for (const Pt& q : pts)
      if (std::fabs(p.n[0] * q.x + p.n[1] * q.y + p.n[2] * q.z + p.d) < band(q.z))
        f.in.push_back(&q);
    if (f.in.size() < 10)
      return false;
    const SensorPose at = poseOf(p);
    const std::array<double, 9> m = levelFromOptical(at.pitch, at.roll);
    f.sums = PlaneSums{};
    for (const Pt* q : f.in)
      f.sums.add(m[0] * q->x + m[1] * q->y + m[2] * q->z, m[3] * q->x + m[4] * q->y + m[5] * q->z,
                 m[6] * q->x + m[7] * q->y + m[8] * q->z, q->w);
    double abc[3];
    if (!solvePlane(f.sums.m, f.sums.rhs, abc))
      return false;
    p = planeOf(poseFromFloorPlane(at, abc[0], abc[1], abc[2]));
  }
  f.p = p;
  return true;
}

/** The pose of a refitted floor, its residuals and the uncertainty of each term. */
void describeFloor(const Refit& f, std::size_t points, FloorPose& out)
{
  const Plane& p = f.p;
  double ss = 0.0, wss = 0.0;
  for (const Pt* q : f.in)
  {
    const double e = p.n[0] * q->x + p.n[1] * q->y + p.n[2] * q->z + p.d;
    ss += e * e;
    wss += q->w * e * e;
  }
  out.found = true;
  out.height = p.d;
  pitchRollFromUp(p.n, out.pitch, out.roll);
  out.floor_pixels = static_cast<int>(f.in.size());
  out.floor_fraction = static_cast<double>(f.in.size()) / points;
  out.rms = std::sqrt(ss / f.in.size());
  // Uncertainty of a weighted plane fit: the residual scale times each term's standard deviation per unit weight.
  // In the level frame the height is -a, and the pitch and roll are the slopes b and c to first order.
  const double scale = std::sqrt(wss / std::max<std::size_t>(1, f.in.size() - 3));
  double var[3];
  planeTermVariances(f.sums.m, var);
  out.height_std = scale * std::sqrt(var[0]);
  out.pitch_std = scale * std::sqrt(var[1]);
  out.roll_std = scale * std::sqrt(var[2]);
}
}  // namespace

FloorPose calibrateFromFloor(const cv::Mat& depth_m, const Camera& camera, const CalibrationOptions& o)
{
  camera.validate();
  if (depth_m.type() != CV_32FC1 || depth_m.cols != camera.width || depth_m.rows != camera.height)
    throw std::invalid_argument("calibrateFromFloor: expected a 32FC1 depth image of the camera's size " +
                                std::to_string(camera.width) + "x" + std::to_string(camera.height));
  const std::vector<Pt> pts = cloudOf(depth_m, camera, o);
  FloorPose out;
  Plane floor;
  Refit fit;
  if (pts.size() < 50 || !searchFloor(pts, o, floor) || !refitPlane(pts, floor, fit))
    return out;
  // A slice of a wall at the tilt limit refits to the wall: what fails the limits after the refit is no floor.
  if (!floorLike(fit.p, o))
    return out;
  describeFloor(fit, pts.size(), out);
  return out;
}

}  // namespace kinect_pipeline
