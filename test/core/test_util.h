// Helpers shared by the core tests: slow, obvious reference geometry in double precision.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"

namespace kp_test
{
/** @return the operator new calls of this process so far (counted in test/core/main.cpp). */
long newCalls();

constexpr double kInf = std::numeric_limits<double>::infinity();

struct V3
{
  double x, y, z;
};

/** Ray of pixel (u, v) in the gravity-aligned frame (x fwd, y left, z up), per metre of optical depth:
 *  R = Ry(pitch) * Rx(roll) applied to (1, -xn, -yn), written out with explicit matrices. */
inline V3 rayWorld(const kinect_pipeline::Camera& c, double u, double v, double pitch, double roll)
{
  const double xn = (u - c.cx) / c.fx, yn = (v - c.cy) / c.fy;
  const double b[3] = {1.0, -xn, -yn};
  const double Rx[3][3] = {{1, 0, 0}, {0, std::cos(roll), -std::sin(roll)}, {0, std::sin(roll), std::cos(roll)}};
  const double Ry[3][3] = {{std::cos(pitch), 0, std::sin(pitch)}, {0, 1, 0}, {-std::sin(pitch), 0, std::cos(pitch)}};
  double t[3], o[3];
  for (int i = 0; i < 3; ++i)
    t[i] = Rx[i][0] * b[0] + Rx[i][1] * b[1] + Rx[i][2] * b[2];
  for (int i = 0; i < 3; ++i)
    o[i] = Ry[i][0] * t[0] + Ry[i][1] * t[1] + Ry[i][2] * t[2];
  return {o[0], o[1], o[2]};
}

/**
 * Bearing [rad, counter-clockwise from forward] and range per metre of depth of pixel (u, v) for a projection:
 * horizontal (the ray in the gravity-aligned frame), or the column model (exact, or the thesis's linear angle).
 */
inline void pixelBeam(const kinect_pipeline::Camera& c, const kinect_pipeline::Config& cfg, int u, int v,
                      double pitch, double roll, double& angle, double& k)
{
  using kinect_pipeline::Geometry;
  using kinect_pipeline::Projection;
  if (cfg.projection == Projection::kHorizontal)
  {
    const V3 d = rayWorld(c, u, v, pitch, roll);
    angle = std::atan2(d.y, d.x);
    k = std::hypot(d.x, d.y);
  }
  else if (cfg.geometry == Geometry::kExact)
  {
    angle = -std::atan((u - c.cx) / c.fx);
    k = std::sqrt(1.0 + std::pow((u - c.cx) / c.fx, 2));
  }
  else
  {
    const double tx = (u - c.width / 2.0) / c.width * c.hfov();
    angle = -tx;
    k = 1.0 / std::cos(tx);
  }
}

/** Depth at which the ray of pixel (u, v) meets the plane z = plane_z, seen from height h; +Inf if never. */
inline double planeDepth(const kinect_pipeline::Camera& c, int u, int v, double h, double pitch, double roll,
                         double plane_z)
{
  const V3 d = rayWorld(c, u, v, pitch, roll);
  const double t = (plane_z - h) / d.z;
  return (d.z != 0.0 && t > 0.0) ? t : kInf;
}
/** Reference t(d): linear interpolation of the control points written out, flat outside. */
inline double slowCurve(const std::vector<kinect_pipeline::CurvePoint>& c, double d)
{
  if (d <= c.front().depth)
    return c.front().threshold;
  for (std::size_t i = 1; i < c.size(); ++i)
    if (d <= c[i].depth)
      return c[i - 1].threshold +
             (c[i].threshold - c[i - 1].threshold) * (d - c[i - 1].depth) / (c[i].depth - c[i - 1].depth);
  return c.back().threshold;
}
/**
 * Reference binning of one row: put(k, v) for each finite range v in the bin k of its pixel centre's fractional
 * bin position f[u]; bins between two neighbouring centres get the range of the nearer centre. Bins outside
 * 0..beams-1 are dropped.
 */
template <typename Put>
void binRowWith(const std::vector<double>& f, const std::vector<double>& rng, int beams, Put put)
{
  const int w = static_cast<int>(f.size());
  auto in = [&](int k, double v) {
    if (k >= 0 && k < beams && std::isfinite(v))
      put(k, v);
  };
  for (int u = 0; u < w; ++u)
  {
    in(static_cast<int>(std::floor(f[u])), rng[u]);
    if (u + 1 == w)
      break;
    const double lo_f = std::min(f[u], f[u + 1]), hi_f = std::max(f[u], f[u + 1]);
    const double r_lo = f[u] < f[u + 1] ? rng[u] : rng[u + 1], r_hi = f[u] < f[u + 1] ? rng[u + 1] : rng[u];
    for (int k = static_cast<int>(std::floor(lo_f)) + 1; k <= static_cast<int>(std::floor(hi_f)) - 1; ++k)
      in(k, (k + 0.5) < 0.5 * (lo_f + hi_f) ? r_lo : r_hi);
  }
}

/** binRowWith keeping the nearest range per bin; counts (if given) counts the finite ranges. */
inline void binRow(const std::vector<double>& f, const std::vector<double>& rng, std::vector<double>& ranges,
                   std::vector<int>* counts)
{
  binRowWith(f, rng, static_cast<int>(ranges.size()), [&](int k, double v) {
    ranges[k] = std::min(ranges[k], v);
    if (counts)
      ++(*counts)[k];
  });
}

/** Whether two images have the same size, type and bytes (any row step). */
inline bool sameBits(const cv::Mat& a, const cv::Mat& b)
{
  if (a.size() != b.size() || a.type() != b.type())
    return false;
  for (int r = 0; r < a.rows; ++r)
    if (std::memcmp(a.ptr(r), b.ptr(r), a.cols * a.elemSize()) != 0)
      return false;
  return true;
}

/** Expects std::invalid_argument from @p f whose message contains every one of @p words. */
template <typename F>
void expectInvalid(F f, std::initializer_list<const char*> words)
{
  try
  {
    f();
    FAIL() << "no exception";
  }
  catch (const std::invalid_argument& e)
  {
    for (const char* w : words)
      EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << "'" << w << "' not in: " << e.what();
  }
}

}  // namespace kp_test

#include <functional>
#include <iostream>

#include "kinect_pipeline/simd.h"

namespace kp_test
{
/**
 * Runs check(target) under each SIMD target this CPU has (kinect_pipeline::simdTargets(): every one the dispatch
 * can pick here), then restores the target in force before: KINECT_PIPELINE_SIMD's, so that the tests after it run
 * on the target it names, or the CPU's best. The targets it ran, for the test to assert on.
 */
inline std::vector<std::string> forEachSimdTarget(const std::function<void(const std::string&)>& check)
{
  struct Restore
  {
    std::string target;
    ~Restore() { kinect_pipeline::restrictSimd(target); }
  } restore{kinect_pipeline::simdTarget() == kinect_pipeline::simdTargets().front() ? "native"
                                                                                     : kinect_pipeline::simdTarget()};
  std::vector<std::string> ran;
  for (const std::string& t : kinect_pipeline::simdTargets())
  {
    kinect_pipeline::restrictSimd(t);
    if (kinect_pipeline::simdTarget() != t)
      throw std::runtime_error("restrictSimd(" + t + ") left the dispatch at " + kinect_pipeline::simdTarget());
    check(t);
    ran.push_back(t);
  }
  std::string names;
  for (const std::string& t : ran)
    names += (names.empty() ? "" : ", ") + t;
  std::cout << "[ info ] SIMD targets run: " << names << std::endl;
  return ran;
}
}  // namespace kp_test
