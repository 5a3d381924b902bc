"""The node and the nodelet as a robot builder meets them on the first day (issue 21), and the floor refinement's
ROS side (issue 19): through a real roscore (the test's own, on a free loopback port), roslaunch with the package's
launch files as the README shows them, the real nodelet manager and real bags. A feeder process
(test/ros/feeder.py) publishes rendered frames and records what the node publishes; every process is stopped by
its own PID; every wait has a deadline."""

from __future__ import annotations

import itertools
import math
import os
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_graph import NODE, ROOT, RosGraph, newest, wait_for

import kinect_pipeline as kp
from kinect_pipeline.simulation.scenes import boxes_scene, kinect_sigma, lab_scene, render_frame

CAM = kp.Camera(512, 424, 365.0, 365.0, 255.5, 211.5)
HEIGHT, TILT = 1.1, 0.26
BAG = ROOT / "build" / "cmake" / "test_data" / "replay_16uc1.bag"
PROC = "processing"
FLOOR = "floor refinement"
RATE = "Frequency Status"

pytestmark = pytest.mark.skipif(not NODE.exists(), reason="no build: run scripts/quickstart.sh first")


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosGraph]:
    g = RosGraph(tmp_path_factory.mktemp("roscore"))
    g.start_core()
    yield g
    g.stop_all()


@pytest.fixture
def ros(shared: RosGraph, tmp_path: Path) -> Iterator[RosGraph]:
    """The module's roscore, with this test's processes and logs; what they leave on the server is removed."""
    shared.reset_params()
    g = shared.session(tmp_path)
    yield g
    g.stop_all()
    shared.reset_params()


@pytest.fixture
def sim(tmp_path: Path) -> Iterator[RosGraph]:
    """A roscore of this test's own with use_sim_time set before anything starts."""
    g = RosGraph(tmp_path)
    g.start_core(sim_time=True)
    yield g
    g.stop_all()


def yaml_file(path: Path, **values: Any) -> str:
    path.write_text("".join(f"{k}: {v!r}\n" if isinstance(v, str) else f"{k}: {v}\n" for k, v in values.items()))
    return str(path)


def ranges(scan: dict[str, Any]) -> np.ndarray:
    return np.array([np.nan if r is None else r for r in scan["ranges"]], np.float32)


def same(scan: dict[str, Any], want: np.ndarray) -> bool:
    got = ranges(scan)
    return bool(np.all(np.isclose(got, want, rtol=1e-5, atol=1e-6) | (np.isnan(got) & np.isnan(want))))


def core_ranges(depth: np.ndarray, pitch: float, height: float = HEIGHT, **cfg: Any) -> np.ndarray:
    pipe = kp.Pipeline(CAM, kp.Config(sensor_height=height, sensor_pitch=pitch, refine_floor=False, **cfg))
    return np.asarray(pipe.process(depth).ranges, np.float32)


def frame(encoding: str = "16UC1", pitch: float = TILT) -> np.ndarray:
    return render_frame(CAM, boxes_scene(), HEIGHT, pitch, 0.0, encoding, seed=None).depth


def lines(text: str, *words: str) -> list[str]:
    return [ln for ln in text.splitlines() if all(w in ln for w in words)]


def start_manager(ros: RosGraph, name: str, ns: str | None = None) -> None:
    args = ["rosrun", "nodelet", "nodelet", "manager", f"__name:={name}"] + ([f"__ns:={ns}"] if ns else [])
    ros.start(f"manager_{name}", *args)
    full = f"{ns or ''}/{name}".replace("//", "/")
    wait_for(f"manager {full}", lambda: ros.has_service(full + "/load_nodelet"), timeout=60)


def node_log(ros: RosGraph) -> str:
    """What the node printed: the launch's output, or for the nodelet its manager's."""
    return ros.log("launch") + ros.log("manager_kinect2_manager")


def manager_args(ros: RosGraph, kind: str) -> list[str]:
    """The launch arguments for the standalone node, or for the nodelet in a manager started here."""
    if kind == "node":
        return []
    start_manager(ros, "kinect2_manager")
    return ["manager:=kinect2_manager"]


def launch_exact(ros: RosGraph, tmp_path: Path, kind: str, *args: str) -> None:
    """The launch file, node or nodelet, at the static pose the frames are rendered at, without refinement: its
    scans are then the core's on the same frames."""
    manager = manager_args(ros, kind)
    params = yaml_file(tmp_path / "p.yaml", refine_floor=False)
    ros.launch(
        "launch",
        "kinect_pipeline.launch",
        "pose_source:=static",
        f"sensor_pitch:={TILT}",
        f"params:={params}",
        *args,
        *manager,
    )


