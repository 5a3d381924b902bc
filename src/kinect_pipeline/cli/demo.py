"""kinect-pipeline demo: the bundled default job."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..outputs import check_rewrite, output_folder
from ._common import count

NAME = "demo"
HELP = "synthetic Segway sequence through the pipeline -> PNGs, quality.json, a replayed bag and its report"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out/demo", help="output folder, made if missing")
    p.add_argument("--frames", type=count(hi=100_000), default=40, help="frames to render [frames]")
    p.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="8UC1", help="depth encoding")
    p.add_argument("--seed", type=count(0, 2**64 - 1), default=1, help="seed of the noise [-]")


DEMO_FILES = ("quality.json", "frame.png", "scan.png", "demo.bag", "demo_replayed.bag", "report")
MARK = ".kinect-pipeline-demo"  #: in a folder the demo wrote: its files there are its own to write again


def run(args: argparse.Namespace) -> int:
    from ..evaluation.report import write_report
    from ..simulation.sequence_bag import Scenario, write_sequence_bag
    from ..tools.demo import run_demo
    from ..tools.replay import format_report, partial_path, replay

    check_rewrite(Path(args.out), DEMO_FILES, (MARK, "quality.json"), "the demo")  # quality.json: before the mark
    with output_folder(Path(args.out), mark=MARK) as out:  # the mark first: a run stopped halfway runs again
        summary = run_demo(out, frames=args.frames, encoding=args.encoding, seed=args.seed)
        print(json.dumps(summary, indent=1))
        # The bag tooling on the same kind of sequence: a small seeded bag, replayed offline, and its report.
        bag, replayed = out / "demo.bag", out / "demo_replayed.bag"
        for p in (bag, replayed, partial_path(replayed)):  # the demo's own outputs of an earlier run
            p.unlink(missing_ok=True)
        write_sequence_bag(bag, Scenario(frames=args.frames, encoding=args.encoding, seed=args.seed))
        print(format_report(replay(bag, replayed, show_progress=True)))
        report = write_report(replayed, out / "report", show_progress=True)
    print(json.dumps({k: v for k, v in report.items() if k != "pictures"}, indent=1))
    print(f"pictures: {out / 'frame.png'}  {out / 'scan.png'}  report: {out / 'report' / 'index.html'}")
    return 0
