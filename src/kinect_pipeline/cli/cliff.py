"""kinect-pipeline cliff: negative obstacles per pitch condition."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from ..outputs import output_folder
from ._common import add_quiet, count

NAME = "cliff"
HELP = "negative obstacles (stair down, hole, flat floor) per pitch condition"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=count(), default=20, help="frames per pitch condition [frames]")
    p.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1", help="depth encoding")
    p.add_argument("--pictures", metavar="DIR", help="also write the stair and hole pictures into DIR (default: none)")
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..evaluation.cliff import EDGE, STEP, evaluate, picture, table

    # The pictures' folder first: one that cannot be made fails before the table's work, not after it.
    with output_folder(Path(args.pictures)) if args.pictures else contextlib.nullcontext() as out:
        rows = evaluate(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
        print(
            f"negative obstacles: a stair down {EDGE:g} m ahead ({STEP * 100:g} cm step) and a flat floor, Kinect v2 "
            f"at 1.1 m tilted 0.3 rad, {args.frames} frames per condition, {args.encoding} with noise, dropouts and "
            "flying pixels; cliff_in_scan on:"
        )
        print(table(rows))
        if out is not None:
            print("pictures: " + "  ".join(str(p) for p in picture(out, args.encoding)))
    return 0