def exit_code(p: subprocess.Popen[bytes], timeout: float = 60.0) -> int:
    return p.wait(timeout=timeout)


# ------------------------------------------------------------------------------------------------------------ item 4
def test_rosrun_finds_the_node_and_help_prints_usage() -> None:
    env = dict(os.environ)
    for flag in ("--help", "-h"):
        r = subprocess.run(
            ["rosrun", "kinect_pipeline", "kinect_pipeline_node", flag],
            env=env,
            cwd="/",
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 0, r.stdout + r.stderr
        for word in (
            "usage:",
            "image",
            "camera_info",
            "scan",
            "cliff_scan",
            "/diagnostics",
            "pose_source",
            "sensor_height",
            "range_max",
            "refine_floor",
            "README.md",
        ):
            assert word in r.stdout, f"'{word}' not in --help:\n{r.stdout}"
        readme = re.search(r"README\.md, 'ROS interface': (\S+)", r.stdout)
        assert readme and Path(readme.group(1)).exists(), r.stdout


def test_launch_files_need_no_argument_but_the_bag() -> None:
    for launch, required in (("kinect_pipeline.launch", []), ("replay.launch", ["bag"]), ("rviz.launch", [])):
        r = subprocess.run(
            ["roslaunch", "--ros-args", "kinect_pipeline", launch],
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        listed = r.stdout.split("Optional Arguments:")[0]
        got = re.findall(r"^  (\w+):", listed.split("Required Arguments:")[-1], re.M) if "Required" in listed else []
        assert got == required, f"{launch}: required {got}\n{r.stdout}"
    args = subprocess.run(
        ["roslaunch", "--ros-args", "kinect_pipeline", "kinect_pipeline.launch"],
        capture_output=True,
        text=True,
        timeout=60,
    ).stdout
    for arg in ("num_threads", "range_min", "range_max", "pose_fallback", "pose_hold_time", "image_transport"):
        assert f"  {arg} (default" in args, arg


# ------------------------------------------------------------------------------------------------------------ item 1
@pytest.mark.parametrize("where", ["top", "camera namespace"])
def test_relative_manager_name_is_found_as_the_driver_names_it(ros: RosGraph, where: str) -> None:
    ns = None if where == "top" else "/kinect2"
    start_manager(ros, "kinect2_manager", ns)
    ros.launch(
        "launch", "kinect_pipeline.launch", "manager:=kinect2_manager", "pose_source:=static", f"sensor_pitch:={TILT}"
    )
    ros.feed("feed", "--noise-free", "--until", "len(scans) >= 3")
    full = "/kinect2/kinect2_manager" if ns else "/kinect2_manager"
    assert lines(ros.log("launch"), "loading kinect_pipeline/KinectPipelineNodelet", f"into {full}")


def test_missing_manager_is_a_clear_error_within_the_deadline(ros: RosGraph) -> None:
    start_manager(ros, "camera_nodelet_manager", "/camera")
    p = ros.launch("launch", "kinect_pipeline.launch", "manager:=kinect2_manager", "manager_timeout:=2")
    wait_for("the loader to give up", lambda: lines(ros.log("launch"), "[ERROR]", "no nodelet manager"), timeout=60)
    err = lines(ros.log("launch"), "no nodelet manager")[0]
    for word in (
        "/kinect2/kinect2_manager or /kinect2_manager",
        "within 2 s",
        "manager:=kinect2_manager",
        "running managers: /camera/camera_nodelet_manager",
    ):
        assert word in err, err
    wait_for(
        "roslaunch to report the loader's exit", lambda: lines(ros.log("launch"), "process has died", "exit code 1")
    )
    assert p.poll() is None  # roslaunch goes on; only the loader gave up


# ------------------------------------------------------------------------------------------------------------ item 2
@pytest.mark.parametrize(("kind", "encoding", "codec"), [("node", "16UC1", "png"), ("nodelet", "32FC1", "rvl")])
def test_compressed_depth_is_decoded_and_bad_payloads_are_dropped(
    ros: RosGraph, tmp_path: Path, kind: str, encoding: str, codec: str
) -> None:
    launch_exact(ros, tmp_path, kind, "image_transport:=compressedDepth")
    res = ros.feed(
        "feed",
        "--noise-free",
        "--transport",
        "compressedDepth",
        "--encoding",
        encoding,
        "--codec",
        codec,
        "--bad-payload-every",
        "5",
        "--until",
        "len(scans) >= 8 and num('dropped: bad compressedDepth payload', 'processing') >= 1",
    )
    fmt, data = kp.encode_compressed_depth(frame(encoding), codec=codec)
    want = core_ranges(kp.decode_compressed_depth(fmt, data), TILT)
    assert all(same(s, want) for s in res["scans"]), "a scan differs from the core's on the decoded frame"
    assert int(newest(res, PROC, "dropped: bad compressedDepth payload") or 0) >= 1
    # Between the first and the last scan, every good frame gave a scan and no bad one did (every 5th is bad).
    got = {s["stamp"] for s in res["scans"]}
    span = [(i, t) for i, t in enumerate(res["sent"]) if min(got) <= t <= max(got)]
    assert [i for i, t in span if (t in got) != (i % 5 != 4)] == []
    log = node_log(ros)
    assert lines(log, "frame dropped (bad compressedDepth payload)")


@pytest.mark.parametrize(("kind", "window"), [("node", (2, 2, 0, 0, 0, 0)), ("nodelet", (2, 3, 37, 20, 440, 390))])
def test_a_crop_decimate_camera_info_gives_the_windows_camera(
    ros: RosGraph, tmp_path: Path, kind: str, window: tuple[int, ...]
) -> None:
    """Images as image_proc's crop_decimate sends them: the camera_info's size and K at full resolution, its binning
    and roi set (REP 104). Before, every such frame was dropped for its size."""
    launch_exact(ros, tmp_path, kind)
    res = ros.feed("feed", "--noise-free", "--window", ",".join(map(str, window)), "--until", "len(scans) >= 3")
    bx, by, x, y, w, h = window
    k = [CAM.fx, 0, CAM.cx, 0, CAM.fy, CAM.cy, 0, 0, 1]
    cam = kp._core.camera_from_intrinsics(CAM.width, CAM.height, k, "", binning_x=bx, binning_y=by, roi=(x, y, w, h))
    w, h = (w, h) if w else (CAM.width, CAM.height)
    part = np.ascontiguousarray(frame()[y : y + h - h % by : by, x : x + w - w % bx : bx])
    assert part.shape == (cam.height, cam.width)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, refine_floor=False))
    want = np.asarray(pipe.process(part).ranges, np.float32)
    assert len(res["scans"]) >= 3 and all(same(s, want) for s in res["scans"]), "a scan differs from the core's"
    assert not int(newest(res, PROC, "dropped: image size differs from camera_info") or 0)


