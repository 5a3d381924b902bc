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


def field_values(f: dict[str, object]) -> st.SearchStrategy[object]:
    """Values for one row of the core's table (kp.CONFIG_FIELDS): valid ones, the edges, and some it must refuse."""
    lo, hi = float(f["min"]), float(f["max"])  # type: ignore[arg-type]
    kind = f["kind"]
    if kind == "real":
        return anyfloat
    if kind == "integer":
        return st.integers(int(lo) - 3, int(min(hi, lo + 2000)))
    if kind == "flag":
        return st.booleans()
    if kind == "choice":
        return st.sampled_from([*f["choices"], "Exact", ""])  # type: ignore[misc]
    return st.lists(st.tuples(anyfloat, anyfloat), max_size=5)


@st.composite
def configs(draw: st.DrawFn) -> dict[str, object]:
    """Any subset of the Config fields, each drawn as its kind says (a new field is fuzzed without a change here)."""
    cfg: dict[str, object] = {}
    for f in kp.CONFIG_FIELDS:
        if draw(st.booleans()):
            cfg[str(f["name"])] = draw(field_values(f))
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
