"""The simulated Segway: where its sensors sit (:class:`Rig`) and how its base pitches while it drives
(:class:`SegwayMotion`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

AXLE_HEIGHT = 0.24  #: wheel axle above the floor [m]


@dataclass
class Rig:
    """Where the sensors sit on the robot."""

    kinect_xyz: tuple[float, float, float] = (0.10, 0.0, 0.86)  #: kinect2_link in base_link (axle) [m]
    kinect_tilt: float = math.radians(15.0)  #: kinect2_link pitch in base_link [rad], + looks down
    lidar_height: float = 0.30  #: LiDAR plane above the floor [m]
    camera_ns: str = "/kinect2"
    image_topic: str = "/kinect2/sd/image_depth"
    info_topic: str = "/kinect2/sd/camera_info"
    lidar_topic: str = "/scan_lidar"
    optical_frame: str = "kinect2_depth_optical_frame"
    extra: dict[str, Any] = field(default_factory=dict)

    def sensor_pose(self, base_pitch: float) -> tuple[float, float, float, float]:
        """(x, z, total pitch, height above the floor) of the optical centre in base_footprint for a base pitched
        by ``base_pitch`` about the wheel axle (base_link's origin)."""
        x, _, z = self.kinect_xyz
        c, s = math.cos(base_pitch), math.sin(base_pitch)
        px = c * x + s * z
        pz = AXLE_HEIGHT - s * x + c * z
        return px, pz, self.kinect_tilt + base_pitch, pz


@dataclass
class SegwayMotion:
    """Base pitch of a Segway driving: a slow oscillation plus a jerk (a sudden stop) [rad]."""

    amplitude: float = math.radians(4.0)
    period_frames: float = 45.0
    jerk_frame: int = 20
    jerk: float = math.radians(6.0)

    def pitch(self, i: int) -> float:
        p = self.amplitude * math.sin(2 * math.pi * i / self.period_frames)
        if i >= self.jerk_frame:
            p += self.jerk * math.exp(-(i - self.jerk_frame) / 3.0) * math.cos((i - self.jerk_frame) * 1.3)
        return max(-math.radians(6.0), min(math.radians(6.0), p))