@pytest.mark.parametrize(
    ("kind", "image", "rectify", "said"),
    [
        ("node", "sd/image_depth", "auto", "yes (pixels move up to"),
        ("nodelet", "sd/image_depth_rect", "auto", "no (the topic's name says"),
        ("node", "sd/image_depth", "never", "no (rectify never)"),
    ],
)
def test_a_raw_topic_is_rectified_by_its_camera_infos_distortion(
    ros: RosGraph, tmp_path: Path, kind: str, image: str, rectify: str, said: str
) -> None:
    """kinect2_bridge's sd/image_depth is raw, its sd/image_depth_rect rectified, both with the IR lens's D; a
    rectified image's camera is its camera_info's P (image_proc rectifies with it), a raw one rectified here K's."""
    launch_exact(ros, tmp_path, kind, f"image:={image}", f"rectify:={rectify}")
    D = [0.0905, -0.2699, 0.0, 0.0, 0.0952]
    until = "len(scans) >= 3 and diag('rectified', 'processing') not in (None, '(no frame yet)')"
    here = said.startswith("yes")
    # The raw image is rectified here with K; the rectified one's camera is P's (image_geometry's): the other is off.
    lens = ["--distortion", ",".join(map(str, D)), "--off", "P" if here else "K"]
    res = ros.feed("feed", "--noise-free", "--image", image, *lens, "--until", until)
    assert (newest(res, PROC, "rectified") or "").startswith(said), newest(res, PROC, "rectified")
    depth = kp.DepthRectifier(CAM, "plumb_bob", D).apply(frame()) if here else frame()
    want = core_ranges(depth, TILT)
    assert len(res["scans"]) >= 3 and all(same(s, want) for s in res["scans"]), "a scan differs from the core's"
    logged = f"the images on /kinect2/{image} rectified (camera_info distortion_model 'plumb_bob', ~rectify auto): "
    said_once = [m["msg"] for m in res["logs"] if logged in m["msg"]]
    assert len(said_once) == (rectify == "auto"), said_once  # "never" does not look at the lens


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_a_transport_that_cannot_be_loaded_is_one_clear_error(ros: RosGraph, kind: str) -> None:
    manager = manager_args(ros, kind)
    ros.launch("launch", "kinect_pipeline.launch", "image_transport:=theora", *manager)
    said = wait_for("the transport error", lambda: lines(ros.log("launch"), "~image_transport = 'theora'"))
    for word in ("no image_transport plugin", "can load: raw", "compressedDepth"):
        assert word in said[0], said[0]
    assert len(said) == 1, said
    wait_for("the node / loader to exit 1", lambda: lines(ros.log("launch"), "process has died", "exit code 1"))


