"""Pose calibration from frames of a flat floor: ``kinect-pipeline calibrate FILE... --intrinsics FX FY CX CY``.

The plane search and fit are the C++ core's (``calibrate_from_floor``); this module loads frames and reports."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import _core


class CalibrationError(ValueError):
    """A frame that cannot be read or used; the message names it."""


def load_depth(path: Path, depth_scale: float = 0.001, max_depth: float = 12.0) -> np.ndarray:
    """A depth frame as float32 metres (0 = unknown): 16-bit PNG/PGM (``depth_scale`` metres per unit, mm by
    default), 8-bit PNG (normalised with ``max_depth``), or .npy (float metres, uint16 mm, uint8 normalised)."""
    path = Path(path)
    if not path.exists():
        raise CalibrationError(f"{path}: no such file")
    if path.suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise CalibrationError(f"{path}: not a numpy array file ({exc})") from exc
        scale = {np.dtype(np.uint16): depth_scale, np.dtype(np.uint8): max_depth / 255.0}
    else:
        import cv2

        arr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if arr is None:
            raise CalibrationError(f"{path}: not an image OpenCV can read")
        scale = {np.dtype(np.uint16): depth_scale, np.dtype(np.uint8): max_depth / 255.0}
    if arr.ndim != 2:
        raise CalibrationError(f"{path}: shape {arr.shape}: expected a single-channel depth image")
    if arr.dtype in scale:
        metres = arr.astype(np.float32) * np.float32(scale[arr.dtype])
        if arr.dtype == np.uint8:
            metres[arr < 2] = 0.0
    elif arr.dtype.kind == "f":
        metres = arr.astype(np.float32)
    else:
        raise CalibrationError(f"{path}: dtype {arr.dtype}: expected uint16 (mm), uint8 (normalised) or float (m)")
    metres[~np.isfinite(metres)] = 0.0
    return np.ascontiguousarray(metres)


@dataclass
class Calibration:
    found: bool
    height: float
    pitch: float
    roll: float
    floor_fraction: float
    height_std: float
    pitch_std: float
    roll_std: float
    frames: list[dict[str, Any]]
    message: str = ""

    def as_dict(self, parent: str = "base_footprint", child: str = "kinect2_depth_optical_frame") -> dict[str, Any]:
        d: dict[str, Any] = {
            "found": self.found,
            "height": self.height,
            "pitch": self.pitch,
            "roll": self.roll,
            "floor_fraction": self.floor_fraction,
            "height_std": self.height_std,
            "pitch_std": self.pitch_std,
            "roll_std": self.roll_std,
            "pitch_deg": math.degrees(self.pitch),
            "roll_deg": math.degrees(self.roll),
            "frames": self.frames,
        }
        if self.message:
            d["message"] = self.message
        if self.found:
            d["launch_args"] = f"sensor_height:={self.height:.4f} sensor_pitch:={self.pitch:.5f} pose_source:=static"
            d["yaml"] = {
                "sensor_height": round(self.height, 4),
                "sensor_pitch": round(self.pitch, 5),
                "sensor_roll": round(self.roll, 5),
            }
            q = optical_quaternion(self.pitch, self.roll)
            d["static_transform"] = (
                f"rosrun tf2_ros static_transform_publisher 0 0 {self.height:.4f} "
                f"{q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f} {parent} {child}"
            )
        return d


def optical_quaternion(pitch: float, roll: float) -> tuple[float, float, float, float]:
    """The optical frame's orientation (x, y, z, w) in a z-up base frame for a sensor at pitch / roll."""
    body = (tuple(_core.quaternion_from_rpy(roll, pitch, 0.0)), (0.0, 0.0, 0.0))
    optical = _core.compose_transforms(body, ((-0.5, 0.5, -0.5, 0.5), (0.0, 0.0, 0.0)))
    q = optical[0]
    return (q[0], q[1], q[2], q[3])


def calibrate(frames: list[tuple[str, np.ndarray]], camera: _core.Camera, **options: Any) -> Calibration:
    """Calibrates from one or more (name, metres) frames; several frames give a mean and a spread."""
    per: list[dict[str, Any]] = []
    for name, metres in frames:
        if metres.shape != (camera.height, camera.width):
            raise CalibrationError(
                f"{name}: {metres.shape[1]}x{metres.shape[0]} but the intrinsics are for "
                f"{camera.width}x{camera.height} (give --size W H if the principal point is off)"
            )
        r = dict(_core.calibrate_from_floor(metres, camera, **options))
        r["file"] = name
        per.append(r)
    good = [r for r in per if r["found"]]
    if not good:
        return Calibration(
            False,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            per,
            f"no floor found in {len(per)} frame(s): no plane facing up with enough pixels",
        )
    w = np.array([r["floor_pixels"] for r in good], float)

    def mean(key: str) -> float:
        return float(np.average([r[key] for r in good], weights=w))

    def spread(key: str) -> float:
        fit = float(np.sqrt(np.mean([r[f"{key}_std"] ** 2 for r in good])) / math.sqrt(len(good)))
        between = float(np.std([r[key] for r in good], ddof=1) / math.sqrt(len(good))) if len(good) > 1 else 0.0
        return max(fit, between)

    return Calibration(
        True,
        mean("height"),
        mean("pitch"),
        mean("roll"),
        mean("floor_fraction"),
        spread("height"),
        spread("pitch"),
        spread("roll"),
        per,
    )
