"""Tools on bad input: a clear message naming the problem, exit 1, the input untouched, no partial output."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rosbags")

from kinect_pipeline.bag import write_sequence_bag


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bags") / "seq.bag"
    write_sequence_bag(path, frames=6, encoding="16UC1", seed=9)
    return path


def cli(*args: str, fsize: int | None = None) -> subprocess.CompletedProcess[str]:
    def limit() -> None:
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    return subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
    )


@pytest.mark.parametrize("content", [b"", b"#ROSBAG V2.0\n", b"not a bag at all" * 100])
def test_empty_or_garbage_bags_are_refused(tmp_path: Path, content: bytes) -> None:
    bad = tmp_path / "bad.bag"
    bad.write_bytes(content)
    r = cli("replay", str(bad), "-o", str(tmp_path / "out.bag"), "--quiet")
    assert r.returncode == 1
    assert str(bad) in r.stderr and "not a readable ROS 1 bag" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1, "one line, no traceback"
    assert not (tmp_path / "out.bag").exists()


def test_a_full_disk_loses_nothing(bag: Path, tmp_path: Path) -> None:
    before = bag.read_bytes()
    out = tmp_path / "out.bag"
    r = cli("replay", str(bag), "-o", str(out), "--quiet", fsize=1_000_000)
    assert r.returncode == 1
    assert "File too large" in r.stderr or "No space" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not out.exists() and not list(tmp_path.glob(".out.bag*"))
    assert bag.read_bytes() == before


def test_report_and_synth_fail_cleanly(bag: Path, tmp_path: Path) -> None:
    r = cli("report", str(tmp_path / "missing.bag"), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 1 and "missing.bag" in r.stderr
    existing = tmp_path / "mine.bag"
    existing.write_bytes(b"keep")
    r = cli("synth", str(existing), "--frames", "2", "--quiet")
    assert r.returncode == 1 and "exists" in r.stderr and existing.read_bytes() == b"keep"


def test_bag_without_depth_names_the_topics(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "nodepth.bag"
    with Writer(path) as w:
        c = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        w.write(c, 1, ts.serialize_ros1(ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))
    r = cli("replay", str(path), "-o", str(tmp_path / "o.bag"), "--quiet")
    assert r.returncode == 1 and "depth topic" in r.stderr and "--depth-topic" in r.stderr
    assert os.path.exists(path)