# ------------------------------------------------------------------------------------------------------------ item 3
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_invalid_startup_parameters_stop_the_node_naming_every_one(ros: RosGraph, tmp_path: Path, kind: str) -> None:
    manager = manager_args(ros, kind)
    params = yaml_file(
        tmp_path / "bad.yaml",
        ceiling_height=0.5,
        range_max=4.0,
        open_kernel_size=4,
        num_threads=5000,
        scan_beams="many",
        pose_source="laser",
        rectify=False,  # YAML's boolean: the values are words
    )
    ros.launch("launch", "kinect_pipeline.launch", f"params:={params}", *manager)
    wait_for("the node / loader to exit 1", lambda: lines(ros.log("launch"), "process has died", "exit code 1"))
    said = [ln for ln in ros.log("launch").splitlines() if ln.startswith("  ~") or "not starting" in ln]
    text = "\n".join(said)
    assert "6 parameters are invalid" in text, ros.log("launch")
    for word in (
        "~ceiling_height = 0.5",
        "~open_kernel_size = 4",
        "~num_threads = 5000",
        "~scan_beams = 'many'",
        "~pose_source = 'laser'",
        "~rectify = false (a bool): expected a string",
    ):
        assert word in text, f"'{word}' not in:\n{text}"
    assert "range_max" not in text  # a good value is not named
    assert not _has_topic(ros, "/kinect2/scan")


def _has_topic(ros: RosGraph, topic: str) -> bool:
    return any(t == topic for t, _ in ros.master().getPublishedTopics(""))


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_unknown_parameters_are_warned_once_naming_ours(ros: RosGraph, tmp_path: Path, kind: str) -> None:
    manager = manager_args(ros, kind)
    params = yaml_file(tmp_path / "p.yaml", range_max=4.0, output_frame_id="laser", sensor_pich=0.3)
    ros.launch("launch", "kinect_pipeline.launch", "pose_source:=static", f"params:={params}", *manager)
    res = ros.feed("feed", "--noise-free", "--until", "len(scans) >= 3")
    assert {s["range_max"] for s in res["scans"]} == {4.0}
    log = node_log(ros)
    frame_id = lines(log, "~output_frame_id is not a parameter")
    assert len(frame_id) == 1 and "closest of ours is ~scan_frame" in frame_id[0], frame_id
    pich = lines(log, "~sensor_pich is not a parameter")
    assert len(pich) == 1 and "closest of ours is ~sensor_pitch" in pich[0], pich


