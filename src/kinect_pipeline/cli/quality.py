"""kinect-pipeline quality: the quality table on the generator's ground truth."""

from __future__ import annotations

import argparse

from ._common import add_quiet

NAME = "quality"
HELP = "quality table per pitch condition and mode vs baselines (ground truth)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=int, default=20, help="frames per pitch condition [frames]")
    p.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1", help="depth encoding")
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..quality import evaluate, table

    rows = evaluate(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"lab scene, Kinect v2 at 1.1 m tilted 15 deg, {args.frames} frames per condition, {args.encoding}, "
        "Kinect noise + dropouts + flying pixels + 8 m range; means over frames:"
    )
    print(table(rows))
    from ..quality import evaluate_pose_errors, pose_table

    pose_rows = evaluate_pose_errors(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"\nthe same camera on a Segway rocking +-4 deg (25 deg/s), {args.frames} frames, told a pose off by: "
        "(the floor fit's learned correction, time constant 2 s, carries over between frames)"
    )
    print(pose_table(pose_rows))
    return 0
