"""Tools on bad input: a clear message naming the problem, exit 1, the input untouched, no partial output."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from clitool import cli

pytest.importorskip("rosbags")

from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bags") / "seq.bag"
    write_sequence_bag(path, Scenario(frames=6, encoding="16UC1", seed=9))
    return path


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


# -- damaged bags: every case names the byte offset and the topic, and --skip-bad goes on past it ----------------


def _index(path: Path) -> list[tuple[int, str, int]]:
    """(byte offset of the message record, topic, time) of every message of a healthy bag, from rosbags' index."""
    from rosbags.rosbag1 import Reader

    with Reader(path) as r:
        topics = {c.id: c.topic for c in r.connections}
        out = [
            (r.chunks[e.chunk_pos].datapos + e.offset, topics[cid], e.time)
            for cid, entries in r.indexes.items()
            for e in entries
        ]
    return sorted(out)


def _damage(bag: Path, tmp_path: Path, how: str) -> tuple[Path, int, str | None]:
    """A damaged copy of ``bag`` and the byte offset and topic the message must name."""
    import struct

    data = bytearray(bag.read_bytes())
    msgs = _index(bag)
    depth = [m for m in msgs if m[1] == "/kinect2/sd/image_depth"]
    index_pos = struct.unpack("<Q", data[data.find(b"index_pos=") + 10 :][:8])[0]
    if how == "cut_in_chunk":  # in the middle of the 4th depth image's data
        off = depth[3][0]
        data = data[: off + 200_000]
        return _write(tmp_path, how, data), off, "/kinect2/sd/image_depth"
    if how == "zeroed_record_header":  # the 3rd depth image's record header
        off = depth[2][0]
        data[off : off + 24] = bytes(24)
        return _write(tmp_path, how, data), off, "/kinect2/sd/image_depth"
    if how == "zeroed_chunk_header":  # the second chunk's record header
        off = data.find(b"\x04\x00\x00\x00op=\x05", depth[0][0]) - 4
        data[off : off + 24] = bytes(24)
        return _write(tmp_path, how, data), off, None
    if how == "no_index":  # cut where the index starts (the bag header still points there)
        return _write(tmp_path, how, data[:index_pos]), index_pos, msgs[-1][1]
    if how == "index_pos_zero":  # a recording that was never closed: rosbag writes index_pos 0
        j = data.find(b"index_pos=") + 10
        data[j : j + 8] = bytes(8)
        return _write(tmp_path, how, data[:index_pos]), index_pos, msgs[-1][1]
    raise AssertionError(how)


def _write(tmp_path: Path, name: str, data: bytes | bytearray) -> Path:
    p = tmp_path / f"{name}.bag"
    p.write_bytes(bytes(data))
    return p


DAMAGE = ["cut_in_chunk", "zeroed_record_header", "zeroed_chunk_header", "no_index", "index_pos_zero"]


@pytest.mark.parametrize("how", DAMAGE)
def test_damaged_bags_are_refused_naming_offset_and_topic(bag: Path, tmp_path: Path, how: str) -> None:
    bad, offset, topic = _damage(bag, tmp_path, how)
    before = bad.read_bytes()
    out = tmp_path / "out.bag"
    r = cli("replay", str(bad), "-o", str(out), "--quiet")
    assert r.returncode == 1, r.stdout
    line = r.stderr.strip()
    assert len(line.splitlines()) == 1, "one line, no traceback"
    assert str(bad) in line and f"byte {offset}" in line, line
    assert f"topic {topic}" in line if topic else "topic " in line, line
    assert "--skip-bad" in line
    assert not out.exists() and not list(tmp_path.glob(".out.bag*"))
    assert bad.read_bytes() == before


@pytest.mark.parametrize("how", DAMAGE)
def test_skip_bad_replays_the_intact_frames_and_says_where(bag: Path, tmp_path: Path, how: str) -> None:
    from rosbags.rosbag1 import Reader

    bad, offset, _ = _damage(bag, tmp_path, how)
    out = tmp_path / "out.bag"
    r = cli("replay", str(bad), "-o", str(out), "--quiet", "--skip-bad")
    assert r.returncode == 0, r.stderr
    assert f"byte {offset}" in r.stdout, r.stdout
    with Reader(out) as rd:
        counts = {c.topic: c.msgcount for c in rd.connections}
    frames = counts["/kinect2/sd/image_depth"]
    assert counts["/kinect2/scan"] == frames
    want = {"cut_in_chunk": 3, "zeroed_record_header": 5, "zeroed_chunk_header": None}.get(how, 6)
    if want is not None:
        assert frames == want, (how, counts)
    else:  # the damaged chunk's frames are lost, the others replayed
        assert 1 <= frames < 6
    damaged = int(r.stdout.split("damaged ")[1].split()[0])
    assert damaged >= (1 if how in ("cut_in_chunk", "zeroed_record_header", "zeroed_chunk_header") else 0)


def test_a_non_bag_and_an_empty_file_name_what_they_are(tmp_path: Path) -> None:
    empty = _write(tmp_path, "empty", b"")
    r = cli("replay", str(empty), "-o", str(tmp_path / "o.bag"), "--quiet", "--skip-bad")
    assert r.returncode == 1 and "empty file (0 bytes)" in r.stderr
    text = _write(tmp_path, "text", b"just some text\n" * 10)
    r = cli("replay", str(text), "-o", str(tmp_path / "o.bag"), "--quiet")
    assert r.returncode == 1 and "b'just some tex'" in r.stderr and "#ROSBAG V2.0" in r.stderr


@pytest.mark.parametrize(("name", "what"), [("x.mcap", "not an MCAP file"), ("x.db3", "not a rosbag2 sqlite3 file")])
def test_a_non_bag_named_as_rosbag2_is_told_against_the_format_its_name_says(
    tmp_path: Path, name: str, what: str
) -> None:
    """A text file named .mcap or .db3 was told against the ROS 1 header ('expected #ROSBAG V2.0')."""
    text = tmp_path / name
    text.write_bytes(b"just some text\n")
    r = cli("replay", str(text), "-o", str(tmp_path / ("o" + text.suffix)), "--quiet")
    assert r.returncode == 1 and f"{text}: {what}: it starts with b'just some text" in r.stderr, r.stderr
    assert "ROSBAG" not in r.stderr