# ------------------------------------------------------------------------------------------------------------ item 5
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_sim_clock_starting_late_and_jumping_back(sim: RosGraph, tmp_path: Path, kind: str) -> None:
    params = yaml_file(tmp_path / "p.yaml", refine_floor=False)
    manager = manager_args(sim, kind)
    sim.launch(
        "launch",
        "kinect_pipeline.launch",
        "pose_source:=static",
        f"sensor_pitch:={TILT}",
        f"params:={params}",
        *manager,
    )
    wait_for("the node", lambda: _has_topic(sim, "/kinect2/scan"))
    res = sim.feed(
        "feed",
        "--noise-free",
        "--clock",
        "1000",
        "--clock-jump",
        "60:100",
        "--until",
        "len([s for s in scans if s['stamp'] < 1000]) >= 20 and len([d for d in diags if d['stamp'] < 1000]) >= 6",
    )
    # Once frames flow, the rate is never reported too low: not after /clock starts, nor after it jumps back.
    first_scan = res["scans"][0]["wall"]
    rates = [d["status"][RATE]["message"] for d in res["diags"] if d["wall"] > first_scan and RATE in d["status"]]
    assert rates and not [m for m in rates if "too low" in m or "No events" in m], rates
    back = [s for s in res["scans"] if s["stamp"] < 1000]
    assert len(back) >= 20  # frames after the jump are served
    want = core_ranges(frame(), TILT)
    assert all(same(s, want) for s in back)
    warned = lines(node_log(sim), "ROS time moved backwards")
    assert len(warned) == 1, warned
    assert int(newest(res, PROC, "clock jumps back") or 0) == 1


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_rosbag_play_loop_with_wall_time_starts_over_each_pass(ros: RosGraph, kind: str) -> None:
    if not BAG.exists():
        pytest.skip("no test bag: build the tests first")
    ros.launch("launch", "kinect_pipeline.launch", *manager_args(ros, kind))
    wait_for("the node", lambda: _has_topic(ros, "/kinect2/scan"))
    ros.start("player", "rosbag", "play", "-l", "--quiet", str(BAG))
    res = ros.feed(
        "feed",
        "--transport",
        "none",
        "--until",
        "sum(1 for a, b in zip(scans, scans[1:]) if b['stamp'] < a['stamp']) >= 2 and len(scans) >= 100",
        deadline=90,
    )
    stamps = [s["stamp"] for s in res["scans"]]
    jumps = sum(1 for a, b in itertools.pairwise(stamps) if b < a)
    warned = lines(node_log(ros), "the image stamps jumped back")
    assert jumps >= 2 and len(warned) >= jumps, (jumps, warned)
    per_pass = len(set(stamps))
    assert per_pass >= 30  # the 40 frames of each pass are served, not dropped as older than the last
    assert int(newest(res, PROC, "dropped: stamp out of order") or 0) == 0
    assert int(newest(res, PROC, "stamp jumps back") or 0) >= jumps


@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_second_rosbag_play_with_clock_keeps_diagnostics(sim: RosGraph, kind: str) -> None:
    if not BAG.exists():
        pytest.skip("no test bag: build the tests first")
    sim.launch("launch", "kinect_pipeline.launch", *manager_args(sim, kind))
    wait_for("the node", lambda: _has_topic(sim, "/kinect2/scan"))
    for run in (1, 2):
        # At half speed: the 1.3 s bag spans a few diagnostics (2 Hz, wall time).
        player = sim.start(f"play{run}", "rosbag", "play", "--clock", "--quiet", "-r", "0.5", str(BAG))
        sim.feed(
            f"feed{run}",
            "--transport",
            "none",
            "--until",
            "len(scans) >= 30 and len([d for d in diags if scans[0]['stamp'] <= d['stamp'] "
            "<= scans[-1]['stamp']]) >= 3",
            deadline=90,
        )
        assert exit_code(player, 120) == 0  # diagnostics came on the bag's clock, the second time too
    assert len(lines(node_log(sim), "ROS time moved backwards")) == 1


# ------------------------------------------------------------------------------------------------------------ item 6
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_tf_stopping_holds_the_last_pose_then_falls_back_with_a_warning(
    ros: RosGraph, tmp_path: Path, kind: str
) -> None:
    params = yaml_file(tmp_path / "p.yaml", refine_floor=False)
    ros.launch("launch", "kinect_pipeline.launch", "pose_hold_time:=1.0", f"params:={params}", *manager_args(ros, kind))
    res = ros.feed(
        "feed",
        "--noise-free",
        "--tf",
        f"{HEIGHT},{TILT},0",
        "--tf-frames",
        "45",
        "--until",
        "num('pose fallbacks: static pose', 'processing') >= 10",
    )
    last_tf = res["state"]["last_tf"]
    at_tf, at_static = core_ranges(frame(), TILT), core_ranges(frame(), 0.0)
    held = [s for s in res["scans"] if last_tf < s["stamp"] < last_tf + 0.9]
    later = [s for s in res["scans"] if s["stamp"] > last_tf + 1.2]
    assert held and later
    assert all(same(s, at_tf) for s in held), "the last good pose was not held for pose_hold_time"
    assert all(same(s, at_static) for s in later), "no static pose after pose_hold_time"
    warned = lines(node_log(ros), "differs from the last tf pose")
    assert len(warned) == 1 and "pitch by -14.90 deg" in warned[0], warned
    assert int(newest(res, PROC, "pose fallbacks: last good pose") or 0) > 0
    # The level tf's quaternion reads back a roll of 7e-18 rad, the static pose 0: every frame ran the level paths.
    assert newest(res, PROC, "frames with roll (pixel by pixel)") == "0"
    assert all(t["parent"] == "base_footprint" for t in res["tfs"])
    assert [t for t in res["tfs"] if t["stamp"] > last_tf + 1.2], "scan_frame no longer broadcast in the fallback"


