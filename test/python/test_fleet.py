"""kinect-pipeline fleet on real Dask: a LocalCluster over ROS 1 bags, rosbag2 (sqlite3, mcap) and a folder of
frames mixed with a damaged bag; a rerun that does nothing; configurations compared; and a real `dask scheduler`
with two `dask worker` processes on loopback, one of them killed (by its own PID) while it works. Small synthetic
bags written with the package's own writer; the processes are started and stopped here (deadlines, no sleeps)."""

from __future__ import annotations

import csv
import hashlib
import json
import math
import os
import queue
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags")
distributed = pytest.importorskip("distributed")

from clitool import cli

import kinect_pipeline as kp
from kinect_pipeline.bags.messages import depth_array
from kinect_pipeline.bags.reader import open_bag
from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag
from kinect_pipeline.tools.fleet import (
    EVENT_TOPIC,
    FleetError,
    FleetOptions,
    find_recordings,
    load_config,
    measure_recording,
)
from kinect_pipeline.tools.replay import ReplayOptions

FRAMES = 6
LONG = 80  #: frames of the recordings one of whose workers is killed: work still in hands when both are frozen


def sha(path: Path) -> str:
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    return hashlib.sha256(b"".join(f.read_bytes() for f in files)).hexdigest()


def rows_of(out: Path) -> list[dict[str, str]]:
    with (out / "fleet.csv").open() as fh:
        return list(csv.DictReader(fh))


def frames_folder(bag: Path, folder: Path) -> Path:
    """The depth frames of a bag as .npy files (float metres), a recording given as a folder of frames."""
    folder.mkdir()
    with open_bag(bag) as b:
        conns = [c for c in b.connections if c.topic == "/kinect2/sd/image_depth"]
        for i, (conn, _, raw) in enumerate(b.messages(conns)):
            d = depth_array(b.decode(conn, raw))
            np.save(folder / f"{i:04d}.npy", (d.astype(np.float32) / 1000.0) if d.dtype == np.uint16 else d)
    return folder


