// Negative obstacles (Config::cliff_scan, cliff_in_scan, cliff_min_pixels) against a reference built from the
// ray caster's ground truth: the nearest hole-bottom / lower-step hit per beam, binned by its bearing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/tools/synthetic.h"
#include "test_scenes.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
constexpr float kInfF = std::numeric_limits<float>::infinity();

Camera kinect() { return Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180); }

using kp_test::holeScene;
using kp_test::stairScene;

// Depth [m] of an encoded frame after the opening the pipeline uses (3x3 rect): OpenCV's morphologyEx on the
// metres (min and max commute with the encodings' monotone scale), unknown pixels as the largest value.
cv::Mat openedMetres(const cv::Mat& frame, double max_depth)
{
  cv::Mat m(frame.size(), CV_32F);
  for (int r = 0; r < frame.rows; ++r)
    for (int u = 0; u < frame.cols; ++u)
    {
      double d;
      if (frame.type() == CV_8UC1)
        d = frame.at<std::uint8_t>(r, u) < 2 ? -1.0 : frame.at<std::uint8_t>(r, u) * max_depth / 255.0;
      else if (frame.type() == CV_16UC1)
        d = frame.at<std::uint16_t>(r, u) == 0 ? -1.0 : frame.at<std::uint16_t>(r, u) * 0.001;
      else
        d = std::isfinite(frame.at<float>(r, u)) && frame.at<float>(r, u) > 0 ? frame.at<float>(r, u) : -1.0;
      m.at<float>(r, u) = d < 0 ? std::numeric_limits<float>::max() : static_cast<float>(d);
    }
  cv::Mat opened;
  cv::morphologyEx(m, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)));
  return opened;
}

struct Truth
{
  std::vector<double> nearest;  // nearest below-floor range per beam (+Inf none)
  std::vector<int> pixels;      // below-floor pixels per beam
};

// The pipeline's below-floor pixels at their opened depth, binned by the reference binning (double precision
// rays, bins between neighbouring centres to the nearer one).
Truth perBeam(const Camera& cam, const cv::Mat& labels, const cv::Mat& opened, double pitch, double roll,
              const ScanData& scan)
{
  const int beams = static_cast<int>(scan.ranges.size());
  Truth t{std::vector<double>(beams, kp_test::kInf), std::vector<int>(beams, 0)};
  const double lo = scan.angle_min - 0.5 * scan.angle_increment;
  std::vector<double> f(labels.cols), rng(labels.cols);
  for (int r = 0; r < labels.rows; ++r)
  {
    for (int u = 0; u < labels.cols; ++u)
    {
      const kp_test::V3 d = kp_test::rayWorld(cam, u, r, pitch, roll);
      f[u] = (std::atan2(d.y, d.x) - lo) / scan.angle_increment;
      rng[u] = labels.at<std::uint8_t>(r, u) == kBelowFloor ? opened.at<float>(r, u) * std::hypot(d.x, d.y)
                                                            : kp_test::kInf;
    }
    kp_test::binRow(f, rng, t.nearest, &t.pixels);
  }
  return t;
}

// Beams whose own pixels and both neighbours' are all below the floor or all not (away from the hole's sides).
bool interior(const Truth& t, int b, int min_pixels, bool cliff)
{
  for (int k = std::max(0, b - 1); k <= std::min<int>(t.pixels.size() - 1, b + 1); ++k)
    if (cliff ? t.pixels[k] < min_pixels + 3 : t.pixels[k] > 0)
      return false;
  return true;
}

