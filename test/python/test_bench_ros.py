"""`kinect-pipeline bench-ros` and `soak`: each starts its own roscore on a free loopback port, the node, the nodelet
and a bare image_transport relay (roslaunch, the real nodelet manager), sends them rendered frames and stops every
process it started by its PID. Run here with few frames: what they measure is not asserted (timings are for the
benchmark's own tables), that they measure it, end, and leave nothing running is."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from ros_graph import NODE

pytestmark = pytest.mark.skipif(not NODE.exists(), reason="no build: run scripts/quickstart.sh first")

ROW = re.compile(r"^\| (image_transport relay|kinect_pipeline node|kinect_pipeline nodelet) \| (.*) \|$", re.M)


def _their_processes() -> set[int]:
    """The processes whose ROS_HOME is one of the tool's work folders (kp-bench-ros-*): what a run leaves behind."""
    found = set()
    for p in Path("/proc").glob("[0-9]*"):
        try:
            env = (p / "environ").read_bytes()
        except OSError:
            continue
        if b"ROS_HOME=" in env and b"/kp-bench-ros-" in env and int(p.name) != os.getpid():
            found.add(int(p.name))
    return found


def _run(tmp: Path, *args: str) -> tuple[int, str]:
    """Runs the tool with its temporary folders under ``tmp``: it leaves no process running and, having ended well,
    no work folder."""
    before = _their_processes()
    out = subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args],
        capture_output=True,
        text=True,
        timeout=240,
        env=dict(os.environ, TMPDIR=str(tmp)),
    )
    left = _their_processes() - before
    assert not left, f"{args}: processes left running: {sorted(left)}"
    if out.returncode == 0:
        kept = sorted(p.name for p in tmp.glob("kp-bench-ros-*"))
        assert not kept, f"{args}: work folders left behind: {kept}"
    return out.returncode, out.stdout + out.stderr


def _rows(text: str) -> dict[str, list[str]]:
    return {name: [c.strip() for c in cells.split("|")] for name, cells in ROW.findall(text)}


@pytest.mark.parametrize("sequential", [False, True], ids=["interleaved", "sequential"])
def test_bench_ros_measures_relay_node_and_nodelet(sequential: bool, tmp_path: Path) -> None:
    rc, text = _run(tmp_path, "bench-ros", "--frames", "15", *(["--sequential"] if sequential else []))
    assert rc == 0, text
    rows = _rows(text)
    assert set(rows) == {"image_transport relay", "kinect_pipeline node", "kinect_pipeline nodelet"}, text
    for name, (sent, received, dropped, median, p99, _added, cpu) in rows.items():
        assert (sent, received, dropped) == ("15", "15", "0"), f"{name}: {text}"
        assert 0.0 < float(median) <= float(p99) < 1000.0, f"{name}: {text}"
        assert math.isfinite(float(cpu)), f"{name}: {text}"
    assert ("one subject after the other" in text) == sequential


def test_soak_counts_every_frame_through_the_nodelet(tmp_path: Path) -> None:
    rc, text = _run(tmp_path, "soak", "--minutes", "0.01", "--subject", "nodelet")  # 18 frames at 30 Hz
    assert rc == 0, text
    rows = _rows(text)
    assert list(rows) == ["kinect_pipeline nodelet"], text
    frames_in, out, dropped, *_ = rows["kinect_pipeline nodelet"]
    assert (frames_in, out, dropped) == ("18", "18", "0"), text
    counters = re.search(r"its diagnostics at the end .*: frames in (\d+), frames out (\d+)", text)
    assert counters and int(counters[1]) >= 18 and counters[1] == counters[2], text


def test_the_ros_tests_name_and_stop_a_node_that_outlives_its_roslaunch(tmp_path: Path) -> None:
    """The graph that started a roscore checks at its end that nothing it started is left: here roslaunch is killed
    outright, so the node it started (in a session of its own) is left behind."""
    import signal

    from ros_graph import RosGraph, wait_for

    g = RosGraph(tmp_path)
    g.start_core()
    launch = g.launch("launch", "kinect_pipeline.launch", "pose_source:=static")
    wait_for("the node", lambda: any("kinect_pipeline_node" in c for c in g.leftovers().values()))
    os.killpg(launch.pid, signal.SIGKILL)
    launch.wait(timeout=10)
    with pytest.raises(AssertionError, match=r"processes left running after the test: .*kinect_pipeline_node"):
        g.stop_all()
    assert not g.leftovers(), "what was left is stopped"


def test_a_run_that_did_not_end_well_keeps_its_logs_and_says_where(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """What run() does with its work folder at its end: removed after a run that ended well; kept, its path on
    stderr, after one that did not (its logs say what went wrong)."""
    from kinect_pipeline.tools.bench_ros import _clean_up

    work = tmp_path / "kp-bench-ros-x"
    (work / "log").mkdir(parents=True)
    _clean_up(work, done=False)
    assert (work / "log").is_dir()
    assert str(work) in capsys.readouterr().err
    _clean_up(work, done=True)
    assert not work.exists()