@pytest.fixture(scope="module")
def recs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("fleet_in")
    out = {
        "ros1": d / "a.bag",
        "ros1_b": d / "b.bag",
        "sqlite3": d / "c_sqlite",
        "mcap": d / "d.mcap",
    }
    for i, (kind, path) in enumerate(out.items()):
        # b.bag's tf states the mount 5 cm too high and 1 deg too far down: the floor refinement learns it
        wrong = (0.05, math.radians(1.0), 0.0) if kind == "ros1_b" else (0.0, 0.0, 0.0)
        fmt = "sqlite3" if kind == "sqlite3" else None
        write_sequence_bag(path, Scenario(frames=FRAMES, seed=10 + i, tf_error=wrong), fmt=fmt)
    data = out["ros1_b"].read_bytes()
    out["damaged"] = d / "damaged.bag"
    out["damaged"].write_bytes(data[: len(data) // 2])  # cut in the middle, as a recording whose disk filled up
    out["frames"] = frames_folder(out["ros1"], d / "e_frames")
    return out


def check_row(row: dict[str, str], frames: int) -> None:
    assert row["status"] == "ok", row
    assert int(row["frames"]) == int(row["processed"]) == frames
    assert int(row["dropped"]) == 0 and int(row["damaged"]) == 0
    assert float(row["ms_per_frame"]) > 0 and float(row["core_ms"]) > 0
    reasons = json.loads(row["fit_reasons"])
    assert sum(reasons.values()) == frames and set(reasons) <= {
        "off", "accepted", "too few pixels", "spread too large", "out of bounds", "ill-conditioned",
    }  # fmt: skip
    assert math.isclose(float(row["fit_accepted"]), reasons.get("accepted", 0) / frames)
    for col in ("learned_height_m", "learned_pitch_deg", "learned_roll_deg", "drift_pitch_deg", "cliff_beams"):
        assert math.isfinite(float(row[col])), col
    assert abs(float(row["learned_pitch_deg"])) < 5 and abs(float(row["learned_height_m"])) < 0.2
    assert 0 <= float(row["scan_change"]) <= 1


def test_local_cluster_mixed_inputs_a_damaged_bag_and_a_rerun_that_does_nothing(
    recs: dict[str, Path], tmp_path: Path
) -> None:
    before = {k: sha(p) for k, p in recs.items()}
    listed = tmp_path / "more.txt"
    listed.write_text(f"# the rosbag2 ones\n{recs['sqlite3']}\n{recs['mcap']}\n")
    out = tmp_path / "out"
    cam = kp.kinect_v2_camera()
    args = [
        "fleet", str(recs["ros1"].parent / "[ab].bag"), str(listed), str(recs["damaged"]), str(recs["frames"]),
        "-o", str(out), "--intrinsics", str(cam.fx), str(cam.fy), str(cam.cx), str(cam.cy),
    ]  # fmt: skip
    r = cli(*args, "--workers", "2")
    assert r.returncode == 1, r.stderr
    assert "damaged.bag [default]: damaged" in r.stderr and "dashboard http://127.0.0.1:" in r.stderr
    assert "6/6 recordings" in r.stderr
    rows = {Path(x["recording"]).name: x for x in rows_of(out)}
    assert sorted(rows) == ["a.bag", "b.bag", "c_sqlite", "d.mcap", "damaged.bag", "e_frames"]
    for name in ("a.bag", "b.bag", "c_sqlite", "d.mcap", "e_frames"):
        check_row(rows[name], FRAMES)
        assert rows[name]["config"] == "default"
    for name in ("a.bag", "b.bag", "c_sqlite", "d.mcap"):  # they carry a LiDAR scan: the phantom proxy
        assert 0 < float(rows[name]["phantom_proxy"]) <= 1  # the lab's low boxes lie under the LiDAR plane
    assert rows["e_frames"]["phantom_proxy"] == ""  # no LiDAR in a folder of frames
    assert rows["damaged.bag"]["status"].startswith("damaged: ") and "byte" in rows["damaged.bag"]["status"]
    assert rows["e_frames"]["kind"] == "frames" and rows["a.bag"]["kind"] == "bag"
    # a right tf: nothing learned; b.bag's wrong mount: a correction towards it, learned from the first frames on
    # (each fit weighs by its precision), so it hardly drifts over the recording
    assert float(rows["a.bag"]["learned_height_m"]) == 0 and float(rows["a.bag"]["drift_pitch_deg"]) == 0
    assert float(rows["b.bag"]["learned_height_m"]) < -0.001
    assert 0 <= float(rows["b.bag"]["drift_height_m"]) < 0.5 * abs(float(rows["b.bag"]["learned_height_m"]))
    doc = json.loads((out / "fleet.json").read_text())
    assert all(len(x["series"]) == FRAMES for x in doc["rows"] if x["status"] == "ok")
    page = (out / "index.html").read_text()
    assert page.index("damaged.bag") < page.index("b.bag") < page.index("a.bag")  # not ok, then the worst mount
    assert (out / "learned.png").stat().st_size > 0
    assert {k: sha(p) for k, p in recs.items()} == before, "an input changed"

    table = (out / "fleet.json").read_bytes()
    again = cli(*args, "--workers", "2")
    assert again.returncode == 1 and "damaged.bag [default]: damaged" in again.stderr
    assert "0 done now" in again.stdout and "6 up to date" in again.stdout
    assert "dashboard" not in again.stderr  # no cluster started
    assert (out / "fleet.json").read_bytes() == table

    os.utime(recs["ros1"], ns=(time.time_ns(), time.time_ns()))  # touched: done again, the rest skipped
    cpus = len(os.sched_getaffinity(0))
    once_more = cli(*args, "--workers", str(cpus + 1), "--quiet")  # more workers than CPUs: warned, even when quiet
    assert "1 done now" in once_more.stdout and "5 up to date" in once_more.stdout
    assert f"warning: --workers {cpus + 1} is more than the {cpus} CPU(s) this process may use" in once_more.stderr
    assert "is more than the" not in r.stderr or cpus < 2  # 2 workers on 2 CPUs or more: no warning


def test_a_task_in_this_process_skip_bad_measures_the_intact_part(recs: dict[str, Path]) -> None:
    """The task itself, without Dask (no worker: no progress events): --skip-bad measures a cut bag's intact
    frames and still says it is damaged; without it, nothing is measured."""
    opts = FleetOptions(replay=ReplayOptions(skip_bad=True))
    (row,) = measure_recording(str(recs["damaged"]), opts, [("default", {})])
    assert row["status"].startswith("damaged: ") and row["damaged"] >= 1 and row["worker"] == ""
    assert 0 < row["processed"] == row["frames"] < FRAMES
    assert len(row["series"]) == row["processed"]
    (row,) = measure_recording(str(recs["damaged"]), FleetOptions(), [("default", {})])
    assert row["status"].startswith("damaged: ") and row["processed"] == 0


def test_configurations_compared(recs: dict[str, Path], tmp_path: Path) -> None:
    a, same, b = tmp_path / "a.yaml", tmp_path / "same.yaml", tmp_path / "nofloor.yaml"
    a.write_text("refine_floor: true\n")
    same.write_text("refine_floor: true  # the same\n")
    b.write_text("refine_floor: false\nthreshold_curve: '0.5:0.2, 12:0.2'\n")
    out = tmp_path / "out"
    r = cli(
        "fleet", str(recs["ros1"]), str(recs["mcap"]), "-o", str(out), "--workers", "1", "--quiet",
        "--config", str(a), "--compare", str(same), "--compare", str(b), "--grid", "floor_min_pixels=500,5000000",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    rows = rows_of(out)
    assert len(rows) == 2 * 5
    by = {(Path(x["recording"]).name, x["config"]): x for x in rows}
    for rec in ("a.bag", "d.mcap"):
        assert by[(rec, "a")]["vs_config"] == "" and by[(rec, "same")]["vs_config"] == "a"
        assert float(by[(rec, "same")]["beams_moved"]) == 0 and float(by[(rec, "same")]["fit_changed"]) == 0
        assert by[(rec, "same")]["fit_reasons"] == by[(rec, "a")]["fit_reasons"]
        assert json.loads(by[(rec, "nofloor")]["fit_reasons"]) == {"off": FRAMES}
        assert float(by[(rec, "nofloor")]["beams_moved"]) > 0.01
        assert float(by[(rec, "nofloor")]["fit_changed"]) == 1.0
        never = json.loads(by[(rec, "floor_min_pixels=5000000")]["fit_reasons"])
        assert never == {"too few pixels": FRAMES}
        assert float(by[(rec, "floor_min_pixels=5000000")]["learned_pitch_deg"]) == 0
    assert by[("a.bag", "a")]["config_hash"] == by[("a.bag", "same")]["config_hash"]
    assert len({x["config_hash"] for x in rows}) == 4


def test_inputs_and_configurations_are_checked(recs: dict[str, Path], tmp_path: Path) -> None:
    d = recs["ros1"].parent
    assert find_recordings([str(d / "*.bag"), str(d / "a.bag")]) == [d / "a.bag", d / "b.bag", d / "damaged.bag"]
    with pytest.raises(FleetError, match=r"nothing\*\.bag: matches no file"):
        find_recordings([str(d / "nothing*.bag")])
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensor_hieght: 1.0\n")
    with pytest.raises(FleetError, match=r"bad\.yaml: no Config field 'sensor_hieght'"):
        load_config(bad, {})
    r = cli("fleet", str(recs["sqlite3"]), "-o", str(recs["sqlite3"] / "out"))
    assert r.returncode == 1 and "lies inside the input folder" in r.stderr
    empty = tmp_path / "none.txt"
    empty.write_text("# nothing yet\n\n")
    with pytest.raises(FleetError, match=r"none\.txt: lists no recording: expected a path or glob a line"):
        find_recordings([str(empty)])
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\xb3\x00\xff")
    with pytest.raises(FleetError, match=r"binary\.yaml: cannot read a configuration: .*codec"):
        load_config(binary, {})
    broken = tmp_path / "broken.yaml"
    broken.write_text("sensor_height: [1.0\n")
    with pytest.raises(FleetError, match=r"broken\.yaml: cannot read a configuration: [^\n]*$"):
        load_config(broken, {})
    r = cli("fleet", str(recs["ros1"]), "-o", str(tmp_path / "g"), "--scheduler", "garbage", "--quiet")
    assert r.returncode == 1 and "--scheduler garbage: cannot reach a Dask scheduler there" in r.stderr, r.stderr
    r = cli("fleet", str(tmp_path / "missing.bag"), "-o", str(tmp_path / "o"), "--workers", "1", "--quiet")
    assert r.returncode == 1 and "missing.bag [default]: unreadable: " in r.stderr and "no such file" in r.stderr


# -- a real scheduler and two workers -----------------------------------------------------------------------------


def _dask(*args: str, log: Path) -> subprocess.Popen[bytes]:
    exe = Path(sys.executable).with_name("dask")
    with log.open("wb") as fh:
        return subprocess.Popen([str(exe), *args], stdout=fh, stderr=subprocess.STDOUT, start_new_session=True)


def _stop(procs: list[subprocess.Popen[bytes]]) -> None:
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(timeout=10)


def _address(scheduler_file: Path, proc: subprocess.Popen[bytes], deadline: float) -> str:
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the scheduler exited"
        try:
            return str(json.loads(scheduler_file.read_text())["address"])
        except (OSError, ValueError, KeyError):
            time.sleep(0.05)  # polling the file, under the deadline
    raise AssertionError("no scheduler address within the deadline")


@pytest.fixture
def cluster(tmp_path: Path) -> Any:
    """A `dask scheduler` and two `dask worker` processes (no nanny: the PID is the worker) on 127.0.0.1."""
    sf = tmp_path / "scheduler.json"
    procs = [
        _dask(
            "scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address", "127.0.0.1:0",
            "--scheduler-file", str(sf), "--no-show", log=tmp_path / "scheduler.log",
        )
    ]  # fmt: skip
    try:
        address = _address(sf, procs[0], time.monotonic() + 60)
        workers = {}
        for name in ("w0", "w1"):
            w = _dask(
                "worker", address, "--name", name, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1",
                "--no-dashboard", "--death-timeout", "60", log=tmp_path / f"{name}.log",
            )  # fmt: skip
            procs.append(w)
            workers[name] = w
        with distributed.Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
            yield address, workers, client
    finally:
        _stop(procs)


def _next_event(
    events: queue.Queue[dict[str, Any]], run: subprocess.Popen[str], deadline: float, tmp_path: Path
) -> dict[str, Any]:
    """The next fleet event, before the deadline and while the run goes on."""
    while True:
        assert time.monotonic() < deadline, "no recording caught at work within the deadline"
        assert run.poll() is None, (tmp_path / "fleet.log").read_text()
        try:
            return events.get(timeout=1)
        except queue.Empty:
            continue


def _collect(events: queue.Queue[dict[str, Any]], seen: list[dict[str, Any]], seconds: float) -> None:
    """The events that arrive within seconds, appended to seen."""
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        try:
            seen.append(events.get(timeout=left))
        except queue.Empty:
            return


def _in_flight(seen: list[dict[str, Any]]) -> dict[str, Any] | None:
    """An event of a recording its worker reported started (a frame or more) and not done, or None."""
    last = {(ev["worker"], ev["recording"]): ev for ev in seen}
    return next((ev for ev in last.values() if not ev["done"] and ev["frames"] >= 1), None)


@pytest.fixture(scope="module")
def longer(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    d = tmp_path_factory.mktemp("fleet_long")
    paths = [d / "r0.bag", d / "r1_sqlite", d / "r2.bag", d / "r3_sqlite"]
    for p in paths[:2]:
        write_sequence_bag(p, Scenario(frames=LONG, seed=30), fmt="sqlite3" if p.name.endswith("sqlite") else None)
    shutil.copyfile(paths[0], paths[2])  # copies: other recordings of the same drive
    shutil.copytree(paths[1], paths[3])
    return paths


def test_real_scheduler_two_workers_one_killed_while_it_works(cluster: Any, longer: list[Path], tmp_path: Path) -> None:
    address, workers, client = cluster
    events: queue.Queue[dict[str, Any]] = queue.Queue()
    client.subscribe_topic(EVENT_TOPIC, lambda ev: events.put(ev[1]))
    out = tmp_path / "out"
    log = (tmp_path / "fleet.log").open("w")
    run = subprocess.Popen(
        [sys.executable, "-m", "kinect_pipeline.cli", "fleet", *map(str, longer), "-o", str(out),
         "--scheduler", address, "--workers", "2"],
        stdout=log, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        seen: list[dict[str, Any]] = []  # every event so far
        while True:
            seen.append(_next_event(events, run, deadline, tmp_path))
            # Both workers frozen (their own PIDs): nothing more is sent or done. What they sent before the stop
            # arrives within the grace; a recording a worker reported started and not done is then in its hands.
            for w in workers.values():
                os.kill(w.pid, signal.SIGSTOP)
            _collect(events, seen, 0.5)
            busy = _in_flight(seen)
            if busy is not None:
                break
            for w in workers.values():
                os.kill(w.pid, signal.SIGCONT)
        victim = workers[client.scheduler_info()["workers"][busy["worker"]]["name"]]
        os.kill(victim.pid, signal.SIGKILL)  # while it works on busy["recording"]
        for w in workers.values():
            if w is not victim:
                os.kill(w.pid, signal.SIGCONT)
        assert victim.wait(timeout=30) == -signal.SIGKILL
        assert run.wait(timeout=240) == 0, (tmp_path / "fleet.log").read_text()
    finally:
        for w in workers.values():
            if w.poll() is None:
                os.kill(w.pid, signal.SIGCONT)  # none left frozen for the fixture's SIGTERM
        if run.poll() is None:
            run.kill()
            run.wait(timeout=10)
        log.close()
    rows = rows_of(out)
    assert sorted(Path(r["recording"]).name for r in rows) == sorted(p.name for p in longer)  # each exactly once
    for r in rows:
        check_row(r, LONG)
    redone = next(r for r in rows if r["recording"] == busy["recording"])
    assert redone["worker"] and redone["worker"] != busy["worker"]  # retried on the other worker
    text = (tmp_path / "fleet.log").read_text()
    assert "dashboard http://127.0.0.1:" in text and "4/4 recordings" in text
