#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "kinect_pipeline/scan.h"

using namespace kinect_pipeline;

namespace
{
constexpr float kInf = std::numeric_limits<float>::infinity();
}

TEST(FastAtan2, MatchesStdAtan2InAllQuadrants)
{
  double worst = 0.0;
  for (double a = -M_PI; a <= M_PI; a += 0.0007)
    for (double r : {1e-3, 1.0, 250.0})
    {
      const float x = static_cast<float>(r * std::cos(a)), y = static_cast<float>(r * std::sin(a));
      worst = std::max(worst, std::fabs(static_cast<double>(fastAtan2(y, x)) - std::atan2(y, x)));
    }
  EXPECT_LT(worst, 1e-5);
  EXPECT_EQ(fastAtan2(0.0f, 0.0f), 0.0f);
}

TEST(ScanProjector, ColumnBinsAreTheImageColumnsAtDefaults)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  Config cfg;
  cfg.projection = Projection::kColumn;
  cfg.geometry = Geometry::kThesis;
  ScanProjector p;
  p.configure(cam, cfg);
  EXPECT_EQ(p.beams(), 512);
  EXPECT_NEAR(p.angleIncrement(), 70.6 * M_PI / 180 / 512, 1e-7);
  // Thesis eq 4.21 is linear in the column: every column's edges fall on bin boundaries, right to left.
  std::vector<float> buf(513);
  const float* fb = p.rowEdgeBins(0, buf.data());
  for (int e = 0; e <= 512; ++e)
    EXPECT_NEAR(fb[e], 512 - e, 1e-3) << e;
  // eq 4.21 puts angle 0 on column w/2 = 256, half a pixel right of the image centre: the scan is shifted.
  EXPECT_NEAR(p.angleMax() + p.angleMin(), p.angleIncrement(), 1e-6);
}

TEST(ScanProjector, HorizontalEdgesAreMonotoneAndCoverTheScan)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  Config cfg;
  ScanProjector p;
  p.configure(cam, cfg);
  for (double pitch : {0.0, 0.26, 0.6})
  {
    p.setPose(pitch, 0.035);
    std::vector<float> buf(513);
    for (int r = 0; r < 424; r += 9)
    {
      const float* fb = p.rowEdgeBins(r, buf.data());
      for (int e = 1; e <= 512; ++e)
        ASSERT_LT(fb[e], fb[e - 1]) << "row " << r << " edge " << e;  // angle decreases to the right
    }
    float lo, hi;
    p.coverage(lo, hi);
    EXPECT_LE(lo, 0.5f);
    EXPECT_GE(hi, 511.5f);
  }
}

TEST(Confidence, RollingMeanWithAbsoluteValue)
{
  Config cfg;
  cfg.confidence_window = 3;
  cfg.confidence_distance = 0.5;
  Confidence c;
  c.configure(1, cfg);
  std::vector<float> r, i;
  auto push = [&](float d) {
    r = {d};
    c.apply(r, i);
    return i[0];
  };
  EXPECT_FLOAT_EQ(push(2.0f), 1.0f);                 // first sight: mean = itself
  EXPECT_FLOAT_EQ(push(2.0f), 1.0f);
  EXPECT_NEAR(push(2.6f), 1.0f - 0.4f / 0.5f, 1e-5);  // mean(2, 2, 2.6) = 2.2, |2.6 - 2.2| = 0.4
  EXPECT_NEAR(push(1.8f), 1.0f - (6.4f / 3.0f - 1.8f) / 0.5f, 1e-5);  // window (2, 2.6, 1.8): oldest 2 gone
  EXPECT_FLOAT_EQ(push(0.2f), 0.0f);                 // clamped at 0, never negative
}

TEST(Confidence, BeamAppearingOutOfInfinityIsTrustedAndNonFiniteHandled)
{
  Config cfg;
  cfg.confidence_window = 4;
  cfg.confidence_distance = 0.3;
  cfg.intensity_filter = true;
  cfg.min_intensity = 0.2;
  Confidence c;
  c.configure(3, cfg);
  std::vector<float> r = {kInf, kInf, kInf}, i;
  c.apply(r, i);
  EXPECT_EQ(i, (std::vector<float>{1.0f, 1.0f, 1.0f}));
  r = {1.5f, -kInf, std::numeric_limits<float>::quiet_NaN()};
  c.apply(r, i);
  EXPECT_FLOAT_EQ(i[0], 1.0f);  // the window's only finite range is this one
  EXPECT_FLOAT_EQ(r[0], 1.5f);  // so the filter keeps it
  EXPECT_FLOAT_EQ(i[1], 1.0f);
  EXPECT_FLOAT_EQ(i[2], 0.0f);
  EXPECT_TRUE(std::isinf(r[1]));
  // A jump far from the beam's mean is filtered to NaN; the +Inf beams are never filtered.
  r = {0.5f, kInf, kInf};
  c.apply(r, i);
  EXPECT_LE(i[0], 0.2f);
  EXPECT_TRUE(std::isnan(r[0]));
  EXPECT_TRUE(std::isinf(r[1]));
}

TEST(Confidence, WithoutFilterRangesAreUntouched)
{
  Config cfg;
  Confidence c;
  c.configure(2, cfg);
  std::vector<float> r = {1.0f, 2.0f}, i;
  c.apply(r, i);
  r = {5.0f, 2.0f};
  c.apply(r, i);
  EXPECT_FLOAT_EQ(r[0], 5.0f);
  EXPECT_FLOAT_EQ(i[0], 0.0f);
  c.reset();
  c.apply(r, i);
  EXPECT_FLOAT_EQ(i[0], 1.0f);
}
