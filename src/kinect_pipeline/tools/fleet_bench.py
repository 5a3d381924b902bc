"""``kinect-pipeline fleet --bench``: recordings and frames per second of the fleet with 1 and 2 workers, next to a
plain ``replay`` of the same bags and the fleet's task run in this process (no Dask), in one run. A benchmark that
prints, not a test that asserts."""

from __future__ import annotations

import os
import shutil
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from ..simulation.sequence_bag import Scenario, write_sequence_bag
from .fleet import FleetOptions, FleetResult, Table, _client, _Progress, _run_jobs, measure_recording, plan
from .replay import replay


def _bags(work: Path, recordings: int, frames: int) -> list[Path]:
    """One synthetic bag of ``frames`` frames and copies of it: the same work per recording."""
    first = work / "rec0.bag"
    write_sequence_bag(first, Scenario(frames=frames, seed=5))
    paths = [first]
    for i in range(1, recordings):
        paths.append(work / f"rec{i}.bag")
        shutil.copyfile(first, paths[-1])
    return paths


def _noop(i: int) -> int:
    return i


def _warm(path: str) -> None:
    """A process's one-time start, done before the clock runs: the imports and rosbags' message types (a task on a
    2-frame bag)."""
    _check([measure_recording(path, FleetOptions(), [("default", {})])[0]], 2)


def _check(rows: list[dict[str, Any]], frames: int) -> None:
    bad = [f"{r['recording']}: {r['status']}, {r['processed']} frames" for r in rows if r["processed"] != frames]
    if bad:
        raise RuntimeError(f"the benchmark's recordings were not measured whole: {bad[:2]}")


def _fleet(paths: list[Path], out: Path, workers: int, warm: Path, frames: int) -> tuple[float, float, float]:
    """(seconds to start the LocalCluster and import the package in its workers, seconds for the recordings,
    median seconds of a Dask round trip of an empty task) with ``workers`` workers."""
    from distributed import as_completed

    opts = FleetOptions()
    configs: list[tuple[str, dict[str, Any]]] = [("default", {})]
    out.mkdir()
    table = Table(out)
    jobs, _ = plan(paths, configs, opts, table, redo=True)
    t0 = time.perf_counter()
    client, cluster = _client(workers, None)
    try:
        client.run(_warm, str(warm))
        t1 = time.perf_counter()
        _run_jobs(client, jobs, opts, table, FleetResult(), _Progress(len(jobs), quiet=True), as_completed)
        t2 = time.perf_counter()
        trips = []
        for i in range(20):
            t = time.perf_counter()
            client.submit(_noop, i, pure=False).result()
            trips.append(time.perf_counter() - t)
    finally:
        client.close()
        cluster.close()
    _check(list(table.rows.values()), frames)
    return t1 - t0, t2 - t1, statistics.median(trips)


def _rounds(paths: list[Path], work: Path, repeat: int, frames: int) -> dict[str, list[float]]:
    """Seconds of each way over all recordings, the ways interleaved ``repeat`` times (the shared machine's load
    comes and goes: each way meets it alike)."""
    got: dict[str, list[float]] = {k: [] for k in ("replay", "task", "start1", "one", "trip", "start2", "two")}
    warm = work / "warm.bag"
    write_sequence_bag(warm, Scenario(frames=2, seed=5))
    _warm(str(warm))
    for k in range(repeat):
        t0 = time.perf_counter()
        for i, p in enumerate(paths):
            replay(p, work / f"replayed{i}.bag", show_progress=False)
        got["replay"].append(time.perf_counter() - t0)
        for i in range(len(paths)):
            (work / f"replayed{i}.bag").unlink()
        t0 = time.perf_counter()
        rows = [measure_recording(str(p), FleetOptions(), [("default", {})])[0] for p in paths]
        got["task"].append(time.perf_counter() - t0)
        _check(rows, frames)
        for w, key in ((1, "one"), (2, "two")):
            start, run, trip = _fleet(paths, work / f"out{w}_{k}", w, warm, frames)
            got[f"start{w}"].append(start)
            got[key].append(run)
            got["trip"].append(trip)
    return got


def bench(recordings: int = 4, frames: int = 100, repeat: int = 2) -> str:
    work = Path(tempfile.mkdtemp(prefix="kp_fleet_bench_"))
    load0 = os.getloadavg()[0]
    try:
        paths = _bags(work, recordings, frames)
        got = _rounds(paths, work, repeat, frames)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    best = {k: min(v) for k, v in got.items()}
    n, f = recordings, recordings * frames
    lines = [
        f"{n} recordings of {frames} frames (512x424 16UC1, copies of one synthetic bag); core threads 1 per task "
        f"(replay: the core's default); best of {repeat} interleaved rounds; load average {load0:.1f} at the start, "
        f"{os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} cores",
        "",
        "| run | recordings/s | frames/s | s per recording |",
        "|---|---|---|---|",
    ]
    for name, key in (
        ("plain `replay`, one after the other (writes each output bag)", "replay"),
        ("the fleet's task in this process, no Dask (no output bag)", "task"),
        (f"fleet, 1 worker (LocalCluster start and warm-up {best['start1']:.1f} s not counted)", "one"),
        (f"fleet, 2 workers (LocalCluster start and warm-up {best['start2']:.1f} s not counted)", "two"),
    ):
        s = best[key]
        lines.append(f"| {name} | {n / s:.2f} | {f / s:.1f} | {s / n:.2f} |")
    per_frame = best["task"] / f
    over = (best["one"] - best["task"]) / n
    lines += [
        "",
        f"2 workers / 1 worker: {best['one'] / best['two']:.2f}x (goal >= 1.8x)",
        f"engine overhead per recording, 1 worker against the task in this process: {over * 1000:+.0f} ms; a Dask "
        f"round trip of an empty task: {best['trip'] * 1000:.1f} ms; against a 1,000-frame recording at "
        f"{per_frame * 1000:.1f} ms a frame: {100 * over / (1000 * per_frame):+.1f} % and "
        f"{100 * best['trip'] / (1000 * per_frame):.2f} % (goal <= 5 %)",
        f"fleet 1 worker against plain replay, per recording: {100 * (best['one'] / best['replay'] - 1):+.1f} %",
    ]
    return "\n".join(lines)