def _level_frame_rotation(pitch: float, roll: float) -> np.ndarray:
    """optical <- level for a sensor at pitch / roll, from explicit matrices (the test's own)."""
    cp, sp, cr, sr = math.cos(pitch), math.sin(pitch), math.cos(roll), math.sin(roll)
    level_from_body = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @ np.array(
        [[1, 0, 0], [0, cr, -sr], [0, sr, cr]]
    )
    body_from_optical = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]])
    return (level_from_body @ body_from_optical).T


def _rotation(q: list[float]) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@pytest.mark.parametrize(
    ("kind", "source"), [("node", "static"), ("node", "imu"), ("node", "pitch_topic"), ("nodelet", "static")]
)
def test_scan_frame_is_broadcast_without_tf(ros: RosGraph, tmp_path: Path, kind: str, source: str) -> None:
    params = yaml_file(tmp_path / "p.yaml", refine_floor=False, sensor_roll=0.02)
    manager = manager_args(ros, kind)
    ros.launch(
        "launch", "kinect_pipeline.launch", f"pose_source:={source}", "sensor_pitch:=0.2", f"params:={params}", *manager
    )
    extra = {"imu": ["--imu-pitch", "0.06"], "pitch_topic": ["--base-pitch", "0.06"]}.get(source, [])
    want = _level_frame_rotation(0.26 if extra else 0.2, 0.02)
    # Until three tfs carry the base pitch (their rotation's element [2][0], 2 (x z - y w), is want's): the node's
    # imu / base_pitch subscription may connect after the first frames were sent.
    r20 = "2 * (t['q'][0] * t['q'][2] - t['q'][1] * t['q'][3])"
    with_pitch = f"sum(abs({r20} - {float(want[2][0])!r}) < 1e-6 for t in tfs)"
    res = ros.feed(
        "feed",
        "--noise-free",
        "--render",
        f"{HEIGHT},{0.26 if extra else 0.2},0.02",
        *extra,
        "--until",
        f"{with_pitch} >= 3 and len(scans) >= 3",
    )
    rotations = [_rotation(t["q"]) for t in res["tfs"]]
    for t in res["tfs"]:
        assert t["parent"] == "kinect2_depth_optical_frame" and t["t"] == [0.0, 0.0, 0.0], t
    first = next(i for i, r in enumerate(rotations) if np.allclose(r, want, atol=1e-6))
    # Frames before the node's first message take the static pose (pose_fallback, warned and counted): the mount's
    # pitch alone; from the first with the base pitch on, every one has it.
    for r in rotations[:first]:
        np.testing.assert_allclose(r, _level_frame_rotation(0.2, 0.02), atol=1e-6)
    for r in rotations[first:]:
        np.testing.assert_allclose(r, want, atol=1e-6)
    assert first == 0 or extra, "the static pose needs no message"
    assert {s["frame_id"] for s in res["scans"]} == {"kinect2_scan"}


