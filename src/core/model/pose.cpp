// Poses from transforms and IMU attitudes (REP 103/105 frames): docs/how_it_works.md and docs/ros_node.md, "Fallbacks".
#include "kinect_pipeline/model/pose.h"

#include <algorithm>
#include <cmath>

namespace kinect_pipeline
{
namespace
{
using Q = std::array<double, 4>;

Q normalised(const Q& q)
{
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  return n > 0.0 ? Q{q[0] / n, q[1] / n, q[2] / n, q[3] / n} : Q{0.0, 0.0, 0.0, 1.0};
}

Q multiply(const Q& a, const Q& b)
{
  return {a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1], a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0],
          a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3], a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2]};
}

std::array<double, 3> rotate(const std::array<double, 9>& m, const std::array<double, 3>& v)
{
  return {m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
          m[6] * v[0] + m[7] * v[1] + m[8] * v[2]};
}
}  // namespace

std::array<double, 9> RigidTransform::matrix() const
{
  const Q n = normalised(q);
  const double x = n[0], y = n[1], z = n[2], w = n[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),
          2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
          2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y)};
}

RigidTransform RigidTransform::operator*(const RigidTransform& o) const
{
  RigidTransform r;
  r.q = normalised(multiply(normalised(q), normalised(o.q)));
  const auto rt = rotate(matrix(), o.t);
  r.t = {rt[0] + t[0], rt[1] + t[1], rt[2] + t[2]};
  return r;
}

RigidTransform RigidTransform::inverse() const
{
  RigidTransform r;
  const Q n = normalised(q);
  r.q = {-n[0], -n[1], -n[2], n[3]};
  const auto rt = rotate(r.matrix(), t);
  r.t = {-rt[0], -rt[1], -rt[2]};
  return r;
}

RigidTransform interpolate(const RigidTransform& a, const RigidTransform& b, double f)
{
  RigidTransform r;
  for (int i = 0; i < 3; ++i)
    r.t[i] = a.t[i] + f * (b.t[i] - a.t[i]);
  Q qa = normalised(a.q), qb = normalised(b.q);
  double dot = qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3];
  if (dot < 0.0)
  {
    for (double& c : qb)
      c = -c;
    dot = -dot;
  }
  if (dot > 0.9995)
  {
    for (int i = 0; i < 4; ++i)
      r.q[i] = qa[i] + f * (qb[i] - qa[i]);
    r.q = normalised(r.q);
    return r;
  }
  const double th = std::acos(dot), s = std::sin(th);
  const double wa = std::sin((1 - f) * th) / s, wb = std::sin(f * th) / s;
  for (int i = 0; i < 4; ++i)
    r.q[i] = wa * qa[i] + wb * qb[i];
  return r;
}

std::array<double, 4> quaternionFromRpy(double roll, double pitch, double yaw)
{
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2), cp = std::cos(pitch / 2), sp = std::sin(pitch / 2),
               cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  return {sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
          cr * cp * cy + sr * sp * sy};
}

std::array<double, 3> rollPitchYaw(const std::array<double, 4>& q)
{
  RigidTransform t;
  t.q = q;
  const auto m = t.matrix();
  const double pitch = std::asin(std::max(-1.0, std::min(1.0, -m[6])));
  double roll, yaw;
  if (std::fabs(m[6]) < 1.0 - 1e-12)
  {
    roll = std::atan2(m[7], m[8]);
    yaw = std::atan2(m[3], m[0]);
  }
  else  // gimbal lock (looking straight down or up): put it all in yaw
  {
    roll = 0.0;
    yaw = std::atan2(-m[1], m[4]);
  }
  return {roll, pitch, yaw};
}

namespace
{
/** The sensor body (x forward, y left, z up) seen from the optical frame (x right, y down, z forward). */
RigidTransform opticalFromBody()
{
  RigidTransform optical_from_body;
  optical_from_body.q = {0.5, -0.5, 0.5, 0.5};
  return optical_from_body;
}
}  // namespace

SensorPose poseFromOpticalTransform(const RigidTransform& base_from_optical, double base_frame_height, double& yaw)
{
  RigidTransform base_from_body = base_from_optical * opticalFromBody();
  const auto rpy = rollPitchYaw(base_from_body.q);
  yaw = rpy[2];
  return SensorPose{base_from_optical.t[2] + base_frame_height, rpy[1], rpy[0]};
}

RigidTransform opticalFromLevel(const SensorPose& pose)
{
  // level <- body is the pitch and roll alone (the level frame carries the sensor's yaw).
  RigidTransform level_from_body;
  level_from_body.q = quaternionFromRpy(pose.roll, pose.pitch, 0.0);
  return opticalFromBody() * level_from_body.inverse();
}

std::array<double, 9> levelFromOptical(double pitch, double roll)
{
  // Level (roll within kRollSnap of 0) or upside down (of +-pi): sin exactly 0, not 1e-16, cos exactly 1 or -1. The
  // rows then have one rise each, and the frame takes the paths of a level mount (PlaneModel::oneRisePerRow, the
  // scan's rows without roll).
  const bool level = std::fabs(roll) <= kRollSnap, upside_down = std::fabs(std::fabs(roll) - kPi) <= kRollSnap;
  const double sp = std::sin(pitch), cp = std::cos(pitch), sr = level || upside_down ? 0.0 : std::sin(roll),
               cr = level ? 1.0 : upside_down ? -1.0 : std::cos(roll);
  return {-sp * sr, -sp * cr, cp,  //
          -cr, sr, 0.0,            //
          -cp * sr, -cp * cr, -sp};
}

void pitchRollFromUp(const double n[3], double& pitch, double& roll)
{
  pitch = std::asin(std::max(-1.0, std::min(1.0, -n[2])));
  roll = std::atan2(-n[0], -n[1]);
}

}  // namespace kinect_pipeline
