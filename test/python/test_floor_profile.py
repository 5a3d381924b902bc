"""Issue #25, item 1: the floor profile beyond the plane, through the public API (``kp.Config(floor_profile_max=)``,
``res.floor_fit.profile``, ``Pipeline.floor_state``, ``predicted_floor``). It learns a gently curved floor and a
stereo camera's range bias, stays within its bound, never learns a stair, a hole or an obstacle into the floor,
resets and resumes; off (``floor_profile_max=0`` or ``refine_floor=False``) it is the plane alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.evaluation.real_floors import RS_CAM, RS_HEIGHT, RS_PITCH, curved_floor_robot
from kinect_pipeline.simulation.scenes import (
    BELOW_FLOOR,
    KEPT,
    furniture_scene,
    hole_scene,
    lab_scene,
    render_frame,
    stair_scene,
    truth_labels,
)

DEG = math.pi / 180
BOUND = kp.Config().floor_profile_max


def _config(**kw: object) -> kp.Config:
    return kp.Config(sensor_height=RS_HEIGHT, sensor_pitch=RS_PITCH, ceiling_height=2.0, **kw)


def _profile(res: kp.Result) -> np.ndarray:
    """(band centre [m], bias [m], samples) per band."""
    return np.array(res.floor_fit.profile, dtype=np.float64)


@pytest.mark.parametrize("roll", [0.0, 10.0])
def test_a_gently_curved_floor_is_learned_and_removed(roll: float) -> None:
    # The floor rises 5 cm at 4.4 m: near the plane's noise band's edge. The profile removes more of it in the worst
    # frame than the plane alone does, and the frames stay free of phantoms and cliffs.
    with_profile = curved_floor_robot(roll=roll)
    plane = curved_floor_robot(profile=False, roll=roll)
    assert with_profile.floor >= 0.993, with_profile
    assert with_profile.floor > plane.floor + 0.001, (with_profile, plane)
    assert with_profile.phantom == 0.0 and with_profile.cliff == 0.0, with_profile


def test_the_profile_follows_the_floor_and_predicted_floor_shows_it() -> None:
    pipe = kp.Pipeline(RS_CAM, _config())
    for i in range(12):
        fr = render_frame(RS_CAM, lab_scene(), RS_HEIGHT, RS_PITCH, 0.0, "16UC1", seed=i, floor_curve=0.006)
        res = pipe.process(fr.depth, stamp=i / 30)
    p = _profile(res)
    # The floor rises with range, so beyond ~3 m it is seen nearer than the plane the fit found.
    far = p[(p[:, 0] > 3.0) & (p[:, 0] < 4.0)]
    assert (far[:, 1] < -0.005).all(), p
    # predicted_floor is plane plus profile: nearer than the plane alone where the profile is negative.
    plane = kp.Pipeline(RS_CAM, _config(floor_profile_max=0.0))
    plane.floor_state = pipe.floor_state[:7]
    plane.process(fr.depth, stamp=12 / 30)
    pipe.process(fr.depth, stamp=12 / 30)
    both = np.isfinite(pipe.predicted_floor()) & np.isfinite(plane.predicted_floor())
    fd, pd = pipe.predicted_floor()[both], plane.predicted_floor()[both]
    assert (fd < pd - 0.01).any() and np.abs(fd - pd).max() < 0.5


@pytest.mark.parametrize("curve", [0.03, -0.03])
def test_the_profile_stays_within_its_bound_in_height(curve: float) -> None:
    # A floor that rises or falls far more than floor_profile_max: the profile holds at its bound (in height).
    pipe = kp.Pipeline(RS_CAM, _config())
    for i in range(15):
        fr = render_frame(RS_CAM, lab_scene(), RS_HEIGHT, RS_PITCH, 0.0, "16UC1", seed=i, floor_curve=curve)
        res = pipe.process(fr.depth, stamp=i / 30)
        p = _profile(res)
        height = np.abs(p[:, 1]) * res.pose.height / p[:, 0]
        assert (height <= BOUND * (1 + 1e-5)).all(), (i, p)


@pytest.mark.parametrize(("name", "scene"), [("stair", stair_scene()), ("hole", hole_scene())])
def test_a_stair_down_or_a_hole_is_never_learned_into_the_floor(name: str, scene: object) -> None:
    # 30 frames over a stair down / a hole: the below-floor pixels and cliff beams the plane alone finds stay found.
    cam = _core.Camera.from_fov(512, 424, math.radians(70.6), math.radians(60.0))
    runs = {}
    for prof in (BOUND, 0.0):
        cfg = kp.Config(sensor_height=1.1, sensor_pitch=0.35, cliff_scan=True, floor_profile_max=prof)
        pipe = kp.Pipeline(cam, cfg)
        below = cliffs = 0
        for i in range(30):
            fr = render_frame(cam, scene, 1.1, 0.35, 0.0, "16UC1", seed=i)  # type: ignore[arg-type]
            res = pipe.process(fr.depth, stamp=i / 30)
            truth = truth_labels(fr.truth) == BELOW_FLOOR
            below += int((res.labels[truth] == BELOW_FLOOR).sum())
            cliffs += int(np.isfinite(res.cliff_ranges).sum())
        runs[prof] = (below, cliffs)
    assert runs[0.0][0] > 1000 and runs[0.0][1] > 10, runs  # the check can fail: there is a drop in view
    assert runs[BOUND][0] >= 0.95 * runs[0.0][0] and runs[BOUND][1] >= 0.95 * runs[0.0][1], (name, runs)


def test_what_stands_on_the_floor_is_never_learned_into_it() -> None:
    # Furniture with low parts in the floor band: the obstacles' pixels kept with the profile as without.
    kept = {}
    for prof in (BOUND, 0.0):
        pipe = kp.Pipeline(RS_CAM, _config(floor_profile_max=prof))
        n = 0
        for i in range(20):
            fr = render_frame(RS_CAM, furniture_scene(), RS_HEIGHT, RS_PITCH, 0.0, "16UC1", seed=i)
            res = pipe.process(fr.depth, stamp=i / 30)
            obstacle = truth_labels(fr.truth) == KEPT
            n += int((res.labels[obstacle] == KEPT).sum())
        kept[prof] = n
    assert kept[0.0] > 10000 and kept[BOUND] >= 0.995 * kept[0.0], kept


def test_floor_state_carries_the_profile_and_reset_forgets_it() -> None:
    frames = [
        render_frame(RS_CAM, lab_scene(), RS_HEIGHT, RS_PITCH, 0.0, "16UC1", seed=i, floor_curve=0.006).depth
        for i in range(10)
    ]
    whole = kp.Pipeline(RS_CAM, _config())
    results = [whole.process(f, stamp=i / 30) for i, f in enumerate(frames)]
    first = kp.Pipeline(RS_CAM, _config())
    for i, f in enumerate(frames[:5]):
        first.process(f, stamp=i / 30)
    state = first.floor_state
    assert len(state) == 7 + 2 * len(results[0].floor_fit.profile) + 1
    resumed = kp.Pipeline(RS_CAM, _config())
    resumed.floor_state = state
    for i, f in enumerate(frames[5:], start=5):
        res = resumed.process(f, stamp=i / 30)
        assert np.array_equal(res.labels, results[i].labels) and res.floor_fit.profile == results[i].floor_fit.profile
    assert np.abs(_profile(res)[:, 1]).max() > 0.005  # it carried something
    resumed.reset()
    assert all(b == 0.0 for _, b, _ in _profile_after(resumed, frames[0]))


def _profile_after(pipe: kp.Pipeline, depth: np.ndarray) -> list[tuple[float, float, int]]:
    """The profile before pipe's next frame learns: floor_learn_time 0 learns nothing."""
    cfg = pipe.config
    cfg.floor_learn_time = 0.0
    pipe.config = cfg
    return pipe.process(depth).floor_fit.profile


@pytest.mark.parametrize("off", [{"floor_profile_max": 0.0}, {"refine_floor": False}])
def test_off_is_the_plane_alone(off: dict[str, object]) -> None:
    pipe = kp.Pipeline(RS_CAM, _config(**off))
    for i in range(6):
        fr = render_frame(RS_CAM, lab_scene(), RS_HEIGHT, RS_PITCH, 0.0, "16UC1", seed=i, floor_curve=0.006)
        res = pipe.process(fr.depth, stamp=i / 30)
        assert all(b == 0.0 and n == 0 for _, b, n in res.floor_fit.profile), res.floor_fit.profile


def test_a_bad_bound_is_refused_naming_it() -> None:
    for bad in (-0.01, float("nan"), 2.0):
        with pytest.raises(ValueError, match="floor_profile_max"):
            kp.Config(floor_profile_max=bad)
