"""kinect-pipeline replay: the pipeline over a bag at the pose its tf gives, outputs into a new bag."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ._common import (
    ToolError,
    add_intrinsics,
    add_param,
    add_quiet,
    add_sensor_model,
    check,
    count,
    intrinsics_of,
    named,
    number,
    parse_params,
    warn,
    with_sensor_model,
)

NAME = "replay"
#: What --intrinsics does for a bag.
BAG_INTRINSICS = (
    " (default: the bag's camera_info; where it has none, --sensor-model's nominal camera with a warning; given, "
    "they win over the bag's camera_info)"
)
HELP = "run the pipeline over a bag at the pose its tf gives; write the scans and the cleaned image to a new bag"


def add_bag_topics(p: argparse.ArgumentParser) -> None:
    """The options that say which topics and frames of a bag to use (replay, report, calibrate --bag)."""
    p.add_argument(
        "--depth-topic",
        help="depth Image (or its compressedDepth) topic (default: the only one with 'depth' in its name)",
    )
    p.add_argument("--info-topic", help="CameraInfo topic (default: camera_info beside the depth topic)")
    p.add_argument("--base-frame", default="base_footprint", help="gravity-aligned tf frame on the floor")
    p.add_argument(
        "--base-frame-height", type=number(-10.0, 10.0), default=0.0, help="its origin's height above the floor [m]"
    )
    p.add_argument(
        "--rectify",
        choices=["auto", "always", "never"],
        default="auto",
        help="rectify the depth images by their camera_info's distortion: auto (unless the depth topic's name holds "
        "'rect'), always or never (default: auto, as the node)",
    )


def add_pose_fallback(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--pose-fallback",
        choices=["static", "skip"],
        default="static",
        help="frames without tf: the static pose of the parameters, or skip them",
    )


def bag_options(args: argparse.Namespace, **more: object) -> Any:
    """ReplayOptions of the options add_bag_topics, --param and --sensor-model gave."""
    from ..tools.replay import ReplayOptions

    config = with_sensor_model(parse_params(args.param), getattr(args, "sensor_model", None))
    intr = intrinsics_of(args)
    return ReplayOptions(
        depth_topic=args.depth_topic,
        info_topic=args.info_topic,
        intrinsics=None if intr is None else intr.as_list(),
        lens=None if intr is None else intr.lens(),
        base_frame=args.base_frame,
        base_frame_height=args.base_frame_height,
        rectify=args.rectify,
        config=config,
        **more,  # type: ignore[arg-type]
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", help="bag with a depth image, its camera_info and tf: ROS 1 .bag, rosbag2 folder, .mcap")
    p.add_argument("-o", "--output", required=True, help="new bag: the input's messages plus the outputs")
    p.add_argument(
        "--format",
        choices=["ros1", "sqlite3", "mcap"],
        help="of the output: ROS 1, or rosbag2 with sqlite3 or mcap storage (default: the input's; messages are "
        "converted between ROS 1 and ROS 2 definitions)",
    )
    add_bag_topics(p)
    add_pose_fallback(p)
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip damaged messages (and read a truncated or unindexed ROS 1 bag) instead of stopping; says how many "
        "and where (default: stop at the first)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue a replay into OUTPUT that stopped (killed: its .OUTPUT.partial file; or --max-frames): "
        "takes the frames it wrote, computes the rest; the same result as one uninterrupted run (default: refuse an "
        "existing OUTPUT)",
    )
    p.add_argument(
        "--max-frames",
        type=count(),
        help="stop after this many depth frames: a complete, shorter bag [frames] (default: all)",
    )
    add_intrinsics(p, BAG_INTRINSICS)
    add_sensor_model(
        p, "its threshold curve, range and cliff pixels (and nominal intrinsics where the bag has no CameraInfo)"
    )
    add_param(p)
    add_quiet(p)


def run(args: argparse.Namespace) -> int:
    from ..tools.replay import ReplayError, format_report, partial_path, replay

    opts = bag_options(args, pose_fallback=args.pose_fallback, skip_bad=args.skip_bad, format=args.format)
    inp, out = Path(args.input), Path(args.output)
    check([inp], [named("-o", args.output)])
    try:
        report = replay(inp, out, opts, show_progress=not args.quiet, resume=args.resume, max_frames=args.max_frames)
    except ReplayError as exc:
        raise ToolError(str(exc)) from exc
    except KeyboardInterrupt:
        if partial_path(out).exists():
            print(
                f"kinect-pipeline replay: interrupted; what was written is in {partial_path(out)}: run the same "
                "command with --resume to continue",
                file=sys.stderr,
            )
        return 130
    print(format_report(report))
    for w in report.warnings:
        warn(NAME, w)
    return 0
