/**
 * @file pose.h
 * @brief Rigid transforms (quaternion + translation) and the sensor pose they give, without ROS.
 *
 * The ROS node (through tf2) and the offline tools (through a bag's /tf) both get the sensor's pose here.
 */
#pragma once

#include <array>

#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{

/** A rigid transform: p_parent = R(q) * p_child + t. */
struct RigidTransform
{
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};  ///< rotation quaternion (x, y, z, w), normalised on use
  std::array<double, 3> t{0.0, 0.0, 0.0};       ///< translation [m]

  /** @return this * other (first other, then this): parent <- this.child == other.parent <- other.child. */
  RigidTransform operator*(const RigidTransform& other) const;
  /** @return the inverse transform. */
  RigidTransform inverse() const;
  /** @return rotation matrix, row-major. */
  std::array<double, 9> matrix() const;
};

/** @return a transform between @p a (f = 0) and @p b (f = 1): linear translation, spherical rotation. */
RigidTransform interpolate(const RigidTransform& a, const RigidTransform& b, double f);

/** @return the quaternion (x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll) (the inverse of rollPitchYaw()). */
std::array<double, 4> quaternionFromRpy(double roll, double pitch, double yaw);

/** @return roll, pitch, yaw [rad] (fixed axes x, y, z; R = Rz(yaw) Ry(pitch) Rx(roll), as tf2's getRPY). */
std::array<double, 3> rollPitchYaw(const std::array<double, 4>& q);

/**
 * @brief The sensor's pose relative to the floor from its optical frame's transform in a gravity-aligned base
 *        frame (REP 103 optical frame: x right, y down, z forward).
 * @param base_frame_height height of the base frame's origin above the floor [m]
 * @param[out] yaw heading of the sensor in the base frame [rad]
 */
SensorPose poseFromOpticalTransform(const RigidTransform& base_from_optical, double base_frame_height, double& yaw);

/**
 * @brief Where the gravity-aligned frame at the sensor lies in its optical frame: the transform optical <- level
 *        (no translation), the level frame being x along the sensor's heading, y left, z up (the LaserScan's frame).
 * @param pose the sensor's pitch (+ looks down) and roll (+ right side down) [rad]; the height is not used
 */
RigidTransform opticalFromLevel(const SensorPose& pose);

/**
 * Rolls within this of 0 or of +-pi [rad] count as exactly 0 or +-pi (levelFromOptical). A level mount's roll as tf
 * composes it from a URDF (the optical frame's fixed rotation after the mount's pitch) is up to 3e-16 rad, not
 * 0, and rotations kept in single precision leave about 1e-7; any roll that is not 0 or +-pi costs a frame the level
 * paths (about twice the time). 1e-6 rad moves the floor by a micrometre per metre to the side, a thousandth of a
 * 16-bit depth unit.
 */
constexpr double kRollSnap = 1e-6;

/**
 * @brief The rotation of the sensor's optical frame (x right, y down, z forward) into the gravity-aligned frame at
 *        the sensor (x forward along the heading, y left, z up): the one place it is written out. The optical ray
 *        (xn, yn, 1) is (1, -xn, -yn) in the sensor's x-forward, z-up frame; then roll about x, then pitch about y
 *        (+ looks down): R = Ry(pitch) Rx(roll) S.
 * @param pitch [rad], + looks down; @param roll [rad], + right side down (within kRollSnap of 0 or +-pi: exactly that)
 * @return R row-major: a level-frame vector is R times the optical one; row 2 (R[6..8]) is "up" seen in the
 *         optical frame, column 2 (R[2], R[5], R[8]) the optical axis in the level frame
 */
std::array<double, 9> levelFromOptical(double pitch, double roll);

/**
 * @brief The up direction in the optical frame (a unit floor normal pointing at the camera) as pitch and roll.
 * @param n unit normal (x right, y down, z forward)
 */
void pitchRollFromUp(const double n[3], double& pitch, double& roll);

}  // namespace kinect_pipeline
