// Raw depth images to rectified ones (io/rectify.h): the lens models against their formulas written out here, what
// lies outside the raw image, the errors, and the rule that decides it per topic. test/python/test_rectify.py holds
// the maps to OpenCV's initUndistortRectifyMap.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "kinect_pipeline/io/rectify.h"

using namespace kinect_pipeline;

namespace
{
const Camera kCam(64, 48, 50.0, 52.0, 31.5, 23.5);

cv::Mat ramp()
{
  cv::Mat raw(kCam.height, kCam.width, CV_16UC1);
  for (int v = 0; v < raw.rows; ++v)
    for (int u = 0; u < raw.cols; ++u)
      raw.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>(1000 + 100 * v + u);
  return raw;
}

std::string message(const std::function<void()>& f)
{
  try
  {
    f();
  }
  catch (const std::invalid_argument& e)
  {
    return e.what();
  }
  return "no exception";
}
}  // namespace

TEST(Rectify, NoDistortionIsACopy)
{
  for (const auto& [model, D] : {std::pair<std::string, std::vector<double>>{"plumb_bob", {0, 0, 0, 0, 0}},
                                 {"", {}},
                                 {"unknown_model", {0.0, 0.0}}})
  {
    const DepthRectifier r(kCam, model, D);
    EXPECT_TRUE(r.identity()) << model;
    EXPECT_EQ(r.maxShift(), 0.0);
    cv::Mat out;
    r.apply(ramp(), out);
    EXPECT_EQ(cv::norm(out, ramp(), cv::NORM_INF), 0.0);
  }
}

TEST(Rectify, EachPixelTakesTheRawPixelWhereItsRayMeetsTheRawImage)
{
  // Radial k1 and tangential p1 of plumb_bob, and the equidistant model, written out.
  const double k1 = -0.2, p1 = 0.01, e1 = 0.05;
  struct Case
  {
    std::string model;
    std::vector<double> D;
    std::function<cv::Point2d(double, double)> lens;
  };
  const std::vector<Case> cases = {
      {"plumb_bob", {k1, 0, p1, 0, 0},
       [&](double x, double y) {
         const double r2 = x * x + y * y;
         return cv::Point2d(x * (1 + k1 * r2) + 2 * p1 * x * y, y * (1 + k1 * r2) + p1 * (r2 + 2 * y * y));
       }},
      {"equidistant", {e1, 0, 0, 0}, [&](double x, double y) {
         const double r = std::hypot(x, y), th = std::atan(r), s = th * (1 + e1 * th * th) / r;
         return cv::Point2d(x * s, y * s);
       }}};
  const cv::Mat raw = ramp();
  for (const Case& c : cases)
  {
    const DepthRectifier r(kCam, c.model, c.D);
    cv::Mat out;
    r.apply(raw, out);
    int outside = 0;
    double shift = 0.0;
    for (int v = 0; v < kCam.height; ++v)
      for (int u = 0; u < kCam.width; ++u)
      {
        const cv::Point2d d = c.lens((u - kCam.cx) / kCam.fx, (v - kCam.cy) / kCam.fy);
        const double ur = kCam.fx * d.x + kCam.cx, vr = kCam.fy * d.y + kCam.cy;
        shift = std::max(shift, std::hypot(ur - u, vr - v));
        const int ui = static_cast<int>(std::lround(ur)), vi = static_cast<int>(std::lround(vr));
        const bool in = ui >= 0 && ui < kCam.width && vi >= 0 && vi < kCam.height;
        outside += in ? 0 : 1;
        const int want = in ? raw.at<std::uint16_t>(vi, ui) : 0;
        ASSERT_EQ(out.at<std::uint16_t>(v, u), want) << c.model << " at (" << u << ", " << v << ")";
      }
    EXPECT_NEAR(r.maxShift(), shift, 1e-9) << c.model;
    EXPECT_NEAR(r.outside(), outside / double(kCam.width * kCam.height), 1e-12) << c.model;
    EXPECT_GT(r.maxShift(), 1.0) << c.model << ": a distortion that moves pixels";
  }
  EXPECT_GT(DepthRectifier(kCam, "plumb_bob", {0.3, 0, 0, 0}).outside(), 0.0) << "pincushion: corners from outside";
}

TEST(Rectify, EveryEncodingKeepsItsValues)
{
  const DepthRectifier r(kCam, "rational_polynomial", {-0.1, 0.01, 0, 0, 0, 0.05, 0, 0});
  cv::Mat raw16 = ramp(), out16, raw32, out32, raw8, out8;
  raw16.convertTo(raw32, CV_32FC1, 0.001);
  raw16.convertTo(raw8, CV_8UC1, 0.05);
  r.apply(raw16, out16);
  r.apply(raw32, out32);
  r.apply(raw8, out8);
  cv::Mat want32, want8;
  out16.convertTo(want32, CV_32FC1, 0.001);
  EXPECT_EQ(cv::norm(out32, want32, cv::NORM_INF), 0.0) << "no value is blended";
  cv::Mat padded(kCam.height, kCam.width + 7, CV_16UC1, cv::Scalar(7)), out_view;  // rows with a step of their own
  raw16.copyTo(padded(cv::Rect(0, 0, kCam.width, kCam.height)));
  r.apply(padded(cv::Rect(0, 0, kCam.width, kCam.height)), out_view);
  EXPECT_EQ(cv::norm(out_view, out16, cv::NORM_INF), 0.0) << "a view into a wider image";
  ASSERT_EQ(out8.type(), CV_8UC1);
  EXPECT_EQ(cv::countNonZero(out8 != 0), cv::countNonZero(out16 != 0));
}

