"""Sensor presets (sensor_model) on the shared real frames, and calibrate's documented rule on them."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.tools.calibrate import calibrate, load_depth

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"

#: The shared real frames with a floor (MANIFEST.md): all structured-light Kinect v1 class sensors.
FRAMES = [
    ("tum_nyu_sun_open3d/NYU_depth_mm.png", (582.6, 582.7, 313.0, 238.4), 0.001),
    ("tum_nyu_sun_open3d/SUN_depth_mm.png", (525.0, 525.0, 319.5, 239.5), 0.001),
    ("tum_nyu_sun_open3d/TUM_depth.png", (525.0, 525.0, 319.5, 239.5), 0.0002),
    *[(f"slambook2/ch5/rgbd/depth/{i}.pgm", (518.0, 519.0, 325.5, 253.5), 0.001) for i in range(1, 6)],
    *[(f"slambook2/ch7/{i}_depth.png", (520.9, 521.0, 325.1, 249.7), 0.0002) for i in (1, 2)],
]


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args], capture_output=True, text=True, timeout=300
    )


def _frame(name: str, intr: tuple, scale: float) -> tuple[np.ndarray, kp.Camera]:
    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path} not available")
    m = load_depth(path, scale)
    return m, kp.Camera(m.shape[1], m.shape[0], *intr)


@pytest.mark.parametrize("refine", [True, False], ids=["refine_floor", "pose_as_given"])
@pytest.mark.parametrize(("name", "intr", "scale"), FRAMES, ids=[f[0].split("/")[-1] for f in FRAMES])
def test_no_false_cliff_beam_with_the_preset_at_the_calibrated_pose(
    name: str, intr: tuple, scale: float, refine: bool
) -> None:
    m, cam = _frame(name, intr, scale)
    cal = calibrate([(name, m)], cam)
    assert cal.found
    pose = dict(sensor_height=cal.height, sensor_pitch=cal.pitch, sensor_roll=cal.roll, refine_floor=refine)
    pose["ceiling_height"] = max(2.0, cal.height + 0.5)
    for depth in (m, np.round(m * 1000).astype(np.uint16)):
        res = kp.Pipeline(cam, kp.Config(sensor_model="kinect_v1", **pose)).process(depth)
        assert not np.isfinite(res.cliff_ranges).any(), f"{int(np.isfinite(res.cliff_ranges).sum())} cliff beams"
        assert (res.labels == 2).mean() > 0.5 * cal.floor_fraction, "the floor is still removed"


def test_the_default_curve_shows_them_without_the_preset() -> None:
    """What the preset is for: the Kinect v2 curve (the default) sees cliffs in a Kinect v1 floor's noise."""
    m, cam = _frame(*FRAMES[0])
    cal = calibrate([("nyu", m)], cam)
    cfg = kp.Config(sensor_height=cal.height, sensor_pitch=cal.pitch, sensor_roll=cal.roll, refine_floor=False)
    assert np.isfinite(kp.Pipeline(cam, cfg).process(m).cliff_ranges).sum() > 10


def test_presets_are_the_cores_table() -> None:
    names = kp.sensor_models()
    assert names == ["kinect_v2", "kinect_v1", "realsense_d4xx", "azure_kinect", "orbbec_astra"]
    assert kp.Config().threshold_curve_text == kp.sensor_model("kinect_v2")["threshold_curve"]
    for n in names:
        d = kp.sensor_model(n)
        cfg = kp.Config(sensor_model=n)
        assert cfg.threshold_curve_text == d["threshold_curve"] and cfg.range_max == d["range_max"]
        assert cfg.cliff_min_pixels == d["cliff_min_pixels"] and cfg.speckle_jump == d["speckle_jump"]
        assert d["speckle_jump"] == (0.125 if n == "realsense_d4xx" else 0.0), "wrong matches: the stereo camera's"
        assert d["depth_topic"].endswith(d["image"]) and d["info_topic"].endswith("/camera_info")
        for z in (1.0, 3.0):  # the curve is margin + k sigma (+ depth steps), sigma the published model's
            t = kp.evaluate_curve(d["threshold_curve"], z)
            want = d["margin"] + d["k"] * d["sigma0"] + d["k"] * d["quad"] * (z - d["z0"]) ** 2
            assert t == pytest.approx(want + d["steps"] * d["step2"] * z * z, abs=0.0011)
    with pytest.raises(ValueError, match="sensor_model 'kinect_v3': expected one of kinect_v2, kinect_v1"):
        kp.Config(sensor_model="kinect_v3")


