"""Real sensors' floors (issue #25): no phantom obstacle and no false cliff where a real stereo camera's floor bends
away with range, where people and furniture stand in the floor band, and where a platform rocks beyond the fit's
bounds; real stairs and holes still found. Rendered frames with a stereo camera's artefacts
(``_core.add_stereo_artefacts``, checked here against the shared RealSense frames) and the real frames themselves."""

from __future__ import annotations

import math
import os

import cv2
import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.evaluation.metrics import frame_quality
from kinect_pipeline.evaluation.real_floors import (
    KINECT,
    ROBOT_SCENES,
    RS_CAM,
    RS_HEIGHT,
    RS_PITCH,
    RS_ROLL,
    people_robot,
    real_frames_false_cliffs,
    shared_realsense_frames,
    stereo_robot,
)
from kinect_pipeline.simulation.scenes import (
    FLOOR,
    add_multipath,
    furniture_scene,
    hole_scene,
    lab_scene,
    people_scene,
    render_frame,
    stair_scene,
)

DEG = math.pi / 180
REAL = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "real")


def outlier_rate(metres: np.ndarray) -> float:
    """Valid pixels more than 10 % from their 5x5 median (speckle, wrong matches, smear)."""
    valid = np.isfinite(metres) & (metres > 0)
    z = np.where(valid, metres, 0).astype(np.float32)
    med = cv2.medianBlur(z, 5)
    return float((valid & (med > 0) & (np.abs(z - med) > 0.1 * med)).sum() / valid.sum())


def real_realsense() -> list[np.ndarray]:
    frames = shared_realsense_frames(os.path.join(REAL, "realsense_lowcam"))
    if not frames:
        pytest.fail(f"the shared RealSense frames are missing under {REAL}")
    return frames


def test_rendered_stereo_frames_look_like_the_real_realsense_frames() -> None:
    # Outliers within a few times the real frames' rate, and the noise grows with the square of the depth as the
    # sensor's model says: the floor's rms residual at 3 m about 9 times that at 1 m.
    real = [outlier_rate(np.where(d > 0, d / 1000.0, np.nan)) for d in real_realsense()]
    rendered = []
    for seed in range(3):
        fr = render_frame(RS_CAM, furniture_scene(), 0.4, 10 * DEG, 0.0, "32FC1", seed=seed, stereo=True)
        rendered.append(outlier_rate(fr.metres))
    assert max(real) < 0.002, real
    assert 0.2 * np.median(real) < np.median(rendered) < 10 * max(real), (real, rendered)
    flat = np.full((480, 640), np.inf, np.float32)
    for z in (1.0, 3.0):
        flat[:] = z
        noisy = _core.add_stereo_artefacts(flat, 5, speckle=0.0, dropout=0.0)
        sd = float(np.std(noisy[np.isfinite(noisy)]))
        assert sd == pytest.approx(float(_core.stereo_sigma(z)), rel=0.1), (z, sd)
    # The bias: a positive depth error growing with the square of the depth, as the real camera's floor shows.
    flat[:] = 4.0
    bias = float(np.median(_core.add_stereo_artefacts(flat, 6, speckle=0.0, dropout=0.0))) - 4.0
    assert 0.04 < bias < 0.1


@pytest.mark.parametrize("scene", ["furniture", "lab", "people"])
@pytest.mark.parametrize("told", [(0.0, 0.0, 0.0), (0.05, 1.0, -1.0), (-0.05, -1.0, 1.0)])
def test_a_stereo_robot_sees_no_false_cliff_and_removes_the_floor(scene: str, told: tuple[float, float, float]) -> None:
    worst = stereo_robot(ROBOT_SCENES[scene](), told)
    assert worst.cliff <= 0.005 and worst.floor >= 0.995 and worst.phantom <= 0.01, worst


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1"])
def test_people_around_a_pitching_robot(encoding: str) -> None:
    worst = people_robot(refine=True, exact=False, encoding=encoding)
    assert worst.phantom <= 0.005 and worst.cliff == 0.0 and worst.floor >= 0.99, worst
    # Told the exact pose, the refinement is never worse than without it.
    exact = people_robot(refine=True, exact=True, encoding=encoding)
    plain = people_robot(refine=False, exact=True, encoding=encoding)
    assert exact.phantom <= plain.phantom + 1e-9, (exact, plain)
    assert exact.cliff <= plain.cliff + 1e-9, (exact, plain)
    assert exact.floor >= plain.floor - 0.002, (exact, plain)