// The below-floor labels against the ray caster's truth: only pixels that see into the hole, and nearly all of
// those well below the floor away from the rim.
void checkLabelsAgainstTruth(const cv::Mat& labels, const Rendering& gt)
{
  int below = 0, stray = 0, hole = 0, found = 0;
  for (int r = 1; r < labels.rows - 1; ++r)
    for (int u = 1; u < labels.cols - 1; ++u)
    {
      // Hole pixels well below the floor (not the top of a hole's far wall) within 6 m.
      int hole_around = 0;
      for (int dr = -1; dr <= 1; ++dr)
        for (int du = -1; du <= 1; ++du)
          hole_around += gt.object.at<short>(r + dr, u + du) == 2 && gt.height.at<float>(r + dr, u + du) < -0.1f &&
                         gt.range.at<float>(r + dr, u + du) < 6.0f;
      const bool is_below = labels.at<std::uint8_t>(r, u) == kBelowFloor;
      below += is_below;
      stray += is_below && gt.object.at<short>(r, u) != 2 && gt.range.at<float>(r, u) < 8.0f;
      if (hole_around == 9)
      {
        ++hole;
        found += is_below;
      }
    }
  EXPECT_EQ(stray, 0) << "of " << below << " below-floor pixels";
  ASSERT_GT(hole, 200);
  EXPECT_GE(found, 0.97 * hole) << "of " << hole << " hole-bottom pixels away from the rim";
}

struct CliffCase
{
  int type;
  double pitch, roll;
  bool stair;
};

void checkCliff(const CliffCase& c)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.sensor_height = 1.1;
  cfg.sensor_pitch = 0.3;
  cfg.range_max = 20.0;
  Rendering gt;
  renderScene(cam, cfg.sensor_height, c.pitch, c.roll, c.stair ? stairScene() : holeScene(), gt);
  Pipeline pipe(cam, cfg);
  FrameResult res;
  pipe.process(encodeDepth(gt.depth, c.type, cfg.max_depth), c.pitch - cfg.sensor_pitch, c.roll, res);
  ASSERT_EQ(res.cliff.ranges.size(), res.scan.ranges.size());
  EXPECT_FLOAT_EQ(res.cliff.angle_min, res.scan.angle_min);
  EXPECT_FLOAT_EQ(res.cliff.angle_increment, res.scan.angle_increment);
  EXPECT_TRUE(res.cliff.intensities.empty());
  const cv::Mat frame = encodeDepth(gt.depth, c.type, cfg.max_depth);
  checkLabelsAgainstTruth(res.labels, gt);
  // binned at the pose the frame was processed at (the floor refinement's, within noise of the truth)
  EXPECT_NEAR(res.pose.pitch, c.pitch, 0.002);
  const Truth t = perBeam(cam, res.labels, openedMetres(frame, cfg.max_depth), res.pose.pitch, res.pose.roll, res.scan);
  const double tol = 1e-3;  // float against double rays
  int seen = 0, cliff_beams = 0, off = 0;
  for (std::size_t b = 0; b < t.pixels.size(); ++b)
  {
    const float got = res.cliff.ranges[b];
    if (interior(t, static_cast<int>(b), cfg.cliff_min_pixels, true))
    {
      ++seen;
      ASSERT_TRUE(std::isfinite(got)) << "beam " << b << " sees " << t.pixels[b] << " below-floor pixels";
      // A pixel centre on a bin boundary may fall on either side in float and in double.
      if (std::fabs(got - t.nearest[b]) > tol * t.nearest[b] + 1e-4 && ++off <= 3)
        std::printf("beam %zu: %.4f m, reference %.4f m\n", b, got, t.nearest[b]);
    }
    else if (interior(t, static_cast<int>(b), cfg.cliff_min_pixels, false))
    {
      EXPECT_FALSE(std::isfinite(got)) << "beam " << b << " sees no hole but reports " << got;
    }
    cliff_beams += std::isfinite(got);
  }
  EXPECT_GT(seen, c.stair ? 300 : 40);
  EXPECT_LE(off, std::max(2, seen / 100)) << "beams off the reference, of " << seen;
  EXPECT_GT(res.counts[kBelowFloor], 0u);
  // The main scan is unchanged by default; with cliff_in_scan it is the nearer of the two per beam.
  cfg.cliff_in_scan = true;
  Pipeline with(cam, cfg);
  FrameResult res2;
  with.process(encodeDepth(gt.depth, c.type, cfg.max_depth), c.pitch - cfg.sensor_pitch, c.roll, res2);
  int moved = 0;
  for (std::size_t b = 0; b < res.scan.ranges.size(); ++b)
  {
    const float a = res.scan.ranges[b], cl = res.cliff.ranges[b], both = res2.scan.ranges[b];
    if (std::isnan(a))
    {
      EXPECT_TRUE(std::isnan(both));
      continue;
    }
    const float want = std::isfinite(cl) && !(a < cl) ? cl : a;
    EXPECT_EQ(both, want) << "beam " << b;
    moved += both != a;
  }
  EXPECT_GT(moved, 0);
  EXPECT_EQ(moved, cliff_beams);  // nothing but the floor and the hole in view: every cliff beam was +Inf
}
}  // namespace