TEST(Rectify, WhatItCannotTakeIsNamed)
{
  std::string m = message([] { DepthRectifier(kCam, "fisheye", {0.1, 0.0, 0.0, 0.0}); });
  EXPECT_NE(m.find("distortion_model 'fisheye', D = [0.1, 0, 0, 0]: expected plumb_bob (4 or 5"), std::string::npos)
      << m;
  m = message([] { DepthRectifier(kCam, "rational_polynomial", {0.1, 0.0, 0.0, 0.0, 0.0}); });
  EXPECT_NE(m.find("rational_polynomial (8)"), std::string::npos) << m;
  m = message([] { DepthRectifier(kCam, "plumb_bob", {NAN, 0.0, 0.0, 0.0, 0.0}); });
  EXPECT_NE(m.find("expected finite coefficients"), std::string::npos) << m;
  const DepthRectifier r(kCam, "plumb_bob", {0.1, 0, 0, 0, 0});
  cv::Mat out;
  m = message([&] { r.apply(cv::Mat(10, 10, CV_16UC1, cv::Scalar(1)), out); });
  EXPECT_NE(m.find("depth image 10x10 to rectify: expected its camera's 64x48"), std::string::npos) << m;
}

TEST(Rectify, TheTopicsNameDecidesInAutoMode)
{
  const DepthRectifier lens(kCam, "plumb_bob", {0.1, 0, 0, 0, 0}), none(kCam, "plumb_bob", {});
  std::string why;
  EXPECT_TRUE(rectifyWanted("auto", "/kinect2/sd/image_depth", lens, false, why));
  EXPECT_NE(why.find("yes (pixels move up to"), std::string::npos) << why;
  for (const char* rectified : {"/kinect2/sd/image_depth_rect", "/camera/depth/image_rect_raw/compressedDepth",
                                "/camera/depth/image_rect/compressed"})
  {
    EXPECT_FALSE(rectifyWanted("auto", rectified, lens, false, why)) << rectified;
    EXPECT_NE(why.find("the topic's name says it is rectified"), std::string::npos) << why;
    EXPECT_TRUE(rectifyWanted("always", rectified, lens, false, why)) << rectified;
  }
  EXPECT_TRUE(rectifyWanted("auto", "/rect/image_raw", lens, false, why)) << "only the image's own name counts";
  EXPECT_FALSE(rectifyWanted("always", "/kinect2/sd/image_depth", none, false, why));
  EXPECT_EQ(why, "no (the camera_info has no distortion)");
  EXPECT_FALSE(rectifyWanted("never", "/kinect2/sd/image_depth", lens, false, why));
  // A stereo camera's depth is computed on rectified pairs: its camera_info's R rotates.
  EXPECT_FALSE(rectifyWanted("auto", "/stereo/depth", lens, true, why));
  EXPECT_NE(why.find("a stereo camera's, whose depth images are rectified"), std::string::npos) << why;
  EXPECT_TRUE(rectifyWanted("always", "/stereo/depth", lens, true, why));
  CameraLens l;
  EXPECT_FALSE(l.stereo()) << "R not set";
  l.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  EXPECT_FALSE(l.stereo()) << "the identity";
  l.R = {0.9998, -0.0175, 0, 0.0175, 0.9998, 0, 0, 0, 1};
  EXPECT_TRUE(l.stereo()) << "a rotation of 1 deg";
  EXPECT_NE(message([&] { rectifyWanted("yes", "/a", lens, false, why); }).find("rectify = 'yes': expected auto, always or never"),
            std::string::npos);
}

TEST(Rectify, ATopicsRectificationIsDecidedAgainOnlyWhenSomethingChanged)
{
  TopicRectification t;
  const cv::Mat raw = ramp();
  const CameraLens D{"plumb_bob", {0.1, 0, 0, 0, 0}, {}};
  const cv::Mat& a = t.apply("auto", "/k/image_depth", kCam, D, raw);
  EXPECT_TRUE(t.decidedAnew());
  EXPECT_NE(a.data, raw.data);
  t.apply("auto", "/k/image_depth", kCam, D, raw);
  EXPECT_FALSE(t.decidedAnew());
  EXPECT_TRUE(t.distorts());
  t.apply("auto", "/k/image_depth_rect", kCam, D, raw);
  EXPECT_TRUE(t.decidedAnew());
  EXPECT_TRUE(t.distorts()) << "a lens, though not rectified here";
  const cv::Mat& b = t.apply("never", "/k/image_depth", kCam, D, raw);
  EXPECT_TRUE(t.decidedAnew());
  EXPECT_EQ(b.data, raw.data) << "never: the image itself";
  EXPECT_FALSE(t.distorts()) << "never does not look at the lens";
  // "never" never looks at the distortion: one it cannot take is no error there.
  EXPECT_EQ(t.apply("never", "/k/image_depth", kCam, CameraLens{"fisheye", {1.0}, {}}, raw).data, raw.data);
  EXPECT_NE(message([&] { t.apply("auto", "/k/image_depth", kCam, CameraLens{"fisheye", {1.0}, {}}, raw); }).find("'fisheye'"),
            std::string::npos);
}
