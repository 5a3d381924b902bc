// surface_band: each beam's range is the mean of its kept pixels' measured ranges within surface_band * t(m) of
// its nearest m.
// Checked against a per-pixel reference written here (double-precision rays, every contribution of every beam
// kept in a list), on noisy rendered frames in every encoding, both projections, with and without roll.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/tools/synthetic.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
Camera kinect() { return Camera::fromFov(512, 424, 1.2322, 1.0472); }

// A lab: a far wall at 5.5 m (where the sensor's noise is ~6 cm), benches and a person-sized box nearer.
Scene lab()
{
  Scene s;
  s.ceiling = 2.6;
  s.boxes = {{2.0, 2.6, -1.8, -0.6, 0.0, 0.9}, {1.6, 1.9, 0.3, 0.6, 0.0, 1.75}, {5.5, 5.8, -2.5, 2.5, 0.0, 2.6},
             {3.5, 4.2, 0.4, 1.6, 0.7, 0.78}};
  return s;
}

struct Case
{
  int type;
  Projection projection;
  double roll;
};

// Per beam, every range that the pixels labelled kept put into it, at their depth in `depth` (the cleaned image,
// or the raw frame: there its unknown values count as no return).
std::vector<std::vector<double>> contributions(const Camera& cam, const Config& cfg, const FrameResult& res,
                                               const cv::Mat& depth, double pitch, double roll)
{
  const ScanData& scan = res.scan;
  const int beams = static_cast<int>(scan.ranges.size());
  std::vector<std::vector<double>> per(beams);
  const double lo = scan.angle_min - 0.5 * scan.angle_increment;
  std::vector<double> f(cam.width), rng(cam.width);
  for (int r = 0; r < cam.height; ++r)
  {
    for (int u = 0; u < cam.width; ++u)
    {
      double angle, k;
      kp_test::pixelBeam(cam, cfg, u, r, pitch, roll, angle, k);
      f[u] = (angle - lo) / scan.angle_increment;
      double z = kp_test::kInf;
      if (res.labels.at<std::uint8_t>(r, u) == kKept)
      {
        switch (depth.type())
        {
          case CV_8UC1:  // 0 and 1 unknown (thesis eq 4.8), 255 no return
          {
            const int v = depth.at<std::uint8_t>(r, u);
            z = (v >= 2 && v < 255) ? v * cfg.max_depth / 255.0 : kp_test::kInf;
            break;
          }
          case CV_16UC1:
          {
            const int v = depth.at<std::uint16_t>(r, u);
            z = v > 0 ? v * 1e-3 : kp_test::kInf;
            break;
          }
          default:
          {
            const float v = depth.at<float>(r, u);
            z = (std::isfinite(v) && v > 0.0f) ? v : kp_test::kInf;
          }
        }
      }
      rng[u] = z * k;
    }
    kp_test::binRowWith(f, rng, beams, [&](int b, double v) { per[b].push_back(v); });
  }
  return per;
}

class SurfaceBand : public ::testing::TestWithParam<Case>
{
};

