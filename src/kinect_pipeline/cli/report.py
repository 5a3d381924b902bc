"""kinect-pipeline report: pictures and an index.html for a bag."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..outputs import Named
from ._common import ToolError, add_param, add_quiet, check, parse_params
from .replay import add_bag_topics

NAME = "report"
HELP = "pictures and an index.html for a bag (frame, scan, LiDAR and ground truth where the bag has them, timing)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="bag with a depth image, its camera_info and tf: ROS 1 .bag, rosbag2 folder, .mcap")
    p.add_argument("-o", "--out", required=True, help="output folder, made if missing")
    add_bag_topics(p)
    add_param(p)
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..replay import ReplayError, ReplayOptions
    from ..report import FILES, write_report

    inp, out = Path(args.input), Path(args.out)
    check([inp], [Named(out / f, "-o") for f in FILES], [Named(out, "-o")])
    opts = ReplayOptions(
        depth_topic=args.depth_topic,
        info_topic=args.info_topic,
        base_frame=args.base_frame,
        base_frame_height=args.base_frame_height,
        config=parse_params(args.param),
    )
    try:
        summary = write_report(inp, out, opts, show_progress=not args.quiet)
    except ReplayError as exc:
        raise ToolError(str(exc)) from exc
    print(json.dumps({k: v for k, v in summary.items() if k != "pictures"}, indent=1))
    print(f"report: {out / 'index.html'}")
    return 0
