"""kinect_pipeline: depth frames -> floor/ceiling-free depth image and a LaserScan, on a pitching base.

The math lives in the C++ core (``kinect_pipeline._core``); this package re-exports it and adds tools.

>>> import kinect_pipeline as kp
>>> cam = kp.Camera.from_fov(512, 424, 1.232, 1.047)
>>> pipe = kp.Pipeline(cam, kp.Config(sensor_height=1.1, sensor_pitch=0.26))
"""

from __future__ import annotations

from typing import Any

from . import _core
from ._core import (
    Camera,
    Config,
    DepthRectifier,
    Pipeline,
    Result,
    add_kinect_noise,
    decode_compressed_depth,
    default_threshold_curve,
    encode_compressed_depth,
    encode_depth,
    evaluate_curve,
    morph_open,
    render_scene,
    restrict_simd,
    sensor_model,
    sensor_models,
    simd_target,
    simd_targets,
    threshold_lut,
)

#: Values of ``Result.labels`` by name (the core's list).
LABELS: dict[str, int] = dict(_core.LABELS)

#: The core's table of Config fields (model/config_table.h): name, kind, min, max, unit, doc, choices, default.
CONFIG_FIELDS: list[dict[str, Any]] = [dict(f) for f in _core.CONFIG_FIELDS]

#: Kinect v2 depth camera (512x424, 70.6 x 60 deg, as in the thesis).
KINECT_V2_HFOV = 1.2322
KINECT_V2_VFOV = 1.0472

__all__ = [
    "CONFIG_FIELDS",
    "KINECT_V2_HFOV",
    "KINECT_V2_VFOV",
    "LABELS",
    "Camera",
    "Config",
    "DepthRectifier",
    "Pipeline",
    "Result",
    "add_kinect_noise",
    "decode_compressed_depth",
    "default_threshold_curve",
    "encode_compressed_depth",
    "encode_depth",
    "evaluate_curve",
    "kinect_v2_camera",
    "morph_open",
    "render_scene",
    "restrict_simd",
    "sensor_model",
    "sensor_models",
    "simd_target",
    "simd_targets",
    "threshold_lut",
]


def kinect_v2_camera() -> Camera:
    """The thesis's Kinect v2 model: 512x424 pixels, 70.6 x 60 degrees."""
    return Camera.from_fov(512, 424, KINECT_V2_HFOV, KINECT_V2_VFOV)
