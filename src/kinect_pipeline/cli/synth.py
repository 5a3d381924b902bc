"""kinect-pipeline synth: a bag of a synthetic Segway sequence."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from ._common import add_quiet, check, count, named, number

NAME = "synth"
HELP = "write a bag of a synthetic Segway sequence (depth, camera_info, tf, LiDAR, ground truth)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("output", help="bag to write (refused if it exists): a ROS 1 .bag, a rosbag2 folder, a .mcap file")
    p.add_argument(
        "--format",
        choices=["ros1", "sqlite3", "mcap"],
        help="ROS 1, or rosbag2 with sqlite3 or mcap storage (default: what the name says; ROS 1 unless .mcap/.db3)",
    )
    p.add_argument("--frames", type=count(hi=100_000), default=30, help="depth frames [frames]")
    p.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1", help="depth encoding")
    p.add_argument("--seed", type=count(0, 2**64 - 1), default=1, help="seed of the noise [-]")
    add_quiet(p)
    for what, unit in (("height", "m"), ("pitch", "deg"), ("roll", "deg")):
        p.add_argument(
            f"--tf-error-{what}",
            type=number(-10.0, 10.0) if unit == "m" else number(-90.0, 90.0),
            default=0.0,
            help=f"add this to the mounting {what} the bag's tf states (a wrong URDF) [{unit}]",
        )


def run(args: argparse.Namespace) -> int:
    from ..simulation.sequence_bag import Scenario, write_sequence_bag

    check([], [named("", args.output)])  # a positional: the message says "output PATH" itself
    tf_error = (args.tf_error_height, math.radians(args.tf_error_pitch), math.radians(args.tf_error_roll))
    scenario = Scenario(frames=args.frames, encoding=args.encoding, seed=args.seed, tf_error=tf_error)
    summary = write_sequence_bag(Path(args.output), scenario, fmt=args.format, show_progress=not args.quiet)
    print(json.dumps(summary))
    return 0
