"""Issue #19, the floor refinement, through the public API (kp.Config(refine_floor=...), res.pose, res.floor_fit):
frames rendered at the true pose, the pipeline told a pose off by up to 1 deg of pitch and roll and 5 cm of height."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.evaluation.metrics import frame_quality
from kinect_pipeline.evaluation.quality import phantom_rates
from kinect_pipeline.simulation.scenes import FIRST_BOX, Scene, lab_scene, render_frame, stair_scene

DEG = math.radians(1.0)
#: told pose minus true: height [m], pitch [deg], roll [deg]
ERRORS = [
    (0.0, 0, 0),
    (0.0, -1, 0),
    (0.0, 1, 0),
    (0.0, 0, 1),
    (0.05, 0, 0),
    (-0.05, 0, 0),
    (0.05, 1, -1),
    (-0.05, -1, 1),
]
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


def scores(res: kp.Result, frame: object) -> tuple[float, float, float, float]:
    """phantom beams (5 cm + 4 sigma short of the nearest obstacle), false cliff beams, floor removed (< 6 m),
    obstacle pixels 5 cm .. 1.95 m kept."""
    t = frame.truth  # type: ignore[attr-defined]
    q = frame_quality(res, frame)  # type: ignore[arg-type]
    obstacle = (t["object"] >= FIRST_BOX) & (t["height"] <= 2.0)
    phantom = phantom_rates(t, res.ranges, res.angle_min, res.angle_increment, obstacle)[1]
    return phantom, float(np.isfinite(res.cliff_ranges).mean()), q.floor_removed, q.obstacles_kept


def told(tilt: float, dh: float, dp: float, dr: float, **kw: object) -> kp.Config:
    return kp.Config(sensor_height=1.1 + dh, sensor_pitch=tilt + dp * DEG, sensor_roll=dr * DEG, **kw)


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1", "32FC1"])
@pytest.mark.parametrize("tilt_deg", [10, 20])
@pytest.mark.parametrize("base_pitch_deg", [-4, 4])
def test_pose_errors_meet_the_goals(encoding: str, tilt_deg: int, base_pitch_deg: int) -> None:
    cam = kp.kinect_v2_camera()
    tilt, bp = math.radians(tilt_deg), math.radians(base_pitch_deg)
    frame = render_frame(cam, lab_scene(), 1.1, tilt + bp, 0.0, encoding, seed=tilt_deg + base_pitch_deg + 50, tof=True)
    for dh, dp, dr in ERRORS:
        res = kp.Pipeline(cam, told(tilt, dh, dp, dr)).process(frame.depth, bp, 0.0)
        phantom, cliff, floor, kept = scores(res, frame)
        what = f"told {dh:+.2f} m {dp:+d} deg {dr:+d} deg: {res.floor_fit}"
        assert res.floor_fit.accepted, what
        assert abs(res.pose.height - 1.1) < 0.005 and abs(res.pose.pitch - tilt - bp) < 0.1 * DEG, what
        assert phantom <= 0.002 and cliff == 0.0, what
        assert floor >= 0.995 and kept >= 0.99, what


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1"])
def test_a_roll_below_the_noise_is_left_out(encoding: str) -> None:
    """Told a wrong height and pitch but the right roll (0), the fit corrects height and pitch and leaves the roll
    at exactly 0 (a roll term below a tenth of t(d) is noise), so the frame keeps the roll-free per-row paths; a
    real roll error of 1 deg is still corrected."""
    cam = kp.kinect_v2_camera()
    frame = render_frame(cam, lab_scene(), 1.1, 0.26, 0.0, encoding, seed=3, tof=True)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=1.13, sensor_pitch=0.26 + 0.5 * DEG))
    for _ in range(3):
        res = pipe.process(frame.depth)
        assert res.floor_fit.accepted and abs(res.pose.height - 1.1) < 0.005, res.floor_fit
        assert res.pose.roll == 0.0 and res.floor_fit.correction.roll == 0.0, res.floor_fit
        assert pipe.learned_correction.roll == 0.0
    rolled = render_frame(cam, lab_scene(), 1.1, 0.26, 1.0 * DEG, encoding, seed=3, tof=True)
    res = kp.Pipeline(cam, kp.Config(sensor_height=1.1, sensor_pitch=0.26)).process(rolled.depth)
    assert res.floor_fit.accepted and abs(res.pose.roll - 1.0 * DEG) < 0.1 * DEG, res.floor_fit


def test_without_the_refinement_the_same_errors_fail() -> None:
    """The goals have teeth: refine_floor=False misses them at these errors, and is the pose it was told."""
    cam = kp.kinect_v2_camera()
    tilt = math.radians(15)
    frame = render_frame(cam, lab_scene(), 1.1, tilt, 0.0, "16UC1", seed=3, tof=True)
    for dh, dp, dr in ERRORS[1:]:
        res = kp.Pipeline(cam, told(tilt, dh, dp, dr, refine_floor=False)).process(frame.depth)
        phantom, cliff, floor, kept = scores(res, frame)
        assert res.floor_fit.reason == "off" and tuple(res.pose) == (1.1 + dh, tilt + dp * DEG, dr * DEG)
        assert phantom > 0.002 or cliff > 0.0 or floor < 0.995 or kept < 0.99, (dh, dp, dr)


@pytest.mark.parametrize(
    "scene",
    [
        Scene(boxes=((0.9, 1.1, -5, 5, 0, 3),)),  # a wall close ahead
        Scene(boxes=((1.0, 1.6, -1.0, 1.0, 0, 0.8),)),  # a box filling the lower view
        Scene(boxes=((0.7, 1.0, -0.4, 0.3, 0, 1.8),)),  # a person close
        Scene(boxes=((0.8, 2.5, -1.5, 1.5, 0.68, 0.72),)),  # a table top
        Scene(boxes=((0.7, 2.7, -1.0, 1.0, 0.0, 0.5),)),  # a bed
    ],
    ids=["wall", "box", "person", "table", "bed"],
)
def test_little_floor_in_view_is_never_worse_than_without(scene: Scene) -> None:
    cam = kp.kinect_v2_camera()
    for tilt in (math.radians(10), math.radians(20)):
        frame = render_frame(cam, scene, 1.1, tilt, 0.0, "16UC1", seed=7, tof=True)
        for dh, dp, dr in ERRORS:
            on = scores(kp.Pipeline(cam, told(tilt, dh, dp, dr)).process(frame.depth), frame)
            off = scores(kp.Pipeline(cam, told(tilt, dh, dp, dr, refine_floor=False)).process(frame.depth), frame)
            what = f"told {dh:+.2f} m {dp:+d} deg {dr:+d} deg: on {on}, off {off}"
            assert on[0] <= off[0] + 1e-9 and on[1] <= off[1] + 1e-9, what
            for a, b in zip(on[2:], off[2:], strict=True):
                assert math.isnan(b) or a >= b - 0.002, what


def test_a_table_top_is_kept_whatever_the_pose_error() -> None:
    cam = kp.kinect_v2_camera()
    tilt = math.radians(15)
    frame = render_frame(cam, Scene(boxes=((0.6, 3.0, -1.5, 1.5, 0.67, 0.72),)), 1.1, tilt, 0.0, "16UC1", seed=9)
    top = (frame.truth["object"] == FIRST_BOX) & (frame.truth["height"] > 0.715)
    assert top.sum() > 10000
    for dh, dp, dr in ERRORS:
        res = kp.Pipeline(cam, told(tilt, dh, dp, dr)).process(frame.depth)
        assert (res.labels[top] == 0).mean() > 0.999, res.floor_fit
        assert abs(res.pose.height - 1.1) < abs(dh) + 0.01, res.floor_fit


def test_the_cliff_of_a_stair_survives_pose_errors() -> None:
    """A stair down 2.5 m ahead: with the pose told off, the lower level is still a cliff and the floor is not."""
    cam = kp.kinect_v2_camera()
    tilt = math.radians(17)
    frame = render_frame(cam, stair_scene(), 1.1, tilt, 0.0, "16UC1", seed=4)
    exact = kp.Pipeline(cam, told(tilt, 0, 0, 0, refine_floor=False)).process(frame.depth)
    want = np.isfinite(exact.cliff_ranges)
    assert want.mean() > 0.5
    for dh, dp, dr in ERRORS:
        res = kp.Pipeline(cam, told(tilt, dh, dp, dr)).process(frame.depth)
        got = np.isfinite(res.cliff_ranges)
        assert (got == want).mean() > 0.98, res.floor_fit
        both = got & want
        assert np.nanmax(np.abs(res.cliff_ranges[both] - exact.cliff_ranges[both])) < 0.1, res.floor_fit


def test_a_lagging_base_pitch_on_a_rocking_segway() -> None:
    """The base pitch signal 50 ms late on a Segway rocking +-4 deg once a second (25 deg/s): up to 1.3 deg off."""
    from kinect_pipeline.evaluation.quality import segway_pitch

    cam = kp.kinect_v2_camera()
    tilt = math.radians(15)
    pipe = kp.Pipeline(cam, told(tilt, 0, 0, 0))
    off = kp.Pipeline(cam, told(tilt, 0, 0, 0, refine_floor=False))
    worst_off = 0.0
    for i in range(30):
        t = i / 30.0
        frame = render_frame(cam, lab_scene(), 1.1, tilt + segway_pitch(t), 0.0, "16UC1", seed=100 + i, tof=True)
        res = pipe.process(frame.depth, segway_pitch(t - 0.05), 0.0, stamp=t)
        phantom, cliff, floor, kept = scores(res, frame)
        assert phantom <= 0.002 and cliff == 0.0 and floor >= 0.995 and kept >= 0.99, (i, res.floor_fit)
        o = scores(off.process(frame.depth, segway_pitch(t - 0.05), 0.0, stamp=t), frame)
        worst_off = max(worst_off, o[0], o[1])
    assert worst_off > 0.05, "the lag must matter without the refinement"


def test_a_mounting_error_is_learned_and_holds_without_floor() -> None:
    """Told 4 cm too high and 1 deg too level every frame: the learned correction converges to it (within what
    moves the floor by a tenth of t(d)) and is applied to a frame without any floor in view."""
    cam = kp.kinect_v2_camera()
    tilt = math.radians(15)
    pipe = kp.Pipeline(cam, told(tilt, 0.04, -1, 0, floor_learn_time=0.5))
    frame = render_frame(cam, lab_scene(), 1.1, tilt, 0.0, "16UC1", seed=5, tof=True)
    for i in range(90):
        res = pipe.process(frame.depth, stamp=i / 30.0)
    h, p, _ = pipe.learned_correction
    assert abs(h + 0.04) < 0.005 and abs(p - DEG) < 0.1 * DEG, pipe.learned_correction
    wall = render_frame(cam, Scene(boxes=((0.6, 0.8, -5, 5, 0, 3),)), 1.1, tilt, 0.0, "16UC1", seed=6)
    res = pipe.process(wall.depth, stamp=3.1)
    assert not res.floor_fit.accepted
    assert abs(res.pose.height - 1.1) < 0.005 and abs(res.pose.pitch - tilt) < 0.1 * DEG
    pipe.reset()
    assert tuple(pipe.learned_correction) == (0.0, 0.0, 0.0)


def test_floor_fit_fields_and_config_validation() -> None:
    cam = kp.kinect_v2_camera()
    cfg = kp.Config()
    assert cfg.refine_floor is True
    assert 0.05 < cfg.floor_max_height_error <= 0.1 and 0.017 < cfg.floor_max_pitch_error <= 0.05
    assert cfg.floor_min_pixels > 0 and cfg.floor_learn_time > 0
    res = kp.Pipeline(cam, cfg).process(np.zeros((cam.height, cam.width), np.uint16))
    f = res.floor_fit
    assert f.reason == "too few pixels" and not f.accepted and f.pixels == 0
    assert tuple(res.pose) == (cfg.sensor_height, cfg.sensor_pitch, cfg.sensor_roll)
    assert "too few pixels" in repr(f)
    for field, bad in [
        ("floor_max_height_error", 0.0),
        ("floor_max_pitch_error", -1.0),
        ("floor_min_pixels", 0),
        ("floor_learn_time", float("nan")),
    ]:
        with pytest.raises(ValueError, match=field):
            kp.Config(**{field: bad})
    with pytest.raises(ValueError, match="stamp"):
        kp.Pipeline(cam, cfg).process(np.zeros((cam.height, cam.width), np.uint16), stamp=float("inf"))


def kinect_v1_sigma(z: np.ndarray) -> np.ndarray:
    """Depth noise of a Kinect v1 / PrimeSense sensor (Khoshelham & Elberink 2012: 1.425e-3 z^2 [m])."""
    return 1.425e-3 * z * z


REAL_FRAMES = [
    ("tum_nyu_sun_open3d/TUM_depth.png", 5000.0, (525.0, 525.0, 319.5, 239.5)),
    ("tum_nyu_sun_open3d/NYU_depth_mm.png", 1000.0, (582.6, 582.7, 313.0, 238.4)),
    ("tum_nyu_sun_open3d/SUN_depth_mm.png", 1000.0, (525.0, 525.0, 319.5, 239.5)),
    ("slambook2/ch7/1_depth.png", 5000.0, (520.9, 521.0, 325.1, 249.7)),
    ("slambook2/ch7/2_depth.png", 5000.0, (520.9, 521.0, 325.1, 249.7)),
] + [(f"slambook2/ch5/rgbd/depth/{i}.pgm", 1000.0, (518.0, 519.0, 325.5, 253.5)) for i in (1, 2, 3, 5)]
# Frame 4: the fitted pose lies 0.06 deg / 0.11 deg from calibrate's (its floor beyond 4 m, where calibrate still
# fits and the refinement does not, bends away from the plane nearer): 163 floor pixels 4-5.5 m away at the margin
# of t(d) are kept, 11 of 640 beams (docs/floor_refinement.md, "What it cannot do").
FRAME_4 = ("slambook2/ch5/rgbd/depth/4.pgm", 1000.0, (518.0, 519.0, 325.5, 253.5))
KNOWN = pytest.param(
    *FRAME_4,
    None,
    id="4.pgm-default-curve",
    marks=pytest.mark.xfail(strict=True, reason="far floor off the near plane: 1.7 % phantom beams"),
)


@pytest.mark.parametrize(
    ("name", "per_metre", "k", "model"),
    [pytest.param(*f, None, id=f[0].split("/")[-1]) for f in REAL_FRAMES]
    + [KNOWN]
    + [pytest.param(*f, "kinect_v1", id=f"{f[0].split('/')[-1]}-kinect_v1") for f in [*REAL_FRAMES, FRAME_4]],
)
def test_real_frames_told_the_calibrated_pose_off(
    name: str, per_metre: float, k: tuple[float, ...], model: str | None
) -> None:
    """Real Kinect v1 frames: the calibrated pose (MSAC on the frame, `calibrate`) is the reference; told it off,
    the refined frame removes the floor the calibrated pose removes, and no beam is nearer than the calibrated
    pose's scan by more than the sensor's noise allows (5 cm + 4 sigma of a Kinect v1). With the default (Kinect v2)
    curve, and with the sensor's own preset (sensor_model: kinect_v1), as a user of these sensors would set it."""
    import cv2

    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path}: the shared real frames are not beside the repository")
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    metres = raw.astype(np.float32) / per_metre
    depth = np.round(metres * 1000).astype(np.uint16)
    cam = kp.Camera(raw.shape[1], raw.shape[0], *k)
    fp = kp._core.calibrate_from_floor(np.ascontiguousarray(metres), cam)
    assert fp["found"]
    pose = dict(sensor_height=fp["height"], sensor_pitch=fp["pitch"], sensor_roll=fp["roll"])
    ceiling = max(2.0, fp["height"] + 0.5)
    preset = {"sensor_model": model} if model else {}
    ref = kp.Pipeline(cam, kp.Config(refine_floor=False, ceiling_height=ceiling, **pose, **preset)).process(depth)
    floor = ref.labels == 2
    real = np.minimum(ref.ranges, np.minimum(np.roll(ref.ranges, 1), np.roll(ref.ranges, -1))).astype(np.float64)
    margin = 0.05 + 4 * kinect_v1_sigma(np.where(np.isfinite(real), real, 0.0))
    for dh, dp, dr in ERRORS:
        cfg = kp.Config(
            sensor_height=fp["height"] + dh,
            sensor_pitch=fp["pitch"] + dp * DEG,
            sensor_roll=fp["roll"] + dr * DEG,
            ceiling_height=ceiling,
            **preset,
        )
        res = kp.Pipeline(cam, cfg).process(depth)
        assert res.floor_fit.accepted, (dh, dp, dr, res.floor_fit)
        assert (res.labels[floor] != 0).mean() >= 0.99, (dh, dp, dr, res.floor_fit)
        r = np.asarray(res.ranges, np.float64)
        phantom = np.isfinite(r) & (r < np.where(np.isfinite(real), real, np.inf) - margin)
        assert phantom.mean() <= 0.01, (dh, dp, dr, np.flatnonzero(phantom), res.floor_fit)