@pytest.mark.parametrize("scene", ["lab", "furniture"])
def test_a_kinect_v2s_multipath_before_walls_makes_no_false_cliff(scene: str) -> None:
    # Time-of-flight multipath: the floor before a wall's or a cabinet's base is seen up to 4 cm farther; with the
    # ToF artefacts (flying pixels, the 8 m range) and Kinect noise, at 1.1 m, 15 deg down.
    cfg = kp.Config(sensor_height=1.1, sensor_pitch=15 * DEG, cliff_scan=True)
    pipe = kp.Pipeline(KINECT, cfg)
    make = ROBOT_SCENES[scene]
    moved = 0
    for i in range(15):
        fr = render_frame(KINECT, make(), 1.1, 15 * DEG, 0.0, "16UC1", seed=i, tof=True, multipath=0.04)
        plain = render_frame(KINECT, make(), 1.1, 15 * DEG, 0.0, "16UC1", seed=i, tof=True)
        moved += int((fr.metres > plain.metres + 0.005).sum())
        res = pipe.process(fr.depth, stamp=i / 30)
        q = frame_quality(res, fr, floor_radius=4.0, sigma=_core.kinect_sigma)
        assert not np.isfinite(res.cliff_ranges).any(), (i, np.flatnonzero(np.isfinite(res.cliff_ranges)))
        assert q.floor_removed >= 0.99 and q.phantom_beams <= 0.005, (i, q)
    assert moved > 1000  # the multipath is there: the check can fail


def test_multipath_moves_only_the_floor_before_a_surface_and_by_at_most_its_amplitude() -> None:
    fr = render_frame(KINECT, lab_scene(), 1.1, 15 * DEG, 0.0, "32FC1", seed=None)
    bent = add_multipath(fr.metres, fr.truth, 0.04)
    finite = np.isfinite(fr.metres)
    grew = bent[finite] - fr.metres[finite]
    floor = (fr.truth["object"] == FLOOR)[finite]
    assert (grew >= 0).all() and (grew[~floor] == 0).all()
    rng = fr.truth["range"][finite]
    assert (grew * rng / fr.metres[finite] <= 0.04 + 1e-6).all()  # at most 4 cm of range
    assert (grew[floor] > 0.02).sum() > 500  # and near the walls' bases, a lot of it


def test_a_leg_in_the_floor_band_is_no_floor_candidate() -> None:
    # The legs' lowest pixels lie within the band: as vertical surfaces they are not sampled, so they neither pull
    # the plane nor widen its spread.
    fr = render_frame(KINECT, people_scene(seed=3, count=8, spacing=0.3), 1.1, 5 * DEG - 6 * DEG, 0.0, "16UC1", seed=3)
    res = kp.Pipeline(KINECT, kp.Config(sensor_height=1.1, sensor_pitch=-1 * DEG)).process(fr.depth)
    assert res.floor_fit.reason in ("accepted", "not better than the prior"), res.floor_fit
    assert abs(res.pose.pitch - (-1 * DEG)) < 0.05 * DEG and abs(res.pose.height - 1.1) < 0.003, res.pose


def test_a_rocking_platform_beyond_the_bounds_is_followed() -> None:
    # The mount's median pose told, the platform rolled 2.3 deg off it: beyond the 2 deg bound, well supported.
    truth_roll = RS_ROLL + 2.3 * DEG
    fr = render_frame(RS_CAM, furniture_scene(), RS_HEIGHT, RS_PITCH, truth_roll, "16UC1", seed=2, stereo=True)
    cfg = kp.Config(sensor_model="realsense_d4xx", sensor_height=RS_HEIGHT, sensor_pitch=RS_PITCH, sensor_roll=RS_ROLL)
    res = kp.Pipeline(RS_CAM, cfg).process(fr.depth)
    assert res.floor_fit.accepted, res.floor_fit
    assert abs(res.pose.roll - truth_roll) < 0.2 * DEG
    q = frame_quality(res, fr, floor_radius=4.0, sigma=_core.stereo_sigma)
    assert q.floor_removed >= 0.995 and q.phantom_beams <= 0.01, q
    # Beyond twice the bound it is declined, and the frame runs at the told pose.
    fr = render_frame(RS_CAM, furniture_scene(), RS_HEIGHT, RS_PITCH, RS_ROLL + 4.5 * DEG, "16UC1", seed=2, stereo=True)
    res = kp.Pipeline(RS_CAM, cfg).process(fr.depth)
    assert not res.floor_fit.accepted
    assert res.pose.roll == pytest.approx(RS_ROLL)