TEST_P(SurfaceBand, IsTheMeanOfTheRangesNearTheNearest)
{
  const Case c = GetParam();
  const Camera cam = kinect();
  const double pitch = 0.26, band = 1.0;
  Rendering gt;
  renderScene(cam, 1.1, pitch, c.roll, lab(), gt);
  cv::Mat metres = gt.depth.clone();
  addKinectNoise(metres, 5);
  Config cfg;
  cfg.sensor_height = 1.1;
  cfg.sensor_pitch = pitch;
  cfg.sensor_roll = c.roll;
  cfg.projection = c.projection;
  const cv::Mat frame = encodeDepth(metres, c.type, cfg.max_depth);
  FrameResult nearest, mean;
  Pipeline(cam, cfg).process(frame, 0.0, 0.0, nearest);
  cfg.surface_band = band;
  Pipeline(cam, cfg).process(frame, 0.0, 0.0, mean);

  // The labels and the cleaned image do not change; only the ranges do.
  ASSERT_EQ(cv::norm(nearest.labels, mean.labels, cv::NORM_INF), 0.0);
  // The nearest range from the cleaned (opened) depth, the mean from the measured one.
  // binned at the pose the frame was processed at (the floor refinement's)
  ASSERT_EQ(mean.pose.pitch, nearest.pose.pitch);
  const auto opened = contributions(cam, cfg, nearest, nearest.depth, nearest.pose.pitch, nearest.pose.roll);
  const auto raw = contributions(cam, cfg, nearest, frame, nearest.pose.pitch, nearest.pose.roll);
  int compared = 0, bad = 0, moved = 0;
  for (std::size_t b = 0; b < opened.size(); ++b)
  {
    const float got = mean.scan.ranges[b], near = nearest.scan.ranges[b];
    if (opened[b].empty() || !std::isfinite(near))
      continue;
    double m = kp_test::kInf;
    for (double v : opened[b])
      m = std::min(m, v);
    const double limit = m + band * kp_test::slowCurve(cfg.threshold_curve, m);
    double sum = 0.0;
    int n = 0;
    for (double v : raw[b])
      if (v <= limit)
      {
        sum += v;
        ++n;
      }
    if (n == 0)
      continue;  // the nearest was an opened pixel whose raw depth is no return, and nothing else is near
    const double want = sum / n;
    ++compared;
    bad += !(std::fabs(got - want) <= 1e-3 * want + 1e-4);
    moved += got > near + 1e-4;
    EXPECT_GE(got, near - 2e-6f * near - 1e-6f) << "beam " << b << ": a mean below its nearest range (sums are in um)";
    EXPECT_LE(got, limit + 1e-3) << "beam " << b;
  }
  ASSERT_GT(compared, 300);
  // A beam may differ where a pixel centre lies on a bin boundary (the pipeline's bearing is single precision).
  EXPECT_LE(bad, compared / 50) << "of " << compared;
  EXPECT_GT(moved, compared / 4) << "the estimator should move most noisy beams off their nearest pixel";
}

INSTANTIATE_TEST_SUITE_P(Encodings, SurfaceBand,
                         ::testing::Values(Case{CV_8UC1, Projection::kHorizontal, 0.0},
                                           Case{CV_16UC1, Projection::kHorizontal, 0.0},
                                           Case{CV_32FC1, Projection::kHorizontal, 0.0},
                                           Case{CV_16UC1, Projection::kHorizontal, 0.03},
                                           Case{CV_16UC1, Projection::kColumn, 0.0},
                                           Case{CV_8UC1, Projection::kColumn, 0.0}));

// The far wall's beams: the nearest of ~200 noisy pixels lands 2-3 sigma short; the surface mean does not.
TEST(SurfaceBandWall, RemovesTheNoiseBiasOnAFarWall)
{
  const Camera cam = kinect();
  Scene s;
  s.boxes = {{5.8, 6.0, -4.0, 4.0, 0.0, 2.5}};
  Rendering gt;
  renderScene(cam, 1.1, 0.1, 0.0, s, gt);
  cv::Mat metres = gt.depth.clone();
  addKinectNoise(metres, 9);
  const cv::Mat frame = encodeDepth(metres, CV_16UC1, 12.0);
  Config cfg;
  cfg.sensor_height = 1.1;
  cfg.sensor_pitch = 0.1;
  cfg.range_max = 20.0;
  auto shortBeams = [&](double band) {
    cfg.surface_band = band;
    FrameResult res;
    Pipeline(cam, cfg).process(frame, 0.0, 0.0, res);
    int n = 0, finite = 0;
    for (std::size_t b = 0; b < res.scan.ranges.size(); ++b)
    {
      const float r = res.scan.ranges[b];
      if (!std::isfinite(r))
        continue;
      ++finite;
      // The wall's horizontal range in this beam's direction.
      const double angle = res.scan.angle_min + b * res.scan.angle_increment;
      n += r < 5.8 / std::cos(angle) - 0.05;
    }
    EXPECT_GT(finite, 400);
    return static_cast<double>(n) / finite;
  };
  const double nearest = shortBeams(0.0), mean = shortBeams(1.0);
  EXPECT_GT(nearest, 0.05) << "the test needs a noisy wall";
  EXPECT_LE(mean, 0.002);
}

TEST(SurfaceBandConfig, IsValidated)
{
  Config cfg;
  cfg.surface_band = -0.1;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.surface_band = 11.0;
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.surface_band = std::nan("");
  EXPECT_THROW(cfg.validate(), std::invalid_argument);
  cfg.surface_band = 2.0;
  EXPECT_NO_THROW(cfg.validate());
}
}  // namespace
