"""compressedDepth topics in bags: replay, report, calibrate --bag and quality --bag read them. The payloads are
made here as compressed_depth_image_transport writes them: the 12-byte header packed with struct and the PNG made
by OpenCV's encoder (32FC1: the core's encoder, with the inverse-depth quantisation); ROS 1 and rosbag2."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")
cv2 = pytest.importorskip("cv2")

from kinect_pipeline.bags.reader import open_bag
from kinect_pipeline.bags.writer import BagWriter
from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag
from kinect_pipeline.tools.replay import ReplayError, replay

FRAMES = 4
RAW = "/kinect2/sd/image_depth"


def opencv_payload(mm: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", mm)
    assert ok
    return struct.pack("<iff", 0, 0.0, 0.0) + buf.tobytes()


def recompress(src: Path, dst: Path, fmt: str, text: str = "16UC1; compressedDepth png", damage: int = -1) -> None:
    """A copy of a synthetic bag whose depth Image topic is replaced by its compressedDepth topic (frame ``damage``
    cut short)."""
    with open_bag(src) as bag:
        w = BagWriter(dst, fmt, name=dst.name)
        outs = {}
        for c in bag.connections:
            if c.topic == RAW:
                outs[c.id] = w.add(RAW + "/compressedDepth", "sensor_msgs/msg/CompressedImage")
            else:
                outs[c.id] = w.copy(bag, c)
        k = 0
        for conn, t, raw in bag.messages():
            if conn.topic != RAW:
                w.write_copy(outs[conn.id], t, raw)
                continue
            img = bag.decode(conn, raw)
            mm = np.frombuffer(img.data, np.uint16).reshape(img.height, img.width)
            data = opencv_payload(mm)
            if k == damage:
                data = data[: len(data) // 2]
            k += 1
            msg = w.types["sensor_msgs/msg/CompressedImage"](
                header=kp_header(w, img), format=text, data=np.frombuffer(data, np.uint8)
            )
            w.write(outs[conn.id], t, w.encode(msg, "sensor_msgs/msg/CompressedImage"))
        w.close()


def kp_header(w: BagWriter, img: object) -> object:
    from kinect_pipeline.bags.messages import header

    return header(w.types, img.header.stamp, img.header.frame_id, getattr(img.header, "seq", 0))  # type: ignore[attr-defined]


@pytest.fixture(scope="module")
def raw_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("raw") / "raw.bag"
    write_sequence_bag(path, Scenario(frames=FRAMES, encoding="16UC1", seed=12))
    return path


def scans(path: Path) -> list[np.ndarray]:
    with open_bag(path) as bag:
        conns = [c for c in bag.connections if c.topic == "/kinect2/scan"]
        return [np.array(bag.decode(c, raw).ranges) for c, _, raw in bag.messages(conns)]


@pytest.mark.parametrize("fmt", ["ros1", "mcap"])
@pytest.mark.parametrize("text", ["16UC1; compressedDepth png", "16UC1; compressedDepth"])
def test_replay_of_compressed_depth_gives_the_raw_bags_scans(
    raw_bag: Path, tmp_path: Path, fmt: str, text: str
) -> None:
    comp = tmp_path / ("c.bag" if fmt == "ros1" else "c")
    recompress(raw_bag, comp, fmt, text)
    r = replay(comp, tmp_path / "out", show_progress=False)
    assert r.processed == FRAMES and r.depth_topic == RAW + "/compressedDepth"
    ref = tmp_path / "ref.bag"
    replay(raw_bag, ref, show_progress=False)
    for a, b in zip(scans(tmp_path / "out"), scans(ref), strict=True):
        np.testing.assert_array_equal(a, b)
    with open_bag(tmp_path / "out") as out:
        topics = {c.topic for c in out.connections}
    assert RAW + "/processed" in topics and "/kinect2/cliff_scan" in topics


def test_report_calibrate_and_quality_read_compressed_depth(raw_bag: Path, tmp_path: Path) -> None:
    comp = tmp_path / "c"
    recompress(raw_bag, comp, "sqlite3")
    run = lambda *a: subprocess.run(  # noqa: E731
        [sys.executable, "-m", "kinect_pipeline.cli", *a], capture_output=True, text=True, timeout=300
    )
    r = run("report", str(comp), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "rep" / "quality.json").read_text())["frames"] == FRAMES
    r = run("calibrate", "--bag", str(comp), "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["summary"]["frames_with_floor"] == FRAMES
    r = run("quality", "--bag", str(comp), "--quiet")
    assert r.returncode == 0, r.stderr
    assert f"{FRAMES} frames against its ground truth" in r.stdout and "| phantom beams |" in r.stdout


def test_float_compressed_depth_through_the_cores_encoder(tmp_path: Path) -> None:
    bag = tmp_path / "f.bag"
    write_sequence_bag(bag, Scenario(frames=3, encoding="32FC1", seed=2, compressed=True))
    r = replay(bag, tmp_path / "o.bag", show_progress=False)
    assert r.processed == 3
    with open_bag(tmp_path / "o.bag") as out:
        conn = next(c for c in out.connections if c.topic == RAW + "/processed")
        clean = [out.decode(conn, raw) for _, _, raw in out.messages([conn])]
    assert all(c.encoding == "32FC1" for c in clean)


def test_a_damaged_payload_is_named_and_the_other_frames_go_on(raw_bag: Path, tmp_path: Path) -> None:
    comp = tmp_path / "d.bag"
    recompress(raw_bag, comp, "ros1", damage=1)
    r = replay(comp, tmp_path / "o.bag", show_progress=False)
    assert r.processed == FRAMES - 1
    assert any("compressedDepth" in p or "PNG" in p or "png" in p for p in r.problems), r.problems
    every = tmp_path / "all.bag"
    recompress(raw_bag, every, "ros1", text="16UC1; compressedDepth zip")
    with pytest.raises(ReplayError, match=r"no frame of .*compressedDepth could be processed"):
        replay(every, tmp_path / "p.bag", show_progress=False)
