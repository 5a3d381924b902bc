#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/model/threshold_curve.h"

using namespace kinect_pipeline;

TEST(SensorModel, KinectV2IsTodaysDefault)
{
  const std::vector<CurvePoint> want = {{0.5, 0.027}, {1.0, 0.030}, {1.5, 0.037}, {2.0, 0.049}, {2.5, 0.064},
                                        {3.0, 0.085}, {3.5, 0.109}, {4.0, 0.138}, {5.0, 0.208}, {6.0, 0.295},
                                        {8.0, 0.521}, {10.0, 0.815}, {12.0, 1.178}};
  const Config c;
  ASSERT_EQ(c.threshold_curve.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i)
  {
    EXPECT_EQ(c.threshold_curve[i].depth, want[i].depth);
    EXPECT_EQ(c.threshold_curve[i].threshold, want[i].threshold) << i;
  }
  Config k;
  applySensorModel("kinect_v2", k);
  EXPECT_EQ(formatThresholdCurve(k.threshold_curve), formatThresholdCurve(c.threshold_curve));
  EXPECT_EQ(k.range_max, c.range_max);
  EXPECT_EQ(k.cliff_min_pixels, c.cliff_min_pixels);
  EXPECT_EQ(sensorModels().front().name, kDefaultSensorModel);
}

TEST(SensorModel, EveryCurveIsValidAndFollowsItsNoise)
{
  for (const SensorModel& m : sensorModels())
  {
    SCOPED_TRACE(m.name);
    const std::vector<CurvePoint> curve = m.thresholdCurve();
    EXPECT_NO_THROW(validateThresholdCurve(curve));
    for (const CurvePoint& p : curve)  // within a millimetre of margin + k sigma + steps (the rounding)
      EXPECT_NEAR(p.threshold, m.noise.threshold(p.depth), 0.0011);
    EXPECT_GT(m.noise.sigma(4.0), m.noise.sigma(1.0)) << "noise grows with depth";
    EXPECT_NO_THROW(m.camera.validate());
    EXPECT_GE(m.cliffMinPixels(), 3);
    EXPECT_GT(m.range_max, 1.0);
    Config c;
    applySensorModel(m.name, c);
    EXPECT_NO_THROW(c.validate());
  }
}

TEST(SensorModel, StructuredLightIsWiderAtRangeThanTheKinectV2)
{
  // Disparity sensors lose depth resolution with z^2: at 4 m a Kinect v1 floor is noisier than a Kinect v2's.
  EXPECT_GT(evaluateCurve(sensorModel("kinect_v1").thresholdCurve(), 4.0),
            evaluateCurve(sensorModel("kinect_v2").thresholdCurve(), 4.0));
  EXPECT_NEAR(sensorModel("kinect_v1").noise.step2 * 16.0, 0.046, 0.001);  // Khoshelham 2012: 4.6 cm at 4 m
}

TEST(SensorModel, ExplicitFieldsWinAndUnknownNamesAreNamed)
{
  Config c;
  c.range_max = 7.5;
  applySensorModel("realsense_d4xx", c, {"range_max"});
  EXPECT_EQ(c.range_max, 7.5);
  EXPECT_EQ(formatThresholdCurve(c.threshold_curve), formatThresholdCurve(sensorModel("realsense_d4xx").thresholdCurve()));
  try
  {
    sensorModel("kinect_v3");
    FAIL() << "no exception";
  }
  catch (const std::invalid_argument& e)
  {
    const std::string m = e.what();
    EXPECT_NE(m.find("'kinect_v3'"), std::string::npos) << m;
    for (const SensorModel& s : sensorModels())
      EXPECT_NE(m.find(s.name), std::string::npos) << m;
  }
}
