"""kinect-pipeline report: pictures and an index.html for a bag or for depth frames."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..outputs import Named
from ._common import ToolError, add_frames, add_param, add_quiet, check, frame_files, frames_camera, warn
from .replay import add_bag_topics, bag_options

NAME = "report"
HELP = (
    "pictures and an index.html for a bag or depth frames (frame, scan, LiDAR and ground truth where the bag has "
    "them, confidence, timing)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "input",
        nargs="+",
        help="a bag with a depth image, its camera_info and tf (ROS 1 .bag, rosbag2 folder, .mcap), or depth frames "
        "and folders of them (as for calibrate; at --param sensor_height/sensor_pitch, else the pose calibrated "
        "from their floor)",
    )
    p.add_argument("-o", "--out", required=True, help="output folder, made if missing")
    add_bag_topics(p)
    add_frames(p, "", "its threshold curve, range and cliff pixels (and typical intrinsics for frames)", False)
    add_param(p)
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..evaluation.report import FILES, write_report
    from ..tools.calibrate import CalibrationError, is_frames, load_depth
    from ..tools.replay import ReplayError

    items, out = [Path(p) for p in args.input], Path(args.out)
    check(items, [Named(out / f, "-o") for f in FILES], [Named(out, "-o")])
    _refuse_unused(args, is_frames(items))
    opts = bag_options(args)
    cam = None
    if is_frames(items):
        files = frame_files(args.input, NAME)
        h, w = load_depth(files[0], args.depth_scale).shape
        cam = frames_camera(args, w, h)
    try:
        summary = write_report(items, out, opts, show_progress=not args.quiet, camera=cam, depth_scale=args.depth_scale)
    except (ReplayError, CalibrationError) as exc:
        raise ToolError(str(exc)) from exc
    print(json.dumps({k: v for k, v in summary.items() if k != "pictures"}, indent=1))
    print(f"report: {out / 'index.html'}")
    for w in summary["warnings"]:
        warn(NAME, w)
    return 0


BAG_ONLY = ("--depth-topic", "--info-topic", "--base-frame", "--base-frame-height")
FRAMES_ONLY = ("--depth-scale",)


def _refuse_unused(args: argparse.Namespace, frames: bool) -> None:
    """The input says the mode (a bag or depth frames): an option of the other mode, given, would be ignored (the
    options of a mode set by another option are only_with's)."""
    given: set[str] = getattr(args, "given", set())
    ignored = [o for o in (BAG_ONLY if frames else FRAMES_ONLY) if o[2:].replace("-", "_") in given]  # argparse's dest
    if ignored:
        raise ToolError(
            f"{', '.join(ignored)}: for {'a bag' if frames else 'depth frames'} only, and the input is "
            f"{'depth frames' if frames else 'a bag'} (it would be ignored)"
        )
