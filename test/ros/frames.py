"""Orientations the ROS tests publish (tf of the optical frame, IMU attitudes): one place for test_node.py and
feeder.py, which run as scripts from this folder."""

from __future__ import annotations

import math

import numpy as np
from geometry_msgs.msg import Quaternion


def quaternion_from_matrix(m: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (its upper-left 3x3)."""
    r = m[:3, :3]
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2
    y = math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2
    z = math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2
    x = math.copysign(x, r[2, 1] - r[1, 2])
    y = math.copysign(y, r[0, 2] - r[2, 0])
    z = math.copysign(z, r[1, 0] - r[0, 1])
    return x, y, z, w


def optical_quaternion(pitch: float, roll: float = 0.0) -> Quaternion:
    """The optical frame's orientation in base_footprint for a sensor pitched down by ``pitch``, rolled by ``roll``."""
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    body_from_optical = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]])  # optical axes in the body frame
    x, y, z, w = quaternion_from_matrix(ry @ rx @ body_from_optical)
    return Quaternion(x=x, y=y, z=z, w=w)