class CliffScan : public ::testing::TestWithParam<CliffCase>
{
};

TEST_P(CliffScan, MatchesTheRenderedHoleOrStair) { checkCliff(GetParam()); }

INSTANTIATE_TEST_SUITE_P(Scenes, CliffScan,
                         ::testing::Values(CliffCase{CV_16UC1, 0.3, 0.0, false}, CliffCase{CV_32FC1, 0.36, 0.0, false},
                                           CliffCase{CV_8UC1, 0.25, 0.0, false}, CliffCase{CV_16UC1, 0.3, 0.035, false},
                                           CliffCase{CV_16UC1, 0.3, 0.0, true}, CliffCase{CV_32FC1, 0.22, 0.02, true},
                                           CliffCase{CV_8UC1, 0.3, 0.0, true}));

TEST(CliffScan, FlatFloorWithAPitchingBaseNeverFires)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.sensor_height = 1.1;
  cfg.sensor_pitch = 0.3;
  cfg.cliff_in_scan = true;
  Scene s;  // floor only
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
  {
    Pipeline pipe(cam, cfg);
    FrameResult res;
    for (int i = 0; i < 12; ++i)
    {
      const double base_pitch = 0.1 * std::sin(0.9 * i) + (i == 7 ? -0.08 : 0.0);  // oscillation and a jerk
      const double roll = 0.02 * std::cos(0.5 * i);
      Rendering gt;
      renderScene(cam, cfg.sensor_height, cfg.sensor_pitch + base_pitch, roll, s, gt);
      cv::Mat metres = gt.depth.clone();
      addKinectNoise(metres, 100 + i);
      pipe.process(encodeDepth(metres, type, cfg.max_depth), base_pitch, roll, res);
      for (std::size_t b = 0; b < res.cliff.ranges.size(); ++b)
        ASSERT_FALSE(std::isfinite(res.cliff.ranges[b])) << "type " << type << " frame " << i << " beam " << b;
    }
  }
}

TEST(CliffScan, OffLeavesItEmptyAndMinPixelsThins)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.sensor_pitch = 0.3;
  Rendering gt;
  renderScene(cam, cfg.sensor_height, cfg.sensor_pitch, 0.0, holeScene(), gt);
  const cv::Mat frame = encodeDepth(gt.depth, CV_16UC1, cfg.max_depth);
  std::vector<int> finite;
  for (const int min_pixels : {1, 3, 40, 100000})
  {
    cfg.cliff_min_pixels = min_pixels;
    Pipeline pipe(cam, cfg);
    FrameResult res;
    pipe.process(frame, 0.0, 0.0, res);
    int n = 0;
    for (const float r : res.cliff.ranges)
      n += std::isfinite(r);
    finite.push_back(n);
  }
  EXPECT_GT(finite[0], 0);
  EXPECT_GE(finite[0], finite[1]);
  EXPECT_GT(finite[1], finite[2]);
  EXPECT_EQ(finite[3], 0);
  cfg.cliff_scan = false;
  Pipeline off(cam, cfg);
  FrameResult res;
  off.process(frame, 0.0, 0.0, res);
  EXPECT_TRUE(res.cliff.ranges.empty());
  EXPECT_GT(res.counts[kBelowFloor], 0u);  // still labelled
}

TEST(CliffScan, MinPixelsIsValidated)
{
  Config cfg;
  cfg.cliff_min_pixels = 0;
  try
  {
    cfg.validate();
    FAIL() << "cliff_min_pixels = 0 accepted";
  }
  catch (const std::invalid_argument& e)
  {
    EXPECT_NE(std::string(e.what()).find("cliff_min_pixels = 0"), std::string::npos) << e.what();
  }
}
