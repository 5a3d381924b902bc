"""The node on recordings as robots make them (issue 28, ROS side): the real legged-robot bags in ../shared (one
depth frame each, raw, compressedDepth and PNG compressed, no CameraInfo), played with `rosbag play -l` without
--clock into the node started by roslaunch with the package's launch file (and the nodelet in a real manager),
through a roscore of the test's own on a free loopback port. A feeder process (test/ros/feeder.py, listening only)
records scans, diagnostics and /rosout; every process is stopped by its own PID; every wait has a deadline."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from ros_graph import NODE, ROOT, RosGraph, newest, wait_for

import kinect_pipeline as kp

BAGS = ROOT.parent / "shared" / "data" / "real" / "spot_bags"  # read from there, never copied
NS = "/spot/depth/frontleft"
INFO_TOPIC = f"{NS}/camera_info"
# The bags carry no intrinsics; these are plausible for the 424x240 depth camera and used by node and core alike.
FX, FY, CX, CY, W, H = 211.0, 211.0, 212.0, 120.0, 424, 240
PROC = "processing"
BAG = {"raw": "raw.bag", "compressedDepth": "compressedDepth.bag", "compressed": "compressed.bag"}

pytestmark = [
    pytest.mark.skipif(not NODE.exists(), reason="no build: run scripts/quickstart.sh first"),
    pytest.mark.skipif(not BAGS.exists(), reason="no ../shared/data/real/spot_bags"),
]


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RosGraph]:
    g = RosGraph(tmp_path_factory.mktemp("roscore"))
    g.start_core()
    yield g
    g.stop_all()


@pytest.fixture
def ros(shared: RosGraph, tmp_path: Path) -> Iterator[RosGraph]:
    """The module's roscore, with this test's processes and logs; what they leave on the server is removed."""
    _forget(shared)
    g = shared.session(tmp_path)
    yield g
    g.stop_all()
    _forget(shared)


def _forget(g: RosGraph) -> None:
    g.reset_params()
    try:
        g.master().deleteParam("/spot")
    except Exception:
        pass


def _launch(ros: RosGraph, kind: str, transport: str, *args: str) -> subprocess.Popen[bytes]:
    manager: list[str] = []
    if kind == "nodelet":
        ros.start("manager", "rosrun", "nodelet", "nodelet", "manager", "__name:=spot_manager")
        wait_for("the manager", lambda: ros.has_service("/spot_manager/load_nodelet"))
        manager = ["manager:=spot_manager"]
    return ros.launch(
        "launch",
        "kinect_pipeline.launch",
        f"camera:={NS}",
        "image:=image",
        "scan_frame:=frontleft_scan",
        "pose_source:=static",
        f"image_transport:={transport}",
        *manager,
        *args,
    )


def _subscribed(ros: RosGraph, topic: str) -> bool:
    return any(
        t == topic and any("kinect_pipeline" in n or "manager" in n for n in nodes)
        for t, nodes in ros.master().getSystemState()[1]
    )


def _play_loop(ros: RosGraph, transport: str) -> None:
    image = f"{NS}/image" + ("" if transport == "raw" else f"/{transport}")
    wait_for("the node to subscribe", lambda: _subscribed(ros, image))
    ros.start("player", "rosbag", "play", "-l", "--quiet", str(BAGS / BAG[transport]), "--topics", image)


def _listen(ros: RosGraph, until: str, deadline: float = 60.0) -> dict[str, Any]:
    return ros.feed(
        "feed",
        "--ns",
        NS,
        "--scan-frame",
        "frontleft_scan",
        "--transport",
        "none",
        "--until",
        until,
        deadline=deadline,
    )


def _said(result: dict[str, Any], *words: str) -> list[str]:
    return [m["msg"] for m in result["logs"] if all(w in m["msg"] for w in words)]


def _bag_depth() -> np.ndarray:
    import rosbag

    with rosbag.Bag(str(BAGS / "raw.bag")) as bag:
        msg = next(m for _, m, _ in bag.read_messages(topics=[f"{NS}/image"]))
    assert msg.encoding == "16UC1" and (msg.width, msg.height) == (W, H)
    return np.frombuffer(msg.data, np.uint16).reshape(H, W).copy()


def _core_ranges() -> np.ndarray:
    """What a fresh pipeline makes of the bag's frame with the launch file's static pose and the test's intrinsics."""
    pipe = kp.Pipeline(kp.Camera(W, H, FX, FY, CX, CY), kp.Config())
    return np.asarray(pipe.process(_bag_depth()).ranges, np.float32)


def _same(scan: dict[str, Any], want: np.ndarray) -> bool:
    got = np.array([np.nan if r is None else r for r in scan["ranges"]], np.float32)
    return bool(np.all(np.isclose(got, want, rtol=1e-5, atol=1e-6) | (np.isnan(got) & np.isnan(want))))