@pytest.mark.parametrize(("kind", "source"), [("node", "tf"), ("nodelet", "static")])
def test_an_upside_down_camera_scans_as_the_core_does(ros: RosGraph, tmp_path: Path, kind: str, source: str) -> None:
    """A camera mounted upside down: its optical frame rolled 180 deg in the robot's tf, or sensor_roll deg(180).
    Before, the node refused both (|roll| <= 90 deg). Its scans are the core's, and the upright camera's."""
    params = yaml_file(tmp_path / "p.yaml", refine_floor=False, sensor_height=HEIGHT)
    with open(params, "a") as f:
        f.write("sensor_roll: deg(180)\n")  # rosparam's angle form: exactly pi
    manager = manager_args(ros, kind)
    ros.launch(
        "launch",
        "kinect_pipeline.launch",
        f"pose_source:={source}",
        f"sensor_pitch:={TILT}",
        f"params:={params}",
        *manager,
    )
    pose = f"{HEIGHT},{TILT},{math.pi}"
    tf = ["--tf", pose] if source == "tf" else []
    until = "len(scans) >= 3 and num('frames out', 'processing') >= 3" + (
        " and len(tfs) >= 3" if source == "static" else ""
    )
    res = ros.feed("feed", "--noise-free", "--render", pose, *tf, "--until", until)
    # Upside down runs the level mount's paths: no frame was labelled pixel by pixel.
    assert int(newest(res, PROC, "frames out") or 0) >= 3
    assert newest(res, PROC, "frames with roll (pixel by pixel)") == "0"
    upside_down = render_frame(CAM, boxes_scene(), HEIGHT, TILT, math.pi, "16UC1", seed=None).depth
    want = core_ranges(upside_down, TILT, sensor_roll=math.pi)
    assert len(res["scans"]) >= 3 and all(same(s, want) for s in res["scans"]), "a scan differs from the core's"
    upright = core_ranges(frame(), TILT)  # CAM's principal point is the image's centre: the half turn is exact
    assert np.array_equal(np.isfinite(want), np.isfinite(upright)) and np.isfinite(want).sum() > 100
    seen = np.isfinite(want)
    assert np.abs(want[seen] - upright[seen]).max() < 1e-3
    assert not int(newest(res, PROC, "dropped: refused by the core") or 0) and not int(
        newest(res, PROC, "dropped: no pose") or 0
    )
    for t in res["tfs"] if source == "static" else []:  # the scan frame, level, below the rolled optical frame
        np.testing.assert_allclose(_rotation(t["q"]), _level_frame_rotation(TILT, math.pi), atol=1e-6)


# ------------------------------------------------------------------------------------------------------------ item 7
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_launch_arguments_reach_the_node_and_the_tf_wait_is_reported_apart(
    ros: RosGraph, tmp_path: Path, kind: str
) -> None:
    params = yaml_file(tmp_path / "p.yaml", tf_timeout=0.3)
    ros.launch(
        "launch",
        "kinect_pipeline.launch",
        *manager_args(ros, kind),
        "range_min:=0.3",
        "range_max:=4.0",
        "num_threads:=2",
        "pose_hold_time:=0.5",
        "pose_fallback:=static",
        f"params:={params}",
    )
    res = ros.feed("feed", "--noise-free", "--rate", "3", "--until", "num('tf wait last [ms]', 'processing') > 0")
    m = ros.master()
    got = {
        k: m.getParam(f"/kinect2/kinect_pipeline/{k}")
        for k in ("range_min", "range_max", "num_threads", "pose_hold_time", "pose_fallback")
    }
    assert got == {
        "range_min": 0.3,
        "range_max": 4.0,
        "num_threads": 2,
        "pose_hold_time": 0.5,
        "pose_fallback": "static",
    }
    assert all(s["range_min"] == pytest.approx(0.3) and s["range_max"] == 4.0 for s in res["scans"])
    assert float(newest(res, PROC, "fraction taken as wrong matches (speckle_jump)")) == 0.0, "off by default"
    wait_ms = float(newest(res, PROC, "tf wait last [ms]") or 0)
    work_ms = float(newest(res, PROC, "processing time max [ms]") or 0)
    assert wait_ms >= 0.9 * 300  # no tf at all: each frame waited tf_timeout
    assert work_ms < wait_ms, (work_ms, wait_ms)  # the processing time leaves the wait out


def test_replay_launch_records_the_inputs_and_both_scans(ros: RosGraph, tmp_path: Path) -> None:
    if not BAG.exists():
        pytest.skip("no test bag: build the tests first")
    out = tmp_path / "out.bag"
    p = ros.launch("replay", "replay.launch", f"bag:={BAG}", f"record:={out}", "play_args:=--pause")

    def listening() -> bool:
        subs = dict(ros.master().getSystemState()[1])
        image = subs.get("/kinect2/sd/image_depth", [])
        return (
            "/recorder" in image
            and "/kinect2/kinect_pipeline" in image
            and "/recorder" in subs.get("/kinect2/cliff_scan", [])
        )

    wait_for("the recorder and the node to subscribe", listening)
    wait_for("the player", lambda: ros.has_service("/player/pause_playback"))
    subprocess.run(
        ["rosservice", "call", "/player/pause_playback", "data: false"],
        env=ros.env,
        check=True,
        capture_output=True,
        timeout=60,
    )
    exit_code(p, 180)  # the player is required: the launch ends with the bag, and the recorder closes it
    import rosbag

    with rosbag.Bag(str(out)) as bag:
        topics = bag.get_type_and_topic_info().topics
    for t in ("/kinect2/sd/image_depth", "/kinect2/sd/camera_info", "/tf", "/kinect2/scan", "/kinect2/cliff_scan"):
        assert t in topics and topics[t].message_count > 0, f"{t} not recorded: {sorted(topics)}"