def test_an_explicit_field_wins_over_the_preset() -> None:
    cfg = kp.Config(sensor_model="kinect_v1", threshold_curve="0.5:0.05, 12:1.0", range_max=7.0)
    assert cfg.threshold_curve == [(0.5, 0.05), (12.0, 1.0)] and cfg.range_max == 7.0
    assert kp.Config(sensor_model="realsense_d4xx", speckle_jump=0.0).speckle_jump == 0.0
    assert cfg.cliff_min_pixels == kp.sensor_model("kinect_v1")["cliff_min_pixels"]


def test_cli_sensor_model_gives_typical_intrinsics_and_bad_names_are_one_line() -> None:
    path = REAL / "tum_nyu_sun_open3d" / "TUM_depth.png"
    if not path.exists():
        pytest.skip(f"{path} not available")
    r = cli("calibrate", str(path), "--sensor-model", "kinect_v1", "--depth-scale", "0.0002", "--json")
    assert r.returncode == 0, r.stderr
    assert 1.5 < json.loads(r.stdout)["height"] < 2.0
    assert "WARNING: no camera intrinsics given: the nominal camera of --sensor-model kinect_v1" in r.stderr
    r = cli("calibrate", str(path), "--sensor-model", "realsense_d4xx", "--depth-scale", "0.0002")
    assert r.returncode == 1 and "nominal camera is 848x480, the depth images are 640x480" in r.stderr
    r = cli("replay", "x.bag", "-o", "y.bag", "--param", "sensor_model=kinect_v3")
    assert r.returncode == 1 and "sensor_model 'kinect_v3': expected one of" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


# -- calibrate: the documented rule, its warnings, every pose term --------------------------------------------


def test_calibrate_returns_the_floor_not_the_desk() -> None:
    """slambook2 ch7/1: a desk holds most of the pixels, the floor 1.57 m down about a fifth: the floor is the
    lowest plane with >= 5 % of the pixels."""
    m, cam = _frame("slambook2/ch7/1_depth.png", (520.9, 521.0, 325.1, 249.7), 0.0002)
    cal = calibrate([("ch7", m)], cam)
    assert cal.found and 1.50 < cal.height < 1.65, cal.height
    assert 0.05 <= cal.floor_fraction < 0.4


def test_calibrate_warns_when_frames_disagree_and_prints_every_pose_term() -> None:
    folder = REAL / "slambook2" / "ch5" / "rgbd" / "depth"
    if not folder.exists():
        pytest.skip(f"{folder} not available")
    r = cli("calibrate", str(folder), "--intrinsics", "518.0", "519.0", "325.5", "253.5")
    assert r.returncode == 0, r.stderr
    assert "warning: the 5 frames disagree: roll spans 3.9..9.8 deg" in r.stderr, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("launch args:"))
    for term in ("sensor_height:=", "sensor_pitch:=", "sensor_roll:=", "pose_source:=static"):
        assert term in line
    roll = float(line.split("sensor_roll:=")[1].split()[0])
    assert math.degrees(roll) == pytest.approx(6.3, abs=1.0)


def test_calibrate_warns_about_a_weak_fit(tmp_path: Path) -> None:
    from kinect_pipeline.simulation.scenes import boxes_scene, render_frame

    cam = kp.kinect_v2_camera()
    f = render_frame(cam, boxes_scene(), 1.1, 0.05, 0.0, "32FC1", seed=3)  # looking ahead: little floor
    depth = np.where(np.isfinite(f.metres), f.metres, 0).astype(np.float32)
    cal = calibrate([("ahead", depth)], cam)
    if cal.found and cal.floor_fraction < 0.10:
        assert any("weak floor fit" in w for w in cal.warnings), cal.warnings
    strong = render_frame(cam, boxes_scene(), 1.1, 0.4, 0.0, "32FC1", seed=3)
    depth = np.where(np.isfinite(strong.metres), strong.metres, 0).astype(np.float32)
    good = calibrate([("down", depth)], cam)
    assert good.found and not good.warnings, good.warnings
