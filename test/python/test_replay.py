"""Offline replay (kinect-pipeline replay IN.bag -o OUT.bag) and the synthetic bag writer."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

import kinect_pipeline as kp
from kinect_pipeline.cli import main
from kinect_pipeline.simulation.robot import Rig, SegwayMotion
from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag
from kinect_pipeline.tools.replay import ReplayError, ReplayOptions, replay

FRAMES = 12


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bags") / "seq.bag"
    write_sequence_bag(path, Scenario(frames=FRAMES, encoding="16UC1", seed=3))
    return path


def read(path: Path, topic: str) -> list:
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Reader(path) as r:
        conns = [c for c in r.connections if c.topic == topic]
        return [ts.deserialize_ros1(raw, c.msgtype) for c, _, raw in r.messages(connections=conns)]


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_replay_writes_a_scan_per_frame_equal_to_the_core_at_the_tf_pose(bag: Path, tmp_path: Path) -> None:
    before = sha(bag)
    out = tmp_path / "out.bag"
    report = replay(bag, out, show_progress=False)
    assert sha(bag) == before, "the input changed"
    assert report.frames == report.processed == report.pose_from_tf == FRAMES
    images = read(out, "/kinect2/sd/image_depth")
    scans = read(out, "/kinect2/scan")
    cleaned = read(out, "/kinect2/sd/image_depth/processed")
    assert len(images) == len(scans) == len(cleaned) == FRAMES
    rig, motion, cam = Rig(), SegwayMotion(), kp.kinect_v2_camera()
    core = kp.Pipeline(cam, kp.Config())  # frame after frame, as replay runs it: what the refinement learns carries
    for img, scan, clean in zip(images, scans, cleaned, strict=False):
        assert (scan.header.stamp.sec, scan.header.stamp.nanosec) == (img.header.stamp.sec, img.header.stamp.nanosec)
        _, _, pitch, height = rig.sensor_pose(motion.pitch(img.header.seq))
        depth = np.frombuffer(img.data, np.uint16).reshape(img.height, img.width)
        stamp = img.header.stamp.sec + img.header.stamp.nanosec * 1e-9
        want = core.process_pose(depth, height, pitch, 0.0, stamp=stamp)
        same = np.isclose(scan.ranges, want.ranges, rtol=1e-4, atol=1e-5) | (
            np.isnan(scan.ranges) & np.isnan(want.ranges)
        )
        assert same.mean() >= 0.995
        got_clean = np.frombuffer(clean.data, np.uint16).reshape(clean.height, clean.width)
        assert (got_clean == want.depth).mean() >= 0.999


def test_rosbag_tools_read_both_bags(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.bag"
    replay(bag, out, show_progress=False)
    if shutil.which("rosbag") is None:
        pytest.skip("rosbag (Debian python3-rosbag) not installed")
    for path, topic in ((bag, "/kinect2/sd/image_depth"), (out, "/kinect2/scan")):
        info = subprocess.run(
            ["rosbag", "info", str(path)], capture_output=True, text=True, check=True, timeout=60
        ).stdout
        assert topic in info and f"{FRAMES} msgs" in info


def test_cli_refuses_to_overwrite_its_input(bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = sha(bag)
    assert main(["replay", str(bag), "-o", str(bag), "--quiet"]) == 1
    assert "never overwrites its input" in capsys.readouterr().err
    assert sha(bag) == before
    link = tmp_path / "same.bag"
    link.symlink_to(bag)
    with pytest.raises(ReplayError, match="is the input"):
        replay(bag, link, show_progress=False)
    existing = tmp_path / "exists.bag"
    existing.write_bytes(b"keep me")
    with pytest.raises(ReplayError, match="exists"):
        replay(bag, existing, show_progress=False)
    assert existing.read_bytes() == b"keep me"


def test_truncated_bag_is_refused_clearly_or_skipped_on_request(bag: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.bag"
    data = bag.read_bytes()
    cut.write_bytes(data[: len(data) * 2 // 3])
    with pytest.raises(ReplayError) as err:
        replay(cut, tmp_path / "a.bag", show_progress=False)
    assert str(cut) in str(err.value)
    assert not (tmp_path / "a.bag").exists(), "no partial output is left behind"
    assert not list(tmp_path.glob(".a.bag.partial*"))


def test_damaged_bytes_name_where_and_skip_bad_goes_on(bag: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.bag"
    data = bytearray(bag.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 4000] = b"\xff" * 4000
    bad.write_bytes(bytes(data))
    with pytest.raises(ReplayError, match=r"damaged|not a readable"):
        replay(bad, tmp_path / "b.bag", show_progress=False)
    try:
        report = replay(bad, tmp_path / "c.bag", ReplayOptions(skip_bad=True), show_progress=False)
    except ReplayError as exc:  # the index itself was hit: nothing can be skipped to
        assert "not a readable" in str(exc)
        return
    assert report.bad_messages >= 1 or report.processed < FRAMES
    assert (tmp_path / "c.bag").exists()


def test_missing_topics_are_named(tmp_path: Path, bag: Path) -> None:
    with pytest.raises(ReplayError, match="--depth-topic /nope"):
        replay(bag, tmp_path / "x.bag", ReplayOptions(depth_topic="/nope"), show_progress=False)
    with pytest.raises(ReplayError, match="--info-topic /a/camera_info: not in the bag"):
        replay(bag, tmp_path / "y.bag", ReplayOptions(info_topic="/a/camera_info"), show_progress=False)
    with pytest.raises(ReplayError, match="no such bag"):
        replay(tmp_path / "none.bag", tmp_path / "z.bag", show_progress=False)


def test_frames_without_tf_fall_back_or_are_skipped(bag: Path, tmp_path: Path) -> None:
    with pytest.raises(ReplayError, match=rf"no frame of .* could be processed, of {FRAMES}: .*not connected.*"):
        replay(bag, tmp_path / "s.bag", ReplayOptions(base_frame="nowhere", pose_fallback="skip"), show_progress=False)
    assert not list(tmp_path.iterdir()), "a replay that processed nothing writes nothing"
    r = replay(bag, tmp_path / "t.bag", ReplayOptions(base_frame="nowhere"), show_progress=False)
    assert r.pose_fallback == FRAMES and r.processed == FRAMES
    assert any("not connected" in p for p in r.problems)


def test_synth_refuses_to_overwrite(tmp_path: Path) -> None:
    p = tmp_path / "x.bag"
    p.write_bytes(b"mine")
    with pytest.raises(FileExistsError):
        write_sequence_bag(p, Scenario(frames=1))
    assert p.read_bytes() == b"mine"


def test_report_writes_pictures_and_an_index(bag: Path, tmp_path: Path) -> None:
    from kinect_pipeline.evaluation.report import write_report

    summary = write_report(bag, tmp_path / "rep", show_progress=False)
    for name in ("frame.png", "scan.png", "confidence.png", "timing.png", "index.html", "quality.json"):
        assert (tmp_path / "rep" / name).stat().st_size > 1000 or name == "quality.json", name
    page = (tmp_path / "rep" / "index.html").read_text()
    for name in ("frame.png", "scan.png", "confidence.png", "timing.png"):
        assert f'src="{name}"' in page
    assert summary["frames"] == FRAMES
    assert summary["label_agreement_min"] > 0.95
    # The goal's phantom count (noise allowed) and the plain 5 cm count, which can only be the larger.
    assert summary["phantom_beams"] <= 0.002, summary
    assert summary["phantom_beams"] <= summary["phantom_beams_5cm"] <= 1.0
    assert summary["missed_beams"] <= 0.01, summary
    assert json.loads((tmp_path / "rep" / "quality.json").read_text())["phantom_beams"] == summary["phantom_beams"]


# -- resuming an interrupted replay ----------------------------------------------------------------------------


def messages(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """Every message of a bag per topic: (time, raw bytes), read with rosbags."""
    from rosbags.rosbag1 import Reader

    out: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(path) as r:
        for c, t, raw in r.messages():
            out.setdefault(c.topic, []).append((t, bytes(raw)))
    return out


@pytest.fixture(scope="module")
def long_bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, list[tuple[int, bytes]]]]:
    """A 40-frame bag and the messages of its uninterrupted replay (with the intensity filter: the confidence
    history decides which beams are NaN, so a resumed run must restore it exactly)."""
    d = tmp_path_factory.mktemp("long")
    path = d / "long.bag"
    write_sequence_bag(path, Scenario(frames=40, encoding="16UC1", seed=5))
    replay(path, d / "clean.bag", ReplayOptions(config={"intensity_filter": True}), show_progress=False)
    return path, messages(d / "clean.bag")


FILTER = ReplayOptions(config={"intensity_filter": True})


@pytest.mark.parametrize("stop", [1, 4, 13, 39])
def test_resume_after_a_frame_limit_equals_an_uninterrupted_run(long_bag: tuple, tmp_path: Path, stop: int) -> None:
    path, clean = long_bag
    out = tmp_path / "out.bag"
    first = replay(path, out, FILTER, show_progress=False, max_frames=stop)
    assert first.stopped_early and first.processed == stop
    assert len(messages(out)["/kinect2/scan"]) == stop
    second = replay(path, out, FILTER, show_progress=False, resume=True)
    assert second.reused == stop and second.processed == 40 - stop, "only the missing frames are computed"
    assert second.warm_up <= 2 * 5 - 1
    got = messages(out)
    assert got.keys() == clean.keys()
    for topic in clean:
        assert got[topic] == clean[topic], topic
    assert not list(tmp_path.glob(".out.bag*"))


def test_resume_after_the_process_was_killed_equals_an_uninterrupted_run(long_bag: tuple, tmp_path: Path) -> None:
    import os
    import signal
    import sys
    import time

    path, clean = long_bag
    out = tmp_path / "out.bag"
    partial = tmp_path / ".out.bag.partial"
    cmd = [sys.executable, "-m", "kinect_pipeline.cli", "replay", str(path), "-o", str(out), "--quiet"]
    cmd += ["--param", "intensity_filter=true"]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for _attempt in range(3):  # killed once a few chunks are on disk; again if it finished first
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 120
        while proc.poll() is None and time.monotonic() < deadline:
            if partial.exists() and partial.stat().st_size > 6_000_000:
                os.kill(proc.pid, signal.SIGKILL)
                break
            time.sleep(0.002)
        proc.wait(timeout=60)
        proc.stderr.close()  # type: ignore[union-attr]
        if proc.returncode == -signal.SIGKILL:
            break
        out.unlink(missing_ok=True)
    assert proc.returncode == -signal.SIGKILL, "the replay finished before it could be killed, three times"
    assert partial.exists() and not out.exists()
    refused = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert refused.returncode == 1 and "--resume" in refused.stderr and str(partial) in refused.stderr
    resumed = subprocess.run([*cmd, "--resume"], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    taken = int(resumed.stdout.split("resumed: ")[1].split()[0])
    assert 1 <= taken < 40, resumed.stdout
    got = messages(out)
    for topic in clean:
        assert got[topic] == clean[topic], topic
    assert not list(tmp_path.glob(".out.bag*")), "the partial files are gone"


def test_resume_refuses_another_input_or_other_options(long_bag: tuple, bag: Path, tmp_path: Path) -> None:
    path, _ = long_bag
    out = tmp_path / "out.bag"
    with pytest.raises(ReplayError, match="nothing to resume"):
        replay(path, out, FILTER, show_progress=False, resume=True)
    replay(path, out, FILTER, show_progress=False, max_frames=3)
    before = sha(out)
    with pytest.raises(ReplayError, match=r"not a replay of this input with these options \(options\)"):
        replay(path, out, ReplayOptions(config={"intensity_filter": False}), show_progress=False, resume=True)
    with pytest.raises(ReplayError, match=r"\(depth_topic|\(input"):
        replay(bag, out, FILTER, show_progress=False, resume=True)
    assert sha(out) == before, "a refused resume leaves the earlier output as it was"
    other = tmp_path / "other.bag"
    other.write_bytes(bag.read_bytes())
    with pytest.raises(ReplayError, match="no replay record"):
        replay(path, other, FILTER, show_progress=False, resume=True)
    with pytest.raises(ReplayError, match="max_frames = 0"):
        replay(path, tmp_path / "z.bag", max_frames=0)
    with pytest.raises(TypeError, match="max_frames"):
        replay(path, tmp_path / "z.bag", max_frames=2.5)  # type: ignore[arg-type]


def test_resume_refuses_a_frame_limit_the_earlier_output_already_reaches(long_bag: tuple, tmp_path: Path) -> None:
    """Before, --resume --max-frames 1 into a 3-frame output rewrote it with 1 frame, exit 0: computed frames lost."""
    path, _ = long_bag
    out = tmp_path / "out.bag"
    replay(path, out, FILTER, show_progress=False, max_frames=3)
    before = sha(out)
    for limit in (1, 3):
        with pytest.raises(ReplayError, match=rf"--max-frames {limit}: .*out.bag holds 3 frames already.*above 3"):
            replay(path, out, FILTER, show_progress=False, resume=True, max_frames=limit)
        assert sha(out) == before
    more = replay(path, out, FILTER, show_progress=False, resume=True, max_frames=5)
    assert more.reused == 3 and more.processed == 2 and len(messages(out)["/kinect2/scan"]) == 5


def test_a_refused_resume_keeps_the_partial_file_it_could_not_take(long_bag: tuple, tmp_path: Path) -> None:
    """An interrupted replay's partial file made with other options: the refused --resume names it and leaves it
    (before, the refusal's clean-up deleted it)."""
    path, _ = long_bag
    out = tmp_path / "out.bag"
    replay(path, out, FILTER, show_progress=False, max_frames=3)
    partial = tmp_path / ".out.bag.partial"
    out.rename(partial)
    before = sha(partial)
    with pytest.raises(ReplayError, match=r"\.out\.bag\.partial is not a replay of this input with these options"):
        replay(path, out, ReplayOptions(), show_progress=False, resume=True)
    assert partial.exists() and sha(partial) == before and not out.exists()


def test_resume_into_a_complete_output_is_refused_as_nothing_to_do(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.bag"
    replay(bag, out, show_progress=False)
    before = sha(out)
    with pytest.raises(ReplayError, match=rf"out\.bag holds all {FRAMES} frames of the input already: nothing"):
        replay(bag, out, show_progress=False, resume=True)
    assert sha(out) == before