# ----------------------------------------------------------------------------------------------- issue 19, ROS side
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_floor_refinement_learns_a_wrong_static_pose_and_serves_whatever_it_does(ros: RosGraph, kind: str) -> None:
    # Frames rendered at the true pose; the node is told a pose 3 cm too high and looking 1 deg less down.
    dh, dp = 0.03, math.radians(-1.0)
    manager = manager_args(ros, kind)
    ros.launch(
        "launch",
        "kinect_pipeline.launch",
        "pose_source:=static",
        f"sensor_height:={HEIGHT + dh}",
        f"sensor_pitch:={TILT + dp}",
        *manager,
    )
    learned = (
        "abs(num('learned height [mm]', 'floor refinement') + 30) < 5 and "
        "abs(num('learned pitch [deg]', 'floor refinement') - 1) < 0.15"
    )
    res = ros.feed(
        "feed",
        "--scene",
        "lab",
        "--render",
        f"{HEIGHT},{TILT},0",
        "--switch-scene",
        f"wall:{learned}",
        "--until",
        "switched and num('fits too few pixels', 'floor refinement') >= 10",
        deadline=90,
    )
    # While the floor was in view: accepted fits, and the correction learned is the error told.
    before = [d for d in res["diags"] if FLOOR in d["status"]]
    accepted = [d for d in before if d["status"][FLOOR]["values"].get("last status") == "accepted"]
    assert accepted, "no accepted fit reported"
    v = accepted[-1]["status"][FLOOR]["values"]
    assert abs(float(v["learned height [mm]"]) + 30) < 8 and abs(float(v["learned pitch [deg]"]) - 1) < 0.25, v
    assert re.search(
        r"sits (2[2-9]|3[0-8]) mm lower, looks (0\.[89]\d|1\.[01]\d) deg further down", v["to fix the mounting"]
    ), v
    assert int(v["fits accepted"]) > 0
    # The floor profile is reported: "none" or the bands that hold one ("2.25 m: +0.3 cm, ...").
    profile = v["floor profile (band centre: floor beyond the plane)"]
    assert profile == "none" or re.fullmatch(r"\d+\.\d\d m: [+-]\d+\.\d cm(, \d+\.\d\d m: [+-]\d+\.\d cm)*", profile), v
    # The scans at the learned pose have no phantom obstacles from the floor: against the frames' own truth.
    switch = res["state"]["switched_at"]
    lab = [s for s in res["scans"] if s["stamp"] <= res["sent"][switch - 1]][-5:]
    truth = _true_ranges(lab_scene())
    for s in lab:
        got = ranges(s)
        sigma = kinect_sigma(np.nan_to_num(truth, posinf=8.0).astype(np.float64))
        phantom = np.isfinite(got) & ((got < truth - 0.05 - 4 * sigma) | ~np.isfinite(truth))
        assert phantom.sum() <= 1, f"{phantom.sum()} phantom beams after learning"
    # Told the same wrong pose without the refinement, the floor would be obstacles: the check can fail.
    told = core_ranges(render_frame(CAM, lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=0).depth, TILT + dp, HEIGHT + dh)
    assert (np.isfinite(told) & ((told < truth - 0.2) | ~np.isfinite(truth))).sum() > 100
    # A wall filling the view: nothing to fit, the learned correction stays, frames are still served.
    wall = [s for s in res["scans"] if s["stamp"] > res["sent"][switch]]
    assert len(wall) >= 8
    last = [
        d["status"][FLOOR]["values"]
        for d in res["diags"]
        if "last status" in d["status"].get(FLOOR, {}).get("values", {})
    ][-1]
    assert last["last status"] in ("too few pixels", "ill-conditioned")
    assert abs(float(last["learned height [mm]"]) + 30) < 8


def _true_ranges(scene: Any) -> np.ndarray:
    """The nearest true obstacle per beam of the default scan (noise-free, exact pose, no refinement)."""
    depth = render_frame(CAM, scene, HEIGHT, TILT, 0.0, "16UC1", seed=None).depth
    return core_ranges(depth, TILT)
