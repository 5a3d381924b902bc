"""kinect-pipeline evaluate: the quality of the default configuration on noisy rendered frames."""

from __future__ import annotations

import argparse
import math

from ._common import count, number

NAME = "evaluate"
HELP = "quality of the default config on noisy rendered frames (table)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=count(), default=8, help="frames per encoding [frames]")
    p.add_argument("--height", type=number(), default=1.1, help="sensor height [m]")
    p.add_argument("--pitch", type=number(), default=round(math.radians(15), 4), help="sensor tilt [rad]")
    p.add_argument("--encodings", nargs="+", default=["8UC1", "16UC1", "32FC1"], help="depth encodings")


def run(args: argparse.Namespace) -> int:
    from ..evaluation.quality import default_config_table

    print(default_config_table(args.frames, args.height, args.pitch, args.encodings))
    return 0
