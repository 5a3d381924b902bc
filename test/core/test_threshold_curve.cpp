#include <gtest/gtest.h>

#include <algorithm>

#include "kinect_pipeline/model/threshold_curve.h"
#include "test_util.h"

using kp_test::slowCurve;

using namespace kinect_pipeline;


TEST(ThresholdCurve, InterpolatesLikeTheReference)
{
  const std::vector<CurvePoint> c = {{0.5, 0.02}, {1.0, 0.03}, {4.0, 0.2}, {8.0, 0.6}};
  for (double d = 0.0; d < 10.0; d += 0.01)
    EXPECT_NEAR(evaluateCurve(c, d), slowCurve(c, d), 1e-12) << d;
}

TEST(ThresholdLut, EightBitIndexedByValueNeverBelowOneStep)
{
  const auto c = defaultThresholdCurve();
  ThresholdLut lut;
  lut.build(c, Encoding::kMono8, 12.0);
  ASSERT_EQ(lut.table().size(), 256u);
  const double step = 12.0 / 255.0;
  for (int v = 0; v < 256; ++v)
  {
    EXPECT_GE(lut.forValue(static_cast<std::uint8_t>(v)), static_cast<float>(step) * 0.9999f);
    EXPECT_NEAR(lut.forValue(static_cast<std::uint8_t>(v)), std::max(slowCurve(c, (v + 0.5) * step), step), 1e-6);
  }
}

TEST(ThresholdLut, MillimetreTableIsTheDepthTableForEverySixteenBitValue)
{
  ThresholdLut lut;
  lut.build({{0.5, 0.004}, {2.0, 0.02}, {9.0, 0.31}}, Encoding::kMono16, 12.0);
  int differ = 0;
  for (int v = 0; v < 65536; ++v)
    differ += lut.forMillimetres(static_cast<std::uint16_t>(v)) != lut.forDepth(static_cast<float>(v) * 0.001f);
  EXPECT_EQ(differ, 0);
  EXPECT_FLOAT_EQ(lut.forMillimetres(65535), 0.31f);  // beyond the table: its last cell
  EXPECT_GT(lut.forMillimetres(3000), lut.forMillimetres(1000));
}

TEST(ThresholdLut, DepthTableIsTheCurveAtCentimetreCells)
{
  const auto c = defaultThresholdCurve();
  for (Encoding e : {Encoding::kMono16, Encoding::kFloat32})
  {
    ThresholdLut lut;
    lut.build(c, e, 12.0);
    for (double d = 0.0; d < 14.0; d += 0.0037)
    {
      const double ref = std::max(slowCurve(c, d), encodingStep(e, 12.0));
      // The cell's value is the curve at the cell's far end: never below, at most 1 cm of slope above.
      EXPECT_GE(lut.forDepth(static_cast<float>(d)), ref - 1e-6) << d;
      EXPECT_LE(lut.forDepth(static_cast<float>(d)), slowCurve(c, d + 0.0101) + 1e-6) << d;
    }
    // Out-of-range depths clamp to the ends instead of reading outside the table.
    EXPECT_FLOAT_EQ(lut.forDepth(1e30f), static_cast<float>(c.back().threshold));
    EXPECT_FLOAT_EQ(lut.forDepth(std::numeric_limits<float>::infinity()), static_cast<float>(c.back().threshold));
    EXPECT_FLOAT_EQ(lut.forDepth(-3.0f), lut.table().front());
  }
}
