"""``kinect-pipeline fleet --bench``: recordings and frames per second of the fleet with 1 and 2 workers, next to a
plain ``replay`` of the same bags and the fleet's task run in this process (no Dask), in one run. A benchmark that
prints, not a test that asserts."""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

from .bag import write_sequence_bag
from .fleet import FleetOptions, FleetResult, Table, _client, _Progress, _run_jobs, measure_recording, plan
from .replay import replay


def _bags(work: Path, recordings: int, frames: int) -> list[Path]:
    """One synthetic bag of ``frames`` frames and copies of it: the same work per recording."""
    first = work / "rec0.bag"
    write_sequence_bag(first, frames=frames, seed=5)
    paths = [first]
    for i in range(1, recordings):
        paths.append(work / f"rec{i}.bag")
        shutil.copyfile(first, paths[-1])
    return paths


def _fleet(paths: list[Path], out: Path, workers: int) -> tuple[float, float]:
    """(seconds to start the LocalCluster, seconds for the recordings) with ``workers`` workers."""
    from distributed import as_completed

    opts, configs = FleetOptions(), [("default", {})]
    out.mkdir()
    table = Table(out)
    jobs, _ = plan(paths, configs, opts, table, redo=True)
    t0 = time.perf_counter()
    client, cluster = _client(workers, None)
    try:
        t1 = time.perf_counter()
        _run_jobs(client, jobs, opts, table, FleetResult(), _Progress(len(jobs), quiet=True), as_completed)
        t2 = time.perf_counter()
    finally:
        client.close()
        cluster.close()
    bad = [r["status"] for r in table.rows.values() if r["status"] != "ok"]
    if bad:
        raise RuntimeError(f"the benchmark's recordings failed: {bad[:2]}")
    return t1 - t0, t2 - t1


def bench(recordings: int = 4, frames: int = 100) -> str:
    work = Path(tempfile.mkdtemp(prefix="kp_fleet_bench_"))
    try:
        paths = _bags(work, recordings, frames)
        t0 = time.perf_counter()
        for i, p in enumerate(paths):
            replay(p, work / f"replayed{i}.bag", show_progress=False)
        plain = time.perf_counter() - t0
        t0 = time.perf_counter()
        for p in paths:
            measure_recording(str(p), FleetOptions(), [("default", {})])
        task = time.perf_counter() - t0
        start1, one = _fleet(paths, work / "out1", 1)
        start2, two = _fleet(paths, work / "out2", 2)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    n, f = recordings, recordings * frames
    lines = [
        f"{n} recordings of {frames} frames (512x424 16UC1, copies of one synthetic bag); core threads 1 per task",
        "",
        "| run | recordings/s | frames/s | s per recording |",
        "|---|---|---|---|",
    ]
    for name, s in (
        ("plain `replay`, one after the other (writes each output bag)", plain),
        ("the fleet's task in this process, no Dask (no output bag)", task),
        (f"fleet, 1 worker (LocalCluster start {start1:.1f} s not counted)", one),
        (f"fleet, 2 workers (LocalCluster start {start2:.1f} s not counted)", two),
    ):
        lines.append(f"| {name} | {n / s:.2f} | {f / s:.1f} | {s / n:.2f} |")
    over = one / n - task / n
    lines += [
        "",
        f"2 workers / 1 worker: {one / two:.2f}x (goal >= 1.8x)",
        f"engine overhead per recording (1 worker against the task in-process): {over * 1000:+.0f} ms = "
        f"{100 * over / (task / n):+.1f} % of a {frames}-frame recording (goal <= 5 % of a 1,000-frame one)",
        f"fleet 1 worker against plain replay, per recording: {100 * (one - plain) / plain:+.1f} %",
    ]
    return "\n".join(lines)
