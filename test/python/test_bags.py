"""Real recordings in: rosbag2 (sqlite3 and mcap folders, a single .mcap file) next to ROS 1 bags, camera_info paired
by stamp wherever it lies, the cliff scan in replay's output, report on a plain camera bag. The bags are written
with rosbags (ROS 2 definitions for rosbag2: no seq, lowercase k/d/r/p) and read back with rosbags' own readers."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from framebag import write_frames_bag

pytest.importorskip("rosbags")

import kinect_pipeline as kp
from kinect_pipeline.bags.reader import bag_format
from kinect_pipeline.bags.writer import BagWriter
from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag
from kinect_pipeline.tools.replay import ReplayError, ReplayOptions, replay

FRAMES = 5
KINDS = {"ros1": "seq.bag", "sqlite3": "seq_sqlite", "mcap": "seq_mcap", "mcap file": "seq.mcap"}


def fmt_of(kind: str) -> str | None:
    return {"ros1": None, "sqlite3": "sqlite3", "mcap": "mcap", "mcap file": None}[kind]


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("bags")
    out = {}
    for kind, name in KINDS.items():
        out[kind] = d / name
        write_sequence_bag(out[kind], Scenario(frames=FRAMES, encoding="16UC1", seed=8), fmt=fmt_of(kind))
    return out


def messages(path: Path) -> dict[str, list]:
    """Every message of a bag of any kind, per topic, read with rosbags' own readers (not the package's)."""
    from rosbags.typesys import Stores, get_typestore

    out: dict[str, list] = {}
    if path.is_file() and path.suffix == ".bag":
        from rosbags.rosbag1 import Reader

        ts = get_typestore(Stores.ROS1_NOETIC)
        with Reader(path) as r:
            for c, _, raw in r.messages():
                if c.msgtype.startswith("sensor_msgs") or c.msgtype.startswith("std_msgs"):
                    out.setdefault(c.topic, []).append(ts.deserialize_ros1(raw, c.msgtype))
        return out
    from rosbags.rosbag2 import Reader as Reader2

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Reader2(path) as r:
        for c, _, raw in r.messages():
            out.setdefault(c.topic, []).append(ts.deserialize_cdr(raw, c.msgtype))
    return out


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_the_generator_writes_every_kind_with_its_own_definitions(bags: dict[str, Path]) -> None:
    assert [bag_format(bags[k]) for k in KINDS] == ["ros1", "sqlite3", "mcap", "mcap"]
    assert bags["mcap file"].is_file() and (bags["sqlite3"] / "metadata.yaml").exists()
    for kind in ("sqlite3", "mcap", "mcap file"):
        msgs = messages(bags[kind])
        info = msgs["/kinect2/sd/camera_info"][0]
        assert hasattr(info, "k") and not hasattr(info, "K") and not hasattr(info.header, "seq")
        assert info.k[0] == pytest.approx(kp.kinect_v2_camera().fx)


@pytest.mark.parametrize("kind", list(KINDS))
def test_replay_writes_the_inputs_format_with_the_same_scans(bags: dict[str, Path], tmp_path: Path, kind: str) -> None:
    out = tmp_path / ("out.mcap" if kind == "mcap file" else "out.bag" if kind == "ros1" else "out")
    r = replay(bags[kind], out, show_progress=False)
    assert r.processed == FRAMES and r.format == bag_format(bags[kind])
    assert bag_format(out) == bag_format(bags[kind])
    got = messages(out)
    assert len(got["/kinect2/scan"]) == len(got["/kinect2/cliff_scan"]) == FRAMES
    assert len(got["/kinect2/sd/image_depth/processed"]) == FRAMES
    assert len(got["/kinect2/sd/image_depth"]) == FRAMES, "the input's messages are copied"
    info = json.loads(got["/kinect_pipeline/replay_info"][0].data)
    assert info["depth_topic"] == "/kinect2/sd/image_depth"
    # Every format gives the same scans, as the core gives them for the ROS 1 bag.
    ref_out = tmp_path / "ref.bag"
    replay(bags["ros1"], ref_out, show_progress=False)
    ref_scans = messages(ref_out)["/kinect2/scan"]
    for a, b in zip(got["/kinect2/scan"], ref_scans, strict=True):
        np.testing.assert_array_equal(a.ranges, b.ranges)
        assert (a.header.stamp.sec, a.header.stamp.nanosec) == (b.header.stamp.sec, b.header.stamp.nanosec)
        assert hasattr(a.header, "seq") == (kind == "ros1")


def test_the_cliff_scan_is_the_cores(bags: dict[str, Path], tmp_path: Path) -> None:
    from kinect_pipeline.simulation.robot import Rig, SegwayMotion

    out = tmp_path / "c.bag"
    replay(bags["ros1"], out, show_progress=False)
    got = messages(out)
    rig, motion, cam = Rig(), SegwayMotion(), kp.kinect_v2_camera()
    for img, cliff in zip(got["/kinect2/sd/image_depth"], got["/kinect2/cliff_scan"], strict=True):
        assert cliff.header.frame_id == "kinect2_scan" and len(cliff.intensities) == 0
        assert cliff.header.stamp == img.header.stamp
        _, _, pitch, height = rig.sensor_pose(motion.pitch(img.header.seq))
        depth = np.frombuffer(img.data, np.uint16).reshape(img.height, img.width)
        want = kp.Pipeline(cam, kp.Config(sensor_height=height, sensor_pitch=pitch)).process(depth).cliff_ranges
        same = np.isclose(cliff.ranges, want, rtol=1e-4, atol=1e-5) | (np.isnan(cliff.ranges) & np.isnan(want))
        assert same.mean() >= 0.99
    off = tmp_path / "off.bag"
    replay(bags["ros1"], off, ReplayOptions(config={"cliff_scan": False}), show_progress=False)
    assert "/kinect2/cliff_scan" not in messages(off) and "/kinect2/scan" in messages(off)


@pytest.mark.parametrize(("src", "fmt", "name"), [("ros1", "mcap", "conv.mcap"), ("mcap", "ros1", "conv.bag")])
def test_replay_converts_when_told(bags: dict[str, Path], tmp_path: Path, src: str, fmt: str, name: str) -> None:
    out = tmp_path / name
    r = cli("replay", str(bags[src]), "-o", str(out), "--format", fmt, "--quiet")
    assert r.returncode == 0, r.stderr
    assert bag_format(out) == fmt
    got = messages(out)
    info = got["/kinect2/sd/camera_info"][0]
    k = info.k if fmt == "mcap" else info.K
    assert k[0] == pytest.approx(kp.kinect_v2_camera().fx) and len(got["/kinect2/scan"]) == FRAMES
    if fmt == "ros1" and shutil.which("rosbag"):
        text = subprocess.run(["rosbag", "info", str(out)], capture_output=True, text=True, timeout=60).stdout
        assert "/kinect2/cliff_scan" in text and f"{FRAMES} msgs" in text


def test_a_name_that_says_another_format_is_refused(bags: dict[str, Path], tmp_path: Path) -> None:
    r = cli("replay", str(bags["mcap"]), "-o", str(tmp_path / "x.bag"), "--quiet")
    assert r.returncode == 1 and "a .bag name for a mcap bag" in r.stderr and "--format ros1" in r.stderr
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("kind", ["sqlite3", "mcap file"])
def test_report_and_calibrate_read_rosbag2(bags: dict[str, Path], tmp_path: Path, kind: str) -> None:
    r = cli("report", str(bags[kind]), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "rep" / "quality.json").exists() and (tmp_path / "rep" / "index.html").exists()
    r = cli("calibrate", "--bag", str(bags[kind]), "--json")
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)["summary"]
    assert s["frames_with_floor"] == FRAMES and abs(s["height"]["median"]) < 0.01


def test_a_damaged_rosbag2_is_refused_naming_it(bags: dict[str, Path], tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    data = bags["mcap file"].read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    r = cli("replay", str(bad), "-o", str(tmp_path / "o.mcap"), "--quiet")
    assert r.returncode == 1 and str(bad) in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    folder = tmp_path / "nobag"
    folder.mkdir()
    r = cli("report", str(folder), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 1 and "a folder without depth frames" in r.stderr, r.stderr


# -- camera_info by stamp ------------------------------------------------------------------------------------


@pytest.mark.parametrize("frames", [1, 4])
@pytest.mark.parametrize("fmt", [None, "mcap"])
def test_a_camera_info_after_its_image_pairs_with_it(tmp_path: Path, frames: int, fmt: str | None) -> None:
    bag = tmp_path / ("late.bag" if fmt is None else "late")
    write_sequence_bag(bag, Scenario(frames=frames, seed=4, info_after_image=True), fmt=fmt)
    r = replay(bag, tmp_path / "out", ReplayOptions(format=fmt or "ros1"), show_progress=False)
    assert r.processed == frames and not any("camera_info" in p for p in r.problems), r.problems


def _bag_with_infos(path: Path, infos: list[tuple[int, float]], fx: float = 365.0) -> None:
    """A one-frame ROS 1 bag: a 16UC1 image at stamp 10 s and camera_infos at the given (record time, stamp)."""
    w = BagWriter(path, "ros1")
    T = w.types
    c_img = w.add("/cam/depth/image_raw", "sensor_msgs/msg/Image")
    c_info = w.add("/cam/depth/camera_info", "sensor_msgs/msg/CameraInfo")
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    depth = np.full((424, 512), 2000, np.uint16)
    img = T["sensor_msgs/msg/Image"](
        header=Header(seq=0, stamp=Time(sec=10, nanosec=0), frame_id="cam"),
        height=424,
        width=512,
        encoding="16UC1",
        is_bigendian=0,
        step=1024,
        data=depth.view(np.uint8).reshape(-1),
    )
    w.write(c_img, 10_000_000_000, w.encode(img, "sensor_msgs/msg/Image"))
    for t_ns, st in infos:
        sec = int(st)
        info = T["sensor_msgs/msg/CameraInfo"](
            header=Header(seq=0, stamp=Time(sec=sec, nanosec=round((st - sec) * 1e9)), frame_id="cam"),
            height=424,
            width=512,
            distortion_model="plumb_bob",
            D=np.zeros(5),
            K=np.array([fx, 0, 255.5, 0, 365.0, 211.5, 0, 0, 1.0]),
            R=np.eye(3).reshape(-1),
            P=np.zeros(12),
            binning_x=0,
            binning_y=0,
            roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )
        w.write(c_info, t_ns, w.encode(info, "sensor_msgs/msg/CameraInfo"))
    w.close()


def _bag_of_frames(path: Path, frames: list[tuple[str, np.ndarray, tuple[int, int]]]) -> None:
    """A ROS 1 bag of depth images (encoding, pixels, camera_info's height and width), one a second from 10 s."""
    infos = [
        {"height": h, "width": w, "K": [365.0, 0, (w - 1) / 2, 0, 365.0, (h - 1) / 2, 0, 0, 1.0]}
        for _, _, (h, w) in frames
    ]
    write_frames_bag(path, [px for _, px, _ in frames], infos)


def test_a_frame_the_core_refuses_is_skipped_named_and_the_rest_replayed(tmp_path: Path) -> None:
    """A float32 frame in millimetres, or one of another size than its camera_info, ended the replay with the
    core's ValueError (a traceback through the API, 'nothing written' by the CLI): the node drops such a frame."""
    mm = np.full((424, 512), 2000, np.uint16)
    good = ("16UC1", mm, (424, 512))
    bag = tmp_path / "mixed.bag"
    _bag_of_frames(bag, [good, ("32FC1", mm.astype(np.float32), (424, 512)), good, ("16UC1", mm, (480, 640)), good])
    r = replay(bag, tmp_path / "out.bag", ReplayOptions(), show_progress=False)
    assert r.processed == 3, r.problems
    refused = [p for p in r.problems if "refused by the core" in p]
    assert len(refused) == 1, r.problems
    assert "at 11.000 s: refused by the core: depth: float32 with a median of 2000" in refused[0]
    size = "at 13.000 s: the image is 512x424 but its camera_info on /cam/depth/camera_info is 640x480"
    assert size in str(r.problems)
    assert not any("static pose used" in p and "11.000" in p for p in r.problems)

    from kinect_pipeline.evaluation.report import collect

    pose = {"sensor_height": 1.0, "sensor_pitch": 0.3}
    c = collect(bag, ReplayOptions(config=pose), show_progress=False)  # the report's: it stopped at the frame
    assert len(c.frames) == 3 and "frame at 11.00 s: refused by the core: depth: float32" in str(c.problems)


def test_no_camera_info_at_all_is_an_error_saying_why(tmp_path: Path) -> None:
    bag = tmp_path / "b.bag"
    _bag_with_infos(bag, [(11_000_000_000, 11.0)], fx=0.0)
    r = cli("replay", str(bag), "-o", str(tmp_path / "o.bag"), "--quiet")
    assert r.returncode == 1, r.stdout
    assert "no frame of /cam/depth/image_raw could be processed" in r.stderr
    assert "K[0] (fx) = 0: the camera is uncalibrated" in r.stderr, r.stderr
    assert not (tmp_path / "o.bag").exists()


def test_the_camera_info_of_the_same_stamp_wins_over_nearer_ones(tmp_path: Path) -> None:
    bag = tmp_path / "b.bag"
    # written before the image at another stamp (an uncalibrated one), and after it at its own stamp
    _bag_with_infos(bag, [(9_000_000_000, 9.0), (12_000_000_000, 10.0)])
    r = replay(bag, tmp_path / "o.bag", ReplayOptions(pose_fallback="static"), show_progress=False)
    assert r.processed == 1 and not any("camera_info" in p for p in r.problems), r.problems


def test_a_camera_info_of_another_stamp_is_used_and_said(tmp_path: Path) -> None:
    bag = tmp_path / "b.bag"
    _bag_with_infos(bag, [(11_000_000_000, 10.5)])
    r = replay(bag, tmp_path / "o.bag", show_progress=False)
    assert r.processed == 1 and any("no camera_info of its stamp" in p for p in r.problems), r.problems


def test_a_bag_without_any_frame_fails(tmp_path: Path) -> None:
    bag = tmp_path / "b.bag"
    w = BagWriter(bag, "ros1")
    w.add("/cam/depth/image_raw", "sensor_msgs/msg/Image")
    w.add("/cam/depth/camera_info", "sensor_msgs/msg/CameraInfo")
    w.close()
    with pytest.raises(ReplayError, match="no frame of /cam/depth/image_raw could be processed, of 0"):
        replay(bag, tmp_path / "o.bag", show_progress=False)
    assert not (tmp_path / "o.bag").exists()


# -- report on a plain camera bag -----------------------------------------------------------------------------


def test_report_on_a_plain_camera_bag(tmp_path: Path) -> None:
    bag = tmp_path / "plain.bag"
    write_sequence_bag(bag, Scenario(frames=4, seed=6, extras=False))
    r = cli("report", str(bag), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 0, r.stderr
    rep = tmp_path / "rep"
    names = sorted(p.name for p in rep.iterdir())
    assert names == ["confidence.png", "frame.png", "index.html", "scan.png", "timing.png"], names
    page = (rep / "index.html").read_text()
    assert "LiDAR" not in page and "<figcaption>" in page and "pose from the bag" in page
    summary = json.loads(r.stdout[: r.stdout.rindex("}") + 1])
    assert summary["frames"] == 4 and "phantom_beams" not in summary
    assert summary["ms_per_frame_median"] == round(summary["ms_per_frame_median"], 3)
    lo, hi = summary["pitch_deg_range"]
    assert lo == round(lo, 2) and hi == round(hi, 2)