def _camera_yaml(path: Path) -> Path:
    """A camera_info YAML as camera_calibration (camera_calibration_parsers) writes it."""
    path.write_text(
        f"image_width: {W}\nimage_height: {H}\ncamera_name: frontleft\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{FX}, 0, {CX}, 0, {FY}, {CY}, 0, 0, 1]\n"
        "distortion_model: plumb_bob\n"
        "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n"
        "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
        f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{FX}, 0, {CX}, 0, 0, {FY}, {CY}, 0, 0, 0, 1, 0]\n"
    )
    return path


# ------------------------------------------------------------------------------------------- no CameraInfo at all
@pytest.mark.parametrize(
    ("kind", "transport"), [("node", "raw"), ("node", "compressedDepth"), ("nodelet", "compressed")]
)
def test_a_bag_without_camera_info_is_warned_naming_the_topic_and_counted(
    ros: RosGraph, kind: str, transport: str
) -> None:
    _launch(ros, kind, transport)
    _play_loop(ros, transport)
    res = _listen(
        ros,
        f"any('no sensor_msgs/CameraInfo on {INFO_TOPIC}' in m['msg'] for m in logs) "
        "and num('images without camera_info', 'processing') >= 2",
    )
    warned = _said(res, f"no sensor_msgs/CameraInfo on {INFO_TOPIC}")
    assert "image(s) on" in warned[0] and "~camera_info_url" in warned[0] and "~intrinsics" in warned[0], warned
    assert not _said(res, "do not appear to be synchronized")  # not image_transport's generic warning
    assert int(newest(res, PROC, "frames in") or 0) >= 2
    assert int(newest(res, PROC, "frames out") or 0) == 0
    summary = [d["status"][PROC]["message"] for d in res["diags"] if PROC in d["status"]][-1]
    assert f"waiting for camera_info on {INFO_TOPIC}" in summary, summary
    assert not res["scans"]


# ------------------------------------------------------------------------- the camera from parameters, bags looped
@pytest.mark.parametrize(
    ("kind", "transport", "source"),
    [("node", "raw", "url"), ("node", "compressedDepth", "intrinsics"), ("nodelet", "compressed", "url")],
)
def test_camera_from_parameters_serves_every_pass_of_a_looped_bag(
    ros: RosGraph, tmp_path: Path, kind: str, transport: str, source: str
) -> None:
    given = (
        f"camera_info_url:=file://{_camera_yaml(tmp_path / 'frontleft.yaml')}"
        if source == "url"
        else f"intrinsics:={FX} {FY} {CX} {CY} {W} {H}"
    )
    _launch(ros, kind, transport, given)
    _play_loop(ros, transport)
    # Every pass restarts the one-frame bag's stamp: each must be served as a new sequence, not dropped.
    res = _listen(ros, "len(scans) >= 3 and num('stamp jumps back', 'processing') >= 2")
    want = _core_ranges()
    assert all(_same(s, want) for s in res["scans"]), "a scan differs from a fresh pipeline's on the bag's frame"
    assert len({s["stamp"] for s in res["scans"]}) == 1  # the same frame each pass, each served
    assert int(newest(res, PROC, "dropped: stamp out of order") or 0) == 0
    assert int(newest(res, PROC, "camera from parameters (frames)") or 0) >= 3
    assert newest(res, PROC, "camera from").startswith("~camera_info_url" if source == "url" else "~intrinsics")
    log = ros.log("launch") + ros.log("manager")
    assert "the first stamp of this sequence (a bag played again or in a loop)" in log


@pytest.mark.parametrize(
    ("kind", "given", "said"),
    [
        ("node", "camera_info_url:=file:///nonexistent/frontleft.yaml", "cannot read '/nonexistent/frontleft.yaml'"),
        (
            "node",
            "camera_info_url:=/tmp/frontleft.yaml",
            "a path without its scheme (write file:///tmp/frontleft.yaml)",
        ),
        ("node", "intrinsics:=211 211 212 120", "~intrinsics = '211 211 212 120': 4 numbers; expected six"),
        ("nodelet", "BAD_YAML", "is not a camera_info file camera_calibration_parsers can read"),
    ],
)
def test_camera_parameters_it_cannot_honour_stop_it_naming_the_value(
    ros: RosGraph, tmp_path: Path, kind: str, given: str, said: str
) -> None:
    if given == "BAD_YAML":
        bad = tmp_path / "bad.yaml"
        bad.write_text("image_width: 424\ncamera_matrix: [1, 2\n")
        given = f"camera_info_url:=file://{bad}"
    _launch(ros, kind, "raw", given)
    wait_for("the node / loader to exit 1", lambda: "exit code 1" in ros.log("launch"))
    text = ros.log("launch") + ros.log("manager")
    lines = [ln for ln in text.splitlines() if said in ln]
    assert lines and "not starting" in text, text[-3000:]
    assert not _subscribed(ros, f"{NS}/image")