def test_the_learned_correction_converges_in_the_first_second() -> None:
    # Told 4 cm high and 0.8 deg off, 30 Hz: after a second (30 frames) the learned correction holds the error.
    cfg = kp.Config(sensor_height=1.14, sensor_pitch=15 * DEG + 0.8 * DEG, floor_learn_time=2.0)
    pipe = kp.Pipeline(KINECT, cfg)
    for i in range(30):
        fr = render_frame(KINECT, lab_scene(), 1.1, 15 * DEG, 0.0, "16UC1", seed=i)
        res = pipe.process(fr.depth, stamp=i / 30)
    learned = pipe.learned_correction
    assert learned.height == pytest.approx(-0.04, abs=0.005), learned
    assert learned.pitch == pytest.approx(-0.8 * DEG, abs=0.1 * DEG), learned
    # With no floor in view the learned correction holds.
    nothing = np.zeros((424, 512), np.uint16)
    res = pipe.process(nothing, stamp=1.5)
    assert res.pose.height == pytest.approx(1.1, abs=0.005)


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1", "32FC1"])
def test_real_stairs_and_holes_keep_their_beams(encoding: str) -> None:
    # The evidence rule keeps >= 95 % of the beams that see the lower level, at the Kinect's pose and the RealSense's.
    poses = ((KINECT, 1.1, 0.3, 0.0, None), (RS_CAM, RS_HEIGHT, RS_PITCH, RS_ROLL, "realsense_d4xx"))
    for cam, h, pitch, roll, model in poses:
        for scene in (stair_scene(2.0, 0.17), hole_scene()):
            fr = render_frame(cam, scene, h, pitch, roll, encoding, seed=4)
            preset = {"sensor_model": model} if model else {}
            base = dict(sensor_height=h, sensor_pitch=pitch, sensor_roll=roll, **preset)
            gated = kp.Pipeline(cam, kp.Config(**base)).process(fr.depth)
            every = kp.Pipeline(cam, kp.Config(cliff_min_drop=0.0, **base)).process(fr.depth)
            # Beams where no obstacle stands before the cliff (one nearer hides it, by design: the robot stops there).
            seen = np.isfinite(every.cliff_ranges) & ~(every.ranges < every.cliff_ranges + 0.5)
            assert seen.sum() > 20, (encoding, model)
            kept = np.isfinite(gated.cliff_ranges) & seen
            assert kept.sum() >= 0.95 * seen.sum(), (encoding, model, kept.sum(), seen.sum())
            # The nearest evidence lies at most a little beyond the nearest below-floor pixel (the rim's shallow ones).
            d = gated.cliff_ranges[kept] - every.cliff_ranges[kept]
            assert (d >= 0).all() and (d <= 0.15).all(), (encoding, model, d.min(), d.max())


def test_real_realsense_frames_show_no_false_cliff() -> None:
    # The shared RealSense frames (a low handheld camera; objects on the floor, no hole, no stair), each told the
    # floor calibrate fits in it (where calibrate trusts it), with the sensor's preset: no cliff beam.
    cliffs = real_frames_false_cliffs(real_realsense())
    assert len(cliffs) >= 5
    assert max(cliffs) <= 0.005, cliffs


def _spot_depth() -> np.ndarray:
    """The Spot bag's depth frame (uint16 mm, 424x240): a stereo camera mounted rolled about 80 deg, looking down;
    read as the tools read it."""
    from pathlib import Path

    from kinect_pipeline.bags.messages import depth_array
    from kinect_pipeline.bags.reader import open_bag

    with open_bag(Path(REAL) / "spot_bags" / "raw.bag") as bag:
        conns = [c for c in bag.connections if c.topic == "/spot/depth/frontleft/image"]
        for conn, _, raw in bag.messages(conns):
            return depth_array(bag.decode(conn, raw))
    raise AssertionError("no depth frame in the Spot bag")


@pytest.mark.parametrize("told", [(0.0, 0.0, 0.0), (0.05, 1.0, -1.0), (-0.05, -1.0, 1.0)])
def test_a_real_side_mounted_stereo_camera_shows_no_false_cliff(told: tuple[float, float, float]) -> None:
    # A real legged robot's depth camera (shared spot_bags): its floor from the calibration tool (any mounting
    # roll), then the pipeline told that pose, or 5 cm / 1 deg off, with the stereo preset, 8 frames at 10 Hz.
    if not os.path.isdir(os.path.join(REAL, "spot_bags")):
        pytest.skip("no ../shared/data/real/spot_bags")
    from kinect_pipeline.tools.calibrate import fit_floor

    depth = _spot_depth()
    cam = kp.Camera(424, 240, 213.0, 213.0, 212.0, 120.0)  # a D4xx's depth at 424x240 (the bag has no CameraInfo)
    floor = fit_floor(np.where(depth > 0, depth / 1000.0, np.inf).astype(np.float32), cam)
    assert floor["found"] and floor["floor_fraction"] > 0.3 and abs(floor["roll"]) > 60 * DEG, floor
    cfg = kp.Config(
        sensor_model="realsense_d4xx",
        sensor_height=floor["height"] + told[0],
        sensor_pitch=floor["pitch"] + told[1] * DEG,
        sensor_roll=floor["roll"] + told[2] * DEG,
        ceiling_height=2.0,
        cliff_scan=True,
    )
    pipe = kp.Pipeline(cam, cfg)
    for i in range(8):
        res = pipe.process(depth, stamp=i / 10)
        assert not np.isfinite(res.cliff_ranges).any(), (i, res.floor_fit)
    assert res.floor_fit.accepted, res.floor_fit
    assert abs(res.pose.height - floor["height"]) < 0.02 and abs(res.pose.pitch - floor["pitch"]) < 0.5 * DEG
    # Most of what the calibration calls floor is removed as floor.
    assert res.counts["floor"] >= 0.9 * floor["floor_fraction"] * (depth > 0).sum(), (res.counts, floor)


