"""Fuzzing the core through the binding: random shapes, dtypes, values, poses, curves and configs.

Every call either returns a well-formed result or raises TypeError / ValueError; nothing crashes. CI runs a short
run; for the long one: KP_FUZZ_EXAMPLES=100000 python3 -m pytest test/python/test_fuzz.py -q"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import kinect_pipeline as kp

EXAMPLES = int(os.environ.get("KP_FUZZ_EXAMPLES", "300"))
fuzz = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True)

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
anyfloat = st.floats(allow_nan=True, allow_infinity=True, width=64)
dtypes = st.sampled_from([np.uint8, np.uint16, np.float32, np.float64, np.int32, np.int16, np.bool_])


@st.composite
def frames(draw: st.DrawFn) -> tuple[np.ndarray, kp.Camera]:
    h, w = draw(st.integers(1, 24)), draw(st.integers(1, 24))
    dtype = draw(dtypes)
    arr = draw(hnp.arrays(dtype, (h, w), elements=None))
    if draw(st.booleans()):
        arr = arr[::-1]  # negative stride
    if draw(st.booleans()) and w > 1:
        arr = arr[:, ::2]  # column step
    cam = kp.Camera(
        arr.shape[1] if draw(st.booleans()) else draw(st.integers(1, 24)),
        arr.shape[0],
        draw(st.floats(1, 1000)),
        draw(st.floats(1, 1000)),
        draw(st.floats(-50, 50)),
        draw(st.floats(-50, 50)),
    )
    return arr, cam


@st.composite
def configs(draw: st.DrawFn) -> dict[str, object]:
    cfg: dict[str, object] = {}
    if draw(st.booleans()):
        cfg["sensor_height"] = draw(anyfloat)
    if draw(st.booleans()):
        cfg["ceiling_height"] = draw(anyfloat)
    if draw(st.booleans()):
        cfg["sensor_pitch"] = draw(anyfloat)
    if draw(st.booleans()):
        cfg["open_kernel_size"] = draw(st.integers(-3, 9))
    if draw(st.booleans()):
        cfg["open_kernel_shape"] = draw(st.sampled_from(["rect", "cross", "ellipse", "disc"]))
    if draw(st.booleans()):
        cfg["geometry"] = draw(st.sampled_from(["exact", "thesis", "Exact"]))
    if draw(st.booleans()):
        cfg["projection"] = draw(st.sampled_from(["horizontal", "column", ""]))
    if draw(st.booleans()):
        n = draw(st.integers(0, 5))
        cfg["threshold_curve"] = [(draw(anyfloat), draw(anyfloat)) for _ in range(n)]
    if draw(st.booleans()):
        cfg["scan_beams"] = draw(st.integers(-2, 2000))
    if draw(st.booleans()):
        cfg["range_min"], cfg["range_max"] = draw(anyfloat), draw(anyfloat)
    if draw(st.booleans()):
        cfg["max_depth"] = draw(anyfloat)
    return cfg


@fuzz
@given(frames(), configs(), anyfloat, anyfloat)
def test_process_never_crashes(
    frame: tuple[np.ndarray, kp.Camera], cfg: dict[str, object], pitch: float, roll: float
) -> None:
    arr, cam = frame
    try:
        pipe = kp.Pipeline(cam, kp.Config(**cfg))
    except (TypeError, ValueError):
        return
    try:
        res = pipe.process(arr, base_pitch=pitch, base_roll=roll)
    except (TypeError, ValueError):
        return
    assert res.depth.shape == arr.shape and res.depth.dtype == arr.dtype
    assert res.labels.shape == arr.shape and int(res.labels.max(initial=0)) <= 4
    assert res.ranges.shape == res.intensities.shape
    fin = np.isfinite(res.ranges)
    assert np.all(res.ranges[fin] >= res.range_min) and np.all(res.ranges[fin] <= res.range_max)
    assert np.all((res.intensities >= 0) & (res.intensities <= 1))
    assert math.isfinite(res.angle_increment) and res.angle_increment > 0


@fuzz
@given(st.integers(-5, 5), st.integers(-5, 5), anyfloat, anyfloat, anyfloat, anyfloat)
def test_camera_models_are_checked(w: int, h: int, fx: float, fy: float, cx: float, cy: float) -> None:
    try:
        cam = kp.Camera(w, h, fx, fy, cx, cy)
    except ValueError as exc:
        assert any(n in str(exc) for n in ("width", "height", "fx", "fy", "cx", "cy"))
        return
    assert cam.width >= 1 and cam.fx > 0


@fuzz
@given(st.text(max_size=40))
def test_curve_text_is_parsed_or_refused(text: str) -> None:
    try:
        kp.Config(threshold_curve=text)
    except ValueError as exc:
        assert "threshold_curve" in str(exc)
