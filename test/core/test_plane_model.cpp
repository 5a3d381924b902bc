#include <gtest/gtest.h>

#include <cmath>

#include "kinect_pipeline/model/plane_model.h"
#include "kinect_pipeline/model/pose.h"
#include "test_util.h"

using namespace kinect_pipeline;
using kp_test::kInf;

namespace
{
Camera kinect() { return Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180); }

void expectDepthNear(double got, double want, int u, int r)
{
  if (std::isinf(want))
    EXPECT_TRUE(std::isinf(got) || got > 1e4) << "u=" << u << " r=" << r << " got " << got;
  else
    EXPECT_NEAR(got, want, 1e-4 * want * want + 1e-5) << "u=" << u << " r=" << r;  // float terms
}
}  // namespace

class ExactPlanes : public ::testing::TestWithParam<std::tuple<double, double>>
{
};

TEST_P(ExactPlanes, MatchRayPlaneIntersection)
{
  const auto [pitch, roll] = GetParam();
  const Camera cam = kinect();
  Config cfg;
  cfg.sensor_height = 1.1;
  cfg.ceiling_height = 2.0;
  PlaneModel m;
  ASSERT_TRUE(m.update(cam, cfg, cfg.sensor_height, pitch, roll));
  for (int r = 0; r < cam.height; r += 7)
    for (int u = 0; u < cam.width; u += 13)
    {
      expectDepthNear(m.floorDepth(u, r), kp_test::planeDepth(cam, u, r, 1.1, pitch, roll, 0.0), u, r);
      expectDepthNear(m.ceilingDepth(u, r), kp_test::planeDepth(cam, u, r, 1.1, pitch, roll, 2.0), u, r);
    }
  if (roll == 0.0)
  {
    // Without roll the prediction is the same along a row.
    for (int r = 0; r < cam.height; r += 11)
      EXPECT_DOUBLE_EQ(m.floorDepth(0, r), m.floorDepth(cam.width - 1, r));
  }
  // Unchanged pose: nothing recomputed.
  EXPECT_FALSE(m.update(cam, cfg, cfg.sensor_height, pitch, roll));
}

INSTANTIATE_TEST_SUITE_P(Poses, ExactPlanes,
                         ::testing::Values(std::make_tuple(0.0, 0.0), std::make_tuple(0.26, 0.0),
                                           std::make_tuple(0.26 + 0.1, 0.035), std::make_tuple(-0.2, -0.035),
                                           std::make_tuple(M_PI / 2, 0.0), std::make_tuple(-M_PI / 2, 0.0),
                                           std::make_tuple(0.8, 0.3)));

// A level mount as tf gives it (a URDF's pitched camera_link, then the optical frame's fixed rotation) has a roll of
// a few 1e-16 rad, not 0: it must keep the level paths (one rise per row), as an exact 0 does; a real roll not.
TEST(PlaneModel, ARollLeftByComposingRotationsKeepsTheLevelPaths)
{
  const Camera cam = kinect();
  Config cfg;
  int rounded = 0;
  for (double mount_pitch : {0.0, 0.1, 0.26, 0.2617993877991494, 0.35, 0.5, -0.2})
    for (double base_pitch : {0.0, 0.01, -0.05})
    {
      RigidTransform base_from_link, link_from_optical;
      base_from_link.q = quaternionFromRpy(0.0, base_pitch, 0.0);
      RigidTransform link_from_camera;
      link_from_camera.q = quaternionFromRpy(0.0, mount_pitch, 0.0);
      link_from_camera.t = {0.2, 0.0, 1.0};
      link_from_optical.q = quaternionFromRpy(-M_PI / 2, 0.0, -M_PI / 2);
      double yaw = 0.0;
      const SensorPose pose = poseFromOpticalTransform(base_from_link * link_from_camera * link_from_optical, 0.0, yaw);
      ASSERT_LT(std::fabs(pose.roll), 1e-15) << mount_pitch << " " << base_pitch;
      rounded += pose.roll != 0.0;
      EXPECT_EQ(levelFromOptical(pose.pitch, pose.roll), levelFromOptical(pose.pitch, 0.0));
      PlaneModel m;
      ASSERT_TRUE(m.update(cam, cfg, pose.height, pose.pitch, pose.roll));
      EXPECT_TRUE(m.oneRisePerRow()) << "pitch " << pose.pitch << " roll " << pose.roll;
    }
  EXPECT_GT(rounded, 0);  // the composition did leave rolls that are not 0
  for (double roll : {kRollSnap, -kRollSnap, M_PI - 0.5 * kRollSnap, -M_PI + 1e-9, M_PI})
  {
    PlaneModel m;
    ASSERT_TRUE(m.update(cam, cfg, 1.1, 0.26, roll));
    EXPECT_TRUE(m.oneRisePerRow()) << "roll " << roll;
    EXPECT_EQ(levelFromOptical(0.26, roll), levelFromOptical(0.26, std::fabs(roll) < 1.0 ? 0.0 : M_PI));
  }
  for (double roll : {2 * kRollSnap, -1e-5, 0.001, M_PI - 2 * kRollSnap, 2 * M_PI - 1e-9})
  {
    PlaneModel m;
    ASSERT_TRUE(m.update(cam, cfg, 1.1, 0.26, roll));
    EXPECT_FALSE(m.oneRisePerRow()) << "roll " << roll;
  }
}