def test_the_evidence_rule_can_be_turned_off() -> None:
    # cliff_min_drop = 0: every below-floor pixel counts, as before the rule.
    fr = render_frame(RS_CAM, furniture_scene(), RS_HEIGHT, RS_PITCH, RS_ROLL, "16UC1", seed=1, stereo=True)
    base = dict(sensor_model="realsense_d4xx", sensor_height=RS_HEIGHT, sensor_pitch=RS_PITCH, sensor_roll=RS_ROLL)
    off = kp.Pipeline(RS_CAM, kp.Config(cliff_min_drop=0.0, **base)).process(fr.depth)
    on = kp.Pipeline(RS_CAM, kp.Config(**base)).process(fr.depth)
    assert np.isfinite(on.cliff_ranges).sum() <= np.isfinite(off.cliff_ranges).sum()
    with pytest.raises(ValueError, match="cliff_min_drop"):
        kp.Config(cliff_min_drop=-0.01).validate()


@pytest.mark.parametrize("encoding", ["16UC1", "32FC1"])
def test_the_fast_paths_give_the_plain_paths_labels_on_real_frames(encoding: str) -> None:
    """The shared RealSense frames at their mount's roll (10 deg: every row labelled pixel by pixel), a small roll
    (a base's IMU: rows of one floor-profile step, and rows by runs of steps), level and upside down, with a floor
    profile restored: the fast paths (the lift by runs, the thresholds' gather, the float opening's vectors, the
    labelling by value) give the reference paths' labels and cleaned depth bit for bit, and the scan but for the few
    beams a pixel within float rounding of a bin's border moves (the reference bins by the pixels' centres)."""
    frames = real_realsense()[:3]
    for roll in (RS_ROLL, 0.002, 0.0, math.pi):
        cfg = kp.Config(
            sensor_height=RS_HEIGHT, sensor_pitch=RS_PITCH, sensor_roll=roll, cliff_scan=True,
            floor_profile_max=0.1, floor_learn_time=0.0,
        )  # fmt: skip
        fast, plain = kp.Pipeline(RS_CAM, cfg), kp.Pipeline(RS_CAM, cfg, reference_paths=True)
        state = list(fast.floor_state)
        bands = (len(state) - 8) // 2
        state[7 : 7 + bands] = [(0.02 if k % 2 else -0.02) * (k + 1) for k in range(bands)]  # metres of lift
        state[7 + bands : 7 + 2 * bands] = [1.0] * bands
        fast.floor_state = plain.floor_state = tuple(state)
        cfg.floor_profile_max = 0.0
        none = kp.Pipeline(RS_CAM, cfg)
        lifted = 0
        for i, mm in enumerate(frames):
            depth = mm if encoding == "16UC1" else np.where(mm > 0, mm / 1000.0, np.nan).astype(np.float32)
            a = fast.process(depth, base_pitch=0.01 * i, stamp=i / 30)
            b = plain.process(depth, base_pitch=0.01 * i, stamp=i / 30)
            where = f"{encoding}, roll {roll}, frame {i}"
            assert np.array_equal(a.labels, b.labels), where
            assert np.asarray(a.depth).tobytes() == np.asarray(b.depth).tobytes(), where
            x, y = (np.nan_to_num(r.ranges, nan=-1.0, posinf=1e9) for r in (a, b))
            assert int(np.sum(~np.isclose(x, y, rtol=1e-5, atol=0.0))) <= 4, where  # 2 seen at most
            lifted += int(np.sum(a.labels != none.process(depth, base_pitch=0.01 * i, stamp=i / 30).labels))
        assert lifted > 1000, f"roll {roll}: the profile changed {lifted} labels: the lift would not be reached"
