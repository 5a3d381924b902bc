#include <gtest/gtest.h>

#include <cmath>

#include "kinect_pipeline/model/pose.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
// Reference: quaternion from roll/pitch/yaw written out (R = Rz Ry Rx).
std::array<double, 4> quat(double r, double p, double y)
{
  const double cr = std::cos(r / 2), sr = std::sin(r / 2), cp = std::cos(p / 2), sp = std::sin(p / 2),
               cy = std::cos(y / 2), sy = std::sin(y / 2);
  return {sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
          cr * cp * cy + sr * sp * sy};
}
}  // namespace

TEST(Pose, QuaternionFromRpyIsTheReference)
{
  for (double r : {0.0, 0.3, -0.7})
    for (double p : {0.0, 0.26, -1.2})
      for (double y : {0.0, 2.0})
      {
        const auto a = quaternionFromRpy(r, p, y), b = quat(r, p, y);
        for (int i = 0; i < 4; ++i)
          EXPECT_NEAR(a[i], b[i], 1e-12);
      }
}

TEST(Pose, RollPitchYawRoundTrips)
{
  for (double r : {0.0, 0.3, -0.7})
    for (double p : {0.0, 0.26, -1.2})
      for (double y : {0.0, 2.0, -3.0})
      {
        const auto rpy = rollPitchYaw(quat(r, p, y));
        EXPECT_NEAR(rpy[0], r, 1e-9);
        EXPECT_NEAR(rpy[1], p, 1e-9);
        EXPECT_NEAR(rpy[2], y, 1e-9);
      }
}

TEST(Pose, ComposeInverseAndInterpolate)
{
  RigidTransform a, b;
  a.q = quat(0.1, 0.2, 0.3);
  a.t = {1.0, 2.0, 3.0};
  b.q = quat(-0.2, 0.1, 1.0);
  b.t = {-0.5, 0.25, 0.0};
  const RigidTransform ab = a * b;
  // A point through b then a, by matrices.
  const std::array<double, 3> p{0.3, -0.2, 0.9};
  const auto mb = b.matrix(), ma = a.matrix(), mab = ab.matrix();
  double q1[3], q2[3], q3[3];
  for (int i = 0; i < 3; ++i)
    q1[i] = mb[3 * i] * p[0] + mb[3 * i + 1] * p[1] + mb[3 * i + 2] * p[2] + b.t[i];
  for (int i = 0; i < 3; ++i)
    q2[i] = ma[3 * i] * q1[0] + ma[3 * i + 1] * q1[1] + ma[3 * i + 2] * q1[2] + a.t[i];
  for (int i = 0; i < 3; ++i)
    q3[i] = mab[3 * i] * p[0] + mab[3 * i + 1] * p[1] + mab[3 * i + 2] * p[2] + ab.t[i];
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(q2[i], q3[i], 1e-12);
  const RigidTransform id = a * a.inverse();
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(id.t[i], 0.0, 1e-12);
  EXPECT_NEAR(std::fabs(id.q[3]), 1.0, 1e-12);
  const RigidTransform half = interpolate(a, b, 0.5);
  EXPECT_NEAR(half.t[0], 0.25, 1e-12);
  EXPECT_NEAR(interpolate(a, b, 0.0).q[1], a.q[1], 1e-12);
  EXPECT_NEAR(std::fabs(interpolate(a, b, 1.0).q[3]), std::fabs(b.q[3]), 1e-9);
}

TEST(Pose, SensorPoseFromTheOpticalFrame)
{
  // The optical frame of a sensor with a known body pose, built with explicit matrices.
  for (double pitch : {0.0, 0.26, -0.4})
    for (double roll : {0.0, 0.035})
      for (double yaw : {0.0, 0.8})
      {
        RigidTransform body;
        body.q = quat(roll, pitch, yaw);
        body.t = {0.2, 0.0, 1.1};
        RigidTransform body_from_optical;
        body_from_optical.q = {-0.5, 0.5, -0.5, 0.5};
        double got_yaw;
        const SensorPose p = poseFromOpticalTransform(body * body_from_optical, 0.1, got_yaw);
        EXPECT_NEAR(p.height, 1.2, 1e-12);
        EXPECT_NEAR(p.pitch, pitch, 1e-9);
        EXPECT_NEAR(p.roll, roll, 1e-9);
        EXPECT_NEAR(got_yaw, yaw, 1e-9);
        // Cross-check with the test's own ray rotation: the optical axis rises by -sin(pitch) per metre.
        const auto m = (body * body_from_optical).matrix();
        EXPECT_NEAR(m[8], kp_test::rayWorld(kinect_pipeline::Camera(3, 3, 1, 1, 1, 1), 1, 1, pitch, roll).z, 1e-9);
      }
}

TEST(Pose, LevelFrameInTheOpticalFrame)
{
  // The level frame at the sensor (the scan's frame) seen from the optical frame: its z is the world's up, its x
  // the sensor's heading, whatever the pitch and roll; the test builds the optical axes from explicit matrices.
  for (double pitch : {0.0, 0.26, -0.4})
    for (double roll : {0.0, 0.035, -0.2})
    {
      const auto m = opticalFromLevel(SensorPose{1.1, pitch, roll}).matrix();  // row-major optical <- level
      const double cp = std::cos(pitch), sp = std::sin(pitch), cr = std::cos(roll), sr = std::sin(roll);
      // Up (0, 0, 1) of the level frame in optical coordinates (x right, y down, z forward): a sensor looking down
      // sees up behind its optical axis (z < 0), one rolled right side down sees it to its left (x < 0).
      const double up[3] = {-sr * cp, -cr * cp, -sp};
      // The heading (1, 0, 0), forward and level: above the optical axis (y < 0) of a sensor looking down.
      const double fwd[3] = {-sr * sp, -cr * sp, cp};
      for (int i = 0; i < 3; ++i)
      {
        EXPECT_NEAR(m[3 * i + 2], up[i], 1e-9) << "pitch " << pitch << " roll " << roll << " row " << i;
        EXPECT_NEAR(m[3 * i + 0], fwd[i], 1e-9) << "pitch " << pitch << " roll " << roll << " row " << i;
      }
      // And poseFromOpticalTransform reads the same pose back from base <- optical = (optical <- level)^-1.
      double yaw = 1.0;
      RigidTransform base_from_optical = opticalFromLevel(SensorPose{1.1, pitch, roll}).inverse();
      base_from_optical.t = {0.0, 0.0, 1.1};
      const SensorPose back = poseFromOpticalTransform(base_from_optical, 0.0, yaw);
      EXPECT_NEAR(back.pitch, pitch, 1e-9);
      EXPECT_NEAR(back.roll, roll, 1e-9);
      EXPECT_NEAR(yaw, 0.0, 1e-9);
    }
}