# -------------------------------------------------------------- KINECT_PIPELINE_SIMD: named at startup, or refused
@pytest.mark.parametrize(("kind", "target"), [("node", "mmx"), ("nodelet", "mmx"), ("node", "scalar")])
def test_the_simd_target_is_named_at_startup_and_one_the_cpu_lacks_stops_it(
    ros: RosGraph, kind: str, target: str
) -> None:
    ros.env["KINECT_PIPELINE_SIMD"] = target  # the launch's and the manager's environment
    try:
        _launch(ros, kind, "raw")
        if target == "mmx":
            wait_for("the node / loader to exit 1", lambda: "exit code 1" in ros.log("launch"))
        else:
            res = _listen(ros, "diag('SIMD target', 'processing') is not None")
    finally:
        del ros.env["KINECT_PIPELINE_SIMD"]
    text = ros.log("launch") + ros.log("manager")
    if target == "mmx":
        said = [ln for ln in text.splitlines() if "not starting: KINECT_PIPELINE_SIMD: SIMD target 'mmx'" in ln]
        assert said and "expected native or one this CPU has (" in said[0], text[-3000:]
        assert not _subscribed(ros, f"{NS}/image")
    else:
        assert newest(res, PROC, "SIMD target") == "scalar"


# -------------------------------------------------------------- a camera_info of its own stamps: paired by recency
@pytest.mark.parametrize("kind", ["node", "nodelet"])
def test_an_unchanging_camera_info_with_other_stamps_is_paired_by_recency(ros: RosGraph, kind: str) -> None:
    _launch(ros, kind, "raw")
    info = (
        f"{{header: {{frame_id: frontleft}}, width: {W}, height: {H}, distortion_model: plumb_bob, "
        f"D: [0, 0, 0, 0, 0], K: [{FX}, 0, {CX}, 0, {FY}, {CY}, 0, 0, 1], R: [1, 0, 0, 0, 1, 0, 0, 0, 1], "
        f"P: [{FX}, 0, {CX}, 0, 0, {FY}, {CY}, 0, 0, 0, 1, 0]}}"
    )
    ros.start("info", "rostopic", "pub", "-r", "5", INFO_TOPIC, "sensor_msgs/CameraInfo", info)
    _play_loop(ros, "raw")
    res = _listen(ros, "len(scans) >= 2 and num('camera_info paired: latest (stamps differ, camera unchanged)') >= 2")
    want = _core_ranges()
    assert all(_same(s, want) for s in res["scans"])
    assert int(newest(res, PROC, "camera_info paired: same stamp") or 0) == 0
    assert "(the latest; its stamps differ from the images')" in newest(res, PROC, "camera from")
    log = ros.log("launch") + ros.log("manager")  # said once, maybe before the feeder listened to /rosout
    assert log.count(f"the camera_info on {INFO_TOPIC} has other stamps than the images") == 1, log[-3000:]


# ----------------------------------------------------------------- sensor_model: what an earlier run left behind
def test_a_second_launch_with_another_sensor_model_gets_its_preset_and_leftovers_are_warned(ros: RosGraph) -> None:
    node = f"{NS}/kinect_pipeline"
    m = ros.master()
    first = _launch(ros, "node", "raw", "sensor_model:=kinect_v2")
    wait_for("the first run's parameters", lambda: _param(ros, f"{node}/range_max") == 10.0)
    ros.stop(first)
    assert _param(ros, f"{node}/range_max") == 10.0  # left on the server by the first run
    # The launch file clears the node's parameters first: the second preset applies.
    second = ros.launch(
        "launch2",
        "kinect_pipeline.launch",
        f"camera:={NS}",
        "image:=image",
        "scan_frame:=frontleft_scan",
        "sensor_model:=kinect_v1",
    )
    wait_for("the second run's preset", lambda: _param(ros, f"{node}/range_max") == 4.0)
    assert m.getParam(f"{node}/cliff_min_pixels") == 6
    assert not [ln for ln in ros.log("launch2").splitlines() if "override the preset" in ln]
    ros.stop(second)
    # Started without the launch file, the leftovers stay, and win: a warning names each with both values.
    ros.start(
        "rosrun",
        "rosrun",
        "kinect_pipeline",
        "kinect_pipeline_node",
        f"__ns:={NS}",
        "image:=image",
        "_sensor_model:=realsense_d4xx",
    )
    said = wait_for(
        "the override warning",
        lambda: [ln for ln in ros.log("rosrun").splitlines() if "override the preset" in ln],
    )
    assert "[ WARN]" in said[0] or "WARN" in said[0], said
    for word in (
        "~sensor_model realsense_d4xx",
        "~range_max = 4 (the preset's: 6)",
        "~cliff_min_pixels = 6 (the preset's: 4)",
        "~speckle_jump = 0 (the preset's: 0.125)",
        "~threshold_curve = '",
        f"rosparam delete {node}/PARAMETER",
    ):
        assert word in said[0], (word, said[0])


def _param(ros: RosGraph, name: str) -> Any:
    try:
        return ros.master().getParam(name)
    except Exception:
        return None