TEST(PlaneModel, StraightDownSeesFloorEverywhereAndNoCeiling)
{
  const Camera cam = kinect();
  Config cfg;
  PlaneModel m;
  m.update(cam, cfg, cfg.sensor_height, M_PI / 2, 0.0);
  for (int r = 0; r < cam.height; r += 5)
    for (int u = 0; u < cam.width; u += 5)
    {
      EXPECT_TRUE(std::isfinite(m.floorDepth(u, r)));
      EXPECT_TRUE(std::isinf(m.ceilingDepth(u, r)));
    }
  EXPECT_NEAR(m.floorDepth(256, 212), cfg.sensor_height, 0.01);  // centre pixel looks at the floor below
}

TEST(PlaneModel, LevelCameraUpperRowsNeverMeetTheFloor)
{
  const Camera cam = kinect();
  Config cfg;
  PlaneModel m;
  m.update(cam, cfg, cfg.sensor_height, 0.0, 0.0);
  for (int r = 0; r <= 211; ++r)
    EXPECT_TRUE(std::isinf(m.floorDepth(100, r))) << r;
  for (int r = 212; r < cam.height; ++r)
    EXPECT_TRUE(std::isinf(m.ceilingDepth(100, r))) << r;
}

TEST(PlaneModel, ThesisModeReproducesEquations410To418)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.geometry = Geometry::kThesis;
  cfg.sensor_height = 1.1;
  cfg.ceiling_height = 2.0;
  const double pitch = 0.26;
  PlaneModel m;
  m.update(cam, cfg, cfg.sensor_height, pitch, 0.05);  // roll is ignored in thesis mode
  const double vfov = 60 * M_PI / 180;
  for (int r = 0; r < cam.height; ++r)
  {
    // eq 4.10: linear row angle; eq 4.13/4.14: m = tan(pitch), c = cos(pitch) * h; eq 4.18: z = c / (tan - m),
    // with the ray's angle measured downwards so that the floor is ahead for rows below the horizon.
    const double theta = (r - cam.height / 2.0) / cam.height * vfov;
    const double denom = std::tan(theta) + std::tan(pitch);
    const double zg = denom > 0 ? std::cos(pitch) * 1.1 / denom : kInf;
    const double zc = denom < 0 ? std::cos(pitch) * 2.0 / -denom : kInf;
    for (int u : {0, 255, 511})
    {
      expectDepthNear(m.floorDepth(u, r), zg, u, r);
      expectDepthNear(m.ceilingDepth(u, r), zc, u, r);
    }
  }
}

TEST(PlaneModel, ThesisIsAnApproximationOfExact)
{
  // At pitch 0 the intercepts agree exactly (cos 0 = 1) but the row angle does not; at a tilt the thesis
  // floor intercept h*cos(p) falls short of the exact h/cos(p).
  const Camera cam = kinect();
  Config exact, thesis;
  thesis.geometry = Geometry::kThesis;
  PlaneModel a, b;
  a.update(cam, exact, exact.sensor_height, 0.4, 0.0);
  b.update(cam, thesis, thesis.sensor_height, 0.4, 0.0);
  EXPECT_LT(b.floorDepth(256, 300), a.floorDepth(256, 300));
}
