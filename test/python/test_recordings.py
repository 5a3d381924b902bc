"""Recordings as robots make them (issue 28, the tools' side): bags without CameraInfo or tf, a PNG ``compressed``
depth topic, folders of colour and depth frames, a handheld moving sequence, cameras mounted at any roll. On the
real recordings in ../shared/data/real (read from there) and on rendered frames of a camera rolled 90 deg."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from clitool import cli

import kinect_pipeline as kp
from kinect_pipeline import _core

pytest.importorskip("rosbags")
cv2 = pytest.importorskip("cv2")

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
SPOT = REAL / "spot_bags"
KITCHEN = REAL / "7scenes_kitchen" / "frames"
LOWCAM = REAL / "realsense_lowcam"
#: The Spot's front-left depth camera: not in its bags; a RealSense-like 424x240 (half of 848x480).
SPOT_K = "213,213,212,120"
KITCHEN_K = "585,585,320,240"
needs_real = pytest.mark.skipif(not SPOT.exists() or not KITCHEN.exists(), reason="no ../shared/data/real")


def _depth(bag: Path, topic_part: str = "/depth/") -> np.ndarray:
    from kinect_pipeline.bags.messages import depth_array
    from kinect_pipeline.bags.reader import open_bag

    with open_bag(bag) as b:
        for conn, _, raw in b.messages():
            if topic_part in conn.topic:
                return depth_array(b.decode(conn, raw))
    raise AssertionError(f"no depth in {bag}")


# -- row 1: a bag without CameraInfo --------------------------------------------------------------------------------


@needs_real
@pytest.mark.parametrize("command", ["replay", "report", "calibrate"])
def test_no_camera_info_names_the_bags_topics_and_what_to_give(command: str, tmp_path: Path) -> None:
    args = {
        "replay": ["replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "o.bag"), "--quiet"],
        "report": ["report", str(SPOT / "raw.bag"), "-o", str(tmp_path / "rep"), "--quiet"],
        "calibrate": ["calibrate", "--bag", str(SPOT / "raw.bag")],
    }[command]
    r = cli(*args)
    assert r.returncode == 1, r.stderr
    err = r.stderr.strip()
    assert "the bag has no CameraInfo" in err and "/spot/depth/frontleft/image [Image]" in err, err
    assert "--intrinsics" in err and "--sensor-model" in err, err
    assert "--info-topic" not in err, "no advice to name a topic the bag does not have"
    assert not list(tmp_path.iterdir()), "nothing written"


@needs_real
def test_intrinsics_numbers_and_a_camera_info_yaml_give_the_same_replay(tmp_path: Path) -> None:
    yaml_file = tmp_path / "frontleft.yaml"
    yaml_file.write_text(
        "image_width: 424\nimage_height: 240\ncamera_name: frontleft\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [213, 0, 212, 0, 213, 120, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n"
        "  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
    )
    outs = {}
    for name, intr in (("commas", [SPOT_K]), ("spaces", SPOT_K.split(",")), ("yaml", [str(yaml_file)])):
        out = tmp_path / f"{name}.bag"
        r = cli("replay", str(SPOT / "raw.bag"), "-o", str(out), "--quiet", "--intrinsics", *intr)
        assert r.returncode == 0, r.stderr
        assert "1 of 1 frames" in r.stdout and "camera: intrinsics from" in r.stdout, r.stdout
        assert "WARNING" in r.stderr and "default pose" in r.stderr, "no tf: the made-up pose is said"
        outs[name] = _scan(out)
    np.testing.assert_array_equal(outs["commas"], outs["spaces"])
    np.testing.assert_array_equal(outs["commas"], outs["yaml"])
    other = tmp_path / "other.bag"
    assert (
        cli("replay", str(SPOT / "raw.bag"), "-o", str(other), "--quiet", "--intrinsics", "150,150,212,120").returncode
        == 0
    )
    assert not np.array_equal(np.nan_to_num(_scan(other)), np.nan_to_num(outs["commas"])), "the intrinsics are used"


def _scan(bag: Path) -> np.ndarray:
    from kinect_pipeline.bags.reader import open_bag

    with open_bag(bag) as b:
        for conn, _, raw in b.messages():
            if conn.topic.endswith("/scan"):
                return np.array(b.decode(conn, raw).ranges)
    raise AssertionError(f"no scan in {bag}")


@needs_real
def test_bad_intrinsics_are_named(tmp_path: Path) -> None:
    r = cli("replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "o.bag"), "--intrinsics", f"{SPOT_K},640,480")
    assert r.returncode == 1 and "intrinsics for 640x480 images, but the depth images are 424x240" in r.stderr
    r = cli("replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "o.bag"), "--intrinsics", "213,213,212")
    assert r.returncode == 1 and "3 numbers: expected FX FY CX CY" in r.stderr, r.stderr
    (tmp_path / "bad.yaml").write_text("image_width: 424\n")
    r = cli("replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "o.bag"), "--intrinsics", str(tmp_path / "bad.yaml"))
    assert r.returncode == 1 and "not a camera_info YAML" in r.stderr, r.stderr
    assert not list(tmp_path.glob("*.bag"))


@needs_real
def test_the_sensor_models_nominal_camera_comes_with_a_warning(tmp_path: Path) -> None:
    r = cli(
        "replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "o.bag"), "--quiet", "--sensor-model", "realsense_d4xx"
    )
    assert r.returncode == 0, r.stderr
    assert "WARNING: no camera intrinsics given: the nominal camera of --sensor-model realsense_d4xx" in r.stderr
    assert "scaled to 424x240" in r.stderr
    r = cli("replay", str(SPOT / "raw.bag"), "-o", str(tmp_path / "p.bag"), "--quiet", "--sensor-model", "kinect_v2")
    assert r.returncode == 1 and "another aspect ratio" in r.stderr, r.stderr


@needs_real
def test_report_and_calibrate_bag_use_the_intrinsics(tmp_path: Path) -> None:
    """They took --intrinsics and ignored it; now the floor each finds moves with them."""
    heights = []
    for k in (SPOT_K, "300,300,212,120"):
        r = cli("calibrate", "--bag", str(SPOT / "raw.bag"), "--intrinsics", k, "--json")
        assert r.returncode == 0, r.stderr
        d = json.loads(r.stdout)
        assert d["camera"].startswith("intrinsics from --intrinsics") and d["summary"]["frames_with_tf"] == 0
        heights.append(d["summary"]["floor"]["height"])
    assert abs(heights[0] - heights[1]) > 0.05, heights
    r = cli("report", str(SPOT / "raw.bag"), "-o", str(tmp_path / "rep"), "--quiet", "--intrinsics", SPOT_K)
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout[: r.stdout.rindex("}") + 1])
    assert summary["camera"].startswith("intrinsics from --intrinsics") and summary["frames"] == 1
    assert "each frame's own floor" in summary["pose"], "no tf, no pose given: the floor's pose, not a made-up one"


def test_given_intrinsics_win_over_the_bags_camera_info(tmp_path: Path) -> None:
    from kinect_pipeline.intrinsics import Intrinsics
    from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag
    from kinect_pipeline.tools.calibrate import check_tf

    bag = tmp_path / "b.bag"
    write_sequence_bag(bag, Scenario(frames=2, encoding="16UC1", seed=4, extras=False))
    cam = kp.kinect_v2_camera()
    own = check_tf(bag)
    told = check_tf(bag, intrinsics=Intrinsics(cam.fx * 1.3, cam.fy * 1.3, cam.cx, cam.cy))
    assert own.camera.startswith("camera_info on") and told.camera == "intrinsics from --intrinsics"
    assert abs(own.frames[0]["diff_height"]) < 0.01 < abs(told.frames[0]["diff_height"]), (own.frames, told.frames)


# -- row 4: image_transport's compressed plugin on 16-bit depth ---------------------------------------------------


@needs_real
def test_png_compressed_16bit_depth_decodes_as_the_raw_image(tmp_path: Path) -> None:
    raw = _depth(SPOT / "raw.bag")
    np.testing.assert_array_equal(_depth(SPOT / "compressed.bag"), raw)
    np.testing.assert_array_equal(_depth(SPOT / "compressedDepth.bag"), raw)
    scans = []
    for name in ("raw", "compressed", "compressedDepth"):
        out = tmp_path / f"{name}.bag"
        r = cli("replay", str(SPOT / f"{name}.bag"), "-o", str(out), "--quiet", "--intrinsics", SPOT_K)
        assert r.returncode == 0, r.stderr
        scans.append(np.nan_to_num(_scan(out), nan=-1.0))
    np.testing.assert_array_equal(scans[0], scans[1])
    np.testing.assert_array_equal(scans[0], scans[2])


@needs_real
def test_a_compressed_format_that_is_not_depth_is_named_with_what_is_read(tmp_path: Path) -> None:
    r = cli(
        "replay",
        str(SPOT / "compressed.bag"),
        "-o",
        str(tmp_path / "o.bag"),
        "--intrinsics",
        SPOT_K,
        "--depth-topic",
        "/spot/camera/frontleft/image/compressed",
    )
    assert r.returncode == 1
    assert "'mono8; jpeg compressed ': not a depth image this package reads" in r.stderr, r.stderr
    assert "'16UC1; png compressed' and 'mono16; png compressed'" in r.stderr and "compressedDepth" in r.stderr


# -- row 3: folders of colour and depth frames ---------------------------------------------------------------------


@needs_real
def test_a_folder_of_colour_and_depth_frames_takes_the_depth_ones(tmp_path: Path) -> None:
    r = cli("calibrate", str(KITCHEN), "--intrinsics", KITCHEN_K, "--json")
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "colour" in ln]
    assert len(lines) == 1 and "3 colour image(s) skipped" in lines[0] and "50 depth frame(s) taken" in lines[0], lines
    assert len(json.loads(r.stdout)["frames"]) == 50
    r = cli("calibrate", str(LOWCAM), "--intrinsics", "617.25,617.549,317.392,245.980")
    assert r.returncode == 1 and "its folders: color, depth" in r.stderr, r.stderr
    only_colour = tmp_path / "c"
    only_colour.mkdir()
    shutil.copy(LOWCAM / "color" / "000000.png", only_colour)
    r = cli("calibrate", str(only_colour), "--intrinsics", "617.25,617.549,317.392,245.980")
    assert r.returncode == 1 and "without depth frames" in r.stderr and "only 1 colour" in r.stderr, r.stderr


# -- row 2: report on a moving sequence ----------------------------------------------------------------------------


@needs_real
def test_report_of_a_handheld_sequence_gives_each_frame_its_own_floor(tmp_path: Path) -> None:
    """7-Scenes' kitchen: a handheld Kinect v1. One mean pose drew the floor as obstacles; now each frame is at
    its own floor's pose, frames with no floor of their own (counters fill them) are left out, and the floor of
    every frame reported is labelled floor."""
    from kinect_pipeline.evaluation.report import Collected, collect_frames, floor_poses
    from kinect_pipeline.tools.calibrate import calibrate, frame_paths, load_depth

    files = frame_paths([KITCHEN])
    cam = _core.Camera(640, 480, 585, 585, 320, 240)
    c = collect_frames(files, cam, show_progress=False)
    assert c.pose_note.startswith("pose per frame, each from its own floor"), c.pose_note
    assert 0 < len(c.frames) < len(files)
    assert any("frames left out: no floor of their own" in w for w in c.warnings), c.warnings
    frames = [(str(f), load_depth(f)) for f in files]
    poses = floor_poses(frames, cam, Collected("x"))
    used = [(f, p) for f, p in zip(frames, poses, strict=True) if p is not None]
    assert len({p for _, p in used}) == len(used), "a pose per frame"
    mean = calibrate(frames, cam)
    floor = _core.LABELS["floor"]
    for (name, metres), pose in used:
        own = (
            np.asarray(
                _core.Pipeline(cam, _core.Config(sensor_height=pose[0], sensor_pitch=pose[1], sensor_roll=pose[2]))
                .process(metres)
                .labels
            )
            == floor
        ).mean()
        fit = calibrate([(name, metres)], cam)
        assert own >= 0.8 * fit.floor_fraction * (metres > 0).mean(), (name, own, fit.floor_fraction)
    worst = min(
        (
            np.asarray(
                _core.Pipeline(
                    cam, _core.Config(sensor_height=mean.height, sensor_pitch=mean.pitch, sensor_roll=mean.roll)
                )
                .process(m)
                .labels
            )
            == floor
        ).mean()
        for _, m in frames
    )
    assert worst < 0.01, "the mean pose loses the floor of some frame: the case this guards"
    r = cli("report", str(KITCHEN), "-o", str(tmp_path / "rep"), "--quiet", "--intrinsics", KITCHEN_K)
    assert r.returncode == 0, r.stderr
    assert "pose per frame" in r.stdout and "3 colour image(s) skipped" in r.stderr
    assert "WARNING: " in r.stderr and "frames left out" in r.stderr


def test_report_refuses_frames_without_any_floor(tmp_path: Path) -> None:
    wall = np.full((424, 512), 1500, np.uint16)  # a wall straight ahead: no floor
    cv2.imwrite(str(tmp_path / "w.png"), wall)
    r = cli("report", str(tmp_path / "w.png"), "-o", str(tmp_path / "rep"), "--quiet", "--sensor-model", "kinect_v2")
    assert r.returncode == 1 and "no floor found" in r.stderr, r.stderr
    assert not (tmp_path / "rep").exists()


# -- row 6: calibrate at any mounting roll ---------------------------------------------------------------------------


@pytest.mark.parametrize("roll_deg", [-180, -150, -90, -80, -45, 0, 30, 45, 60, 80, 90, 160, 180])
def test_calibrate_finds_the_floor_at_any_roll_and_widening_never_loses_it(tmp_path: Path, roll_deg: float) -> None:
    from kinect_pipeline.simulation.scenes import lab_scene, render_frame

    cam = kp.kinect_v2_camera()
    f = render_frame(cam, lab_scene(), 1.0, 0.3, math.radians(roll_deg), "16UC1", seed=5)
    path = tmp_path / "f.png"
    cv2.imwrite(str(path), f.depth)
    for tilt in ("40", "60", "85", "90"):
        r = cli(
            "calibrate", str(path), "--intrinsics", f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}", "--max-tilt", tilt, "--json"
        )
        assert r.returncode == 0, (tilt, r.stderr)
        d = json.loads(r.stdout)
        assert abs(d["height"] - 1.0) < 0.01 and abs(d["pitch_deg"] - math.degrees(0.3)) < 0.3, (tilt, d)
        assert abs(math.remainder(d["roll_deg"] - roll_deg, 360.0)) < 0.3, (tilt, d)


@needs_real
def test_the_spot_camera_rolled_about_80_deg_is_found_and_a_wrong_plane_is_refused() -> None:
    for tilt in ("40", "60", "85", "90"):
        r = cli("calibrate", "--bag", str(SPOT / "raw.bag"), "--intrinsics", SPOT_K, "--max-tilt", tilt, "--json")
        assert r.returncode == 0, r.stderr
        f = json.loads(r.stdout)["frames"][0]
        assert f["found"] and 70 < math.degrees(f["floor_roll"]) < 90 and f["floor_fraction"] > 0.4, (tilt, f)
    # the kitchen's counters: refused by name, never averaged in
    r = cli("calibrate", *(str(KITCHEN / f"frame-0001{i}.depth.png") for i in (51, 52, 53)), "--intrinsics", KITCHEN_K)
    assert r.returncode == 1 and "below it: a table or counter, not the floor" in r.stderr, r.stderr


def test_many_weak_fits_are_one_line() -> None:
    from kinect_pipeline.tools.calibrate import weak_fits

    fit = {
        "floor_fraction": 0.06,
        "floor_pixels": 5000,
        "rms": 0.01,
        "height_std": 0.001,
        "pitch_std": 0.001,
        "roll_std": 0.001,
    }
    lines = weak_fits([{**fit, "file": f"f{i}.png"} for i in range(31)])
    assert len(lines) == 1 and lines[0].startswith("31 of 31 frames have a weak floor fit (a small floor: 31"), lines
    assert len(weak_fits([{**fit, "file": f"f{i}.png"} for i in range(2)])) == 2


# -- row 7: a camera rolled 90 deg through the whole pipeline ------------------------------------------------------


def test_a_camera_rolled_90_deg_through_the_pipeline_and_calibrate(tmp_path: Path) -> None:
    """A portrait-mounted camera: labels against the ground truth, the scan in the gravity-aligned frame against
    the true nearest obstacle, a hole seen as a cliff, and calibrate recovering the mounting, through the binding
    and the command line."""
    from kinect_pipeline.evaluation.metrics import missed_beams, phantom_beams
    from kinect_pipeline.simulation.scenes import FLOOR, KEPT, Scene, ideal_scan, lab_scene, render_frame, truth_labels

    cam = kp.kinect_v2_camera()
    roll, pitch, height = math.pi / 2, math.radians(20), 0.9
    f = render_frame(cam, lab_scene(), height, pitch, roll, "32FC1", seed=None)
    cfg = _core.Config(sensor_height=height, sensor_pitch=pitch, sensor_roll=roll)
    res = _core.Pipeline(cam, cfg).process(np.ascontiguousarray(f.depth))
    truth = truth_labels(f.truth)
    assert (f.truth["object"] == FLOOR).mean() > 0.3
    assert (np.asarray(res.labels) == truth).mean() > 0.98
    ranges = np.asarray(res.ranges)
    ideal = ideal_scan(f.truth, res.angle_min, res.angle_increment, len(ranges), truth == KEPT)
    assert np.isfinite(ranges).sum() > 0.3 * len(ranges)
    assert phantom_beams(ranges, ideal)[1].sum() == 0 and missed_beams(ranges, ideal).mean() < 0.01
    # the scan lies in the gravity-aligned frame: the desk's front edge at x = 3.2 m straight ahead
    a = res.angle_min + res.angle_increment * np.arange(len(ranges))
    ahead = np.isfinite(ranges) & (np.abs(a) < 0.05)
    at_desk = np.abs(ranges[ahead] * np.cos(a[ahead]) - 3.2) < 0.02
    assert ahead.sum() > 20 and at_desk.mean() > 0.9, ranges[ahead]  # 2 of 42 beams see past its 4 cm edge
    # a hole in the floor ahead shows in the cliff scan
    hole = Scene(boxes=lab_scene().boxes, holes=((1.5, 2.0, -0.3, 0.3),), ceiling=2.8)
    g = render_frame(cam, hole, height, pitch, roll, "32FC1", seed=None)
    cliff = np.asarray(_core.Pipeline(cam, cfg).process(np.ascontiguousarray(g.depth)).cliff_ranges)
    near = np.isfinite(cliff) & (np.abs(a) < 0.1)
    assert near.any() and np.all((cliff[near] > 1.4) & (cliff[near] < 2.1)), cliff[near]
    # calibrate, through the binding and the command line
    from kinect_pipeline.tools.calibrate import calibrate

    noisy = render_frame(cam, lab_scene(), height, pitch, roll, "16UC1", seed=8)
    cal = calibrate([("f", noisy.metres.astype(np.float32))], cam)
    assert cal.found and abs(cal.height - height) < 0.01 and abs(math.degrees(cal.roll - roll)) < 0.3
    path = tmp_path / "portrait.png"
    cv2.imwrite(str(path), noisy.depth)
    r = cli("calibrate", str(path), "--intrinsics", f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert abs(d["roll_deg"] - 90) < 0.3 and abs(d["pitch_deg"] - 20) < 0.3 and abs(d["height"] - height) < 0.01


# -- row 8: an upside-down camera ------------------------------------------------------------------------------------


@pytest.mark.parametrize("roll_deg", [180.0, 176.0, -177.0])
def test_an_upside_down_camera_through_the_pipeline(roll_deg: float) -> None:
    """A camera mounted upside down (roll 180 deg, or a few degrees either side): labels against the ground truth,
    the scan against the true nearest obstacle, a hole as a cliff; and the same frame turned a half turn, seen by the
    camera turned with it at roll - 180 deg, gives the same labels (turned back) and the same scan."""
    from kinect_pipeline.evaluation.metrics import missed_beams, phantom_beams
    from kinect_pipeline.simulation.scenes import FLOOR, KEPT, Scene, ideal_scan, lab_scene, render_frame, truth_labels
    from kinect_pipeline.tools.calibrate import rotated

    cam = kp.kinect_v2_camera()
    roll, pitch, height = math.radians(roll_deg), math.radians(18), 1.1
    scene = Scene(boxes=lab_scene().boxes, holes=((1.5, 2.0, -0.3, 0.3),), ceiling=2.8)
    f = render_frame(cam, scene, height, pitch, roll, "16UC1", seed=None)
    cfg_kw = {"sensor_height": height, "sensor_pitch": pitch, "sensor_roll": roll, "refine_floor": False}
    res = _core.Pipeline(cam, _core.Config(**cfg_kw)).process(np.ascontiguousarray(f.depth))
    labels, ranges = np.asarray(res.labels), np.asarray(res.ranges)
    truth = truth_labels(f.truth)
    assert (f.truth["object"] == FLOOR).mean() > 0.3
    assert (labels == truth).mean() > 0.98
    ideal = ideal_scan(f.truth, res.angle_min, res.angle_increment, len(ranges), truth == KEPT)
    assert np.isfinite(ranges).sum() > 0.3 * len(ranges)
    assert phantom_beams(ranges, ideal)[1].sum() == 0 and missed_beams(ranges, ideal).mean() < 0.01
    a = res.angle_min + res.angle_increment * np.arange(len(ranges))
    cliff = np.asarray(res.cliff_ranges)
    near = np.isfinite(cliff) & (np.abs(a) < 0.1)
    assert near.any() and np.all((cliff[near] > 1.4) & (cliff[near] < 2.1)), cliff[near]
    # the half turn: the same camera rolled by -180 deg
    depth2, cam2 = rotated(f.depth, cam, 2)
    cfg2_kw = {**cfg_kw, "sensor_roll": math.remainder(roll - math.pi, 2 * math.pi)}
    res2 = _core.Pipeline(cam2, _core.Config(**cfg2_kw)).process(depth2)
    assert (np.rot90(np.asarray(res2.labels), 2) == labels).mean() > 0.9999
    r2 = np.asarray(res2.ranges)
    assert np.array_equal(np.isfinite(r2), np.isfinite(ranges))
    both = np.isfinite(r2) & np.isfinite(ranges)
    assert np.abs(r2[both] - ranges[both]).max() < 1e-3
    # the thesis's column projection (each column one bearing): upside down its columns' bearings are mirrored
    # (before, its scan came out left for right)
    col = [
        np.asarray(_core.Pipeline(c, _core.Config(projection="column", **kw)).process(d).ranges)
        for c, d, kw in ((cam, np.ascontiguousarray(f.depth), cfg_kw), (cam2, depth2, cfg2_kw))
    ]
    seen = np.isfinite(col[0])
    assert np.array_equal(seen, np.isfinite(col[1])) and seen.sum() > 0.3 * len(seen)
    assert np.abs(col[0][seen] - col[1][seen]).max() < 1e-3


def test_an_upside_down_mounting_is_calibrated_and_its_frames_averaged_across_180_deg(tmp_path: Path) -> None:
    """Frames of an upside-down camera whose rolls lie either side of 180 deg: each is found at its roll, and their
    mean lies at 180 deg (not at 0, where a plain mean of 179 and -179 lands); through the binding and the CLI."""
    from kinect_pipeline.simulation.scenes import lab_scene, render_frame
    from kinect_pipeline.tools.calibrate import calibrate

    cam = kp.kinect_v2_camera()
    rolls = [179.0, -179.5, 179.5]
    frames = [
        render_frame(cam, lab_scene(), 1.0, 0.3, math.radians(r), "16UC1", seed=3 + i) for i, r in enumerate(rolls)
    ]
    cal = calibrate([(f"f{i}", f.metres.astype(np.float32)) for i, f in enumerate(frames)], cam)
    assert cal.found and abs(cal.height - 1.0) < 0.01 and abs(math.degrees(cal.pitch) - math.degrees(0.3)) < 0.3
    assert abs(math.remainder(math.degrees(cal.roll) - 179.67, 360.0)) < 0.3, cal
    assert math.degrees(cal.roll_std) < 1.0, cal
    assert any("roll spans 179.0..180.5 deg" in w for w in cal.warnings), cal.warnings  # 1.5 deg apart, not 358
    assert any("only to a camera mounted upside down" in w for w in cal.warnings), cal.warnings
    paths = []
    for i, f in enumerate(frames):
        paths.append(str(tmp_path / f"f{i}.png"))
        cv2.imwrite(paths[-1], f.depth)
    r = cli("calibrate", *paths, "--intrinsics", f"{cam.fx},{cam.fy},{cam.cx},{cam.cy}", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    told = dict(a.split(":=") for a in d["launch_args"].split())
    assert (
        abs(math.remainder(d["roll_deg"] - 179.67, 360.0)) < 0.3 and abs(float(told["sensor_roll"]) - d["roll"]) < 1e-4
    )
    assert "3 of 3 frames (f0.png, f1.png, f2.png) show their floor only to a camera mounted upside down" in r.stderr


def test_a_ceiling_seen_by_an_upright_camera_is_not_silently_taken_for_an_upside_down_floor() -> None:
    """The half-turn search's known twin: an upright camera looking up at a ceiling, with no floor in view, sees
    what an upside-down camera sees of a floor. calibrate cannot tell them apart, so it says so."""
    from kinect_pipeline.simulation.scenes import Scene, render_frame
    from kinect_pipeline.tools.calibrate import calibrate

    cam = kp.kinect_v2_camera()
    f = render_frame(cam, Scene(ceiling=2.4), 1.2, math.radians(-40), 0.0, "16UC1", seed=3)
    cal = calibrate([("ceiling.png", f.metres.astype(np.float32))], cam)
    assert cal.found and abs(abs(math.degrees(cal.roll)) - 180) < 0.5 and abs(cal.height - 1.2) < 0.01
    assert cal.warnings == [
        "1 of 1 frames (ceiling.png) show their floor only to a camera mounted upside down (roll near 180 deg): a "
        "ceiling seen by an upright camera that sees no floor looks the same; check the mounting"
    ]


REAL_FLOORS = [
    ("tum_nyu_sun_open3d/NYU_depth_mm.png", (582.6, 582.7, 313.0, 238.4), 0.001),
    ("tum_nyu_sun_open3d/TUM_depth.png", (525.0, 525.0, 319.5, 239.5), 0.0002),
    ("slambook2/ch7/1_depth.png", (520.9, 521.0, 325.1, 249.7), 0.0002),
]


@pytest.mark.parametrize(("name", "intr", "scale"), REAL_FLOORS)
def test_a_real_frame_turned_upside_down_gives_the_same_floor_and_scan(name: str, intr: tuple, scale: float) -> None:
    """A real frame turned a half turn is what the camera would have seen mounted upside down (its principal point
    turned with it): calibrate finds the same height and pitch and the roll 180 deg away, and the pipeline at each
    pose gives the same labels (turned) and the same scan."""
    from kinect_pipeline.tools.calibrate import calibrate, depth_metres, rotated

    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path} not available")
    raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    metres = depth_metres(raw, scale, 12.0, name)
    cam = _core.Camera(raw.shape[1], raw.shape[0], *intr)
    up = calibrate([("up", metres)], cam)
    m2, cam2 = rotated(metres, cam, 2)
    down = calibrate([("down", m2)], cam2)
    assert up.found and down.found
    assert abs(down.height - up.height) < 0.005 and abs(math.degrees(down.pitch - up.pitch)) < 0.1
    assert abs(math.degrees(math.remainder(down.roll - up.roll - math.pi, 2 * math.pi))) < 0.1
    assert abs(math.degrees(down.roll)) > 150
    # the refinement's grid of sampled pixels does not turn with the frame; the beams' span, the camera's, turns
    # with its principal point unless it is given
    fixed = {"refine_floor": False, "scan_fov": 1.0, "scan_beams": 500}
    res = [
        _core.Pipeline(c, _core.Config(sensor_height=up.height, sensor_pitch=up.pitch, sensor_roll=r, **fixed)).process(
            m
        )
        for m, c, r in ((metres, cam, up.roll), (m2, cam2, math.remainder(up.roll + math.pi, 2 * math.pi)))
    ]
    assert (np.rot90(np.asarray(res[1].labels), 2) != np.asarray(res[0].labels)).sum() <= 10  # 0 when written
    a, b = np.asarray(res[0].ranges), np.asarray(res[1].ranges)
    assert np.array_equal(np.isfinite(a), np.isfinite(b)) and np.isfinite(a).sum() > 50
    both = np.isfinite(a)
    # a pixel whose centre lies within float rounding of a beam's border may fall to either beam (the bearings run
    # the other way across the turned image): a few beams at most, at an edge
    assert (np.abs(a[both] - b[both]) > 0.001).sum() <= 2, np.abs(a - b)[both]  # 0 when this was written
