"""kinect-pipeline calibrate: the sensor's pose from frames of a flat floor, or a bag's tf against the floor."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ._common import (
    ToolError,
    add_frames,
    check,
    frame_files,
    frames_camera,
    intrinsics_of,
    named,
    number,
    only_with,
    warn,
)
from .replay import add_bag_topics

NAME = "calibrate"
HELP = "sensor height, pitch and roll from frames of a flat floor; --bag: tf's pose vs the floor per frame"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_frames(p, "frames of a flat floor, the robot standing still", "its typical intrinsics for frames")
    p.add_argument(
        "--bag",
        help="instead of frames, a bag of a moving base: per depth frame, how far the pose tf gives (URDF + IMU) is "
        "from the floor seen in it (median / p95 / max; intrinsics from its camera_info, or --intrinsics) (default: "
        "none)",
    )
    add_bag_topics(p)
    p.add_argument(
        "--plot",
        help="write a PNG: with frames, the first one's labels under the calibrated pose; with --bag, tf vs floor per "
        "frame (default: none)",
    )
    p.add_argument("--max-depth", type=number(above=0.0), default=12.0, help="depth of 8-bit value 255 [m]")
    p.add_argument(
        "--max-tilt",
        type=number(hi=90.0, above=0.0),
        default=40.0,
        help="largest tilt of the floor from the image's up considered [deg] (where that finds no plausible floor, "
        "the frame is searched a quarter turn either way too: any mounting roll, |pitch| up to this): a wall seen by "
        "a level camera looks like a floor seen by a steeply tilted one",
    )
    p.add_argument("--json", action="store_true", help="print JSON: height [m], pitch, roll [rad], ... (default: text)")
    p.add_argument("--optical-frame", default="kinect2_depth_optical_frame", help="child frame of the static tf line")
    # frames give a static tf line of base frame -> optical frame; a bag's frames are read as REP 118 says
    only_with(p, "--bag", "--depth-topic", "--info-topic", "--base-frame-height")
    only_with(p, "--bag", "--depth-scale", "--optical-frame", absent=True)


def run(args: argparse.Namespace) -> int:
    if args.bag:
        return _run_bag(args)
    if not args.files or not (args.intrinsics or args.sensor_model):
        raise ToolError(
            "give depth frames and --intrinsics FX FY CX CY (or --sensor-model NAME), or --bag BAG to check its tf "
            "against the floor"
        )
    from ..tools.calibrate import CalibrationError, calibrate, load_depth

    files = frame_files(args.files, NAME)
    check([*map(Path, args.files), *files], [named("--plot", args.plot)])
    try:
        frames = [(str(f), load_depth(f, args.depth_scale, args.max_depth)) for f in files]
        h, w = frames[0][1].shape
        cam = frames_camera(args, w, h)
        result = calibrate(frames, cam, max_tilt=math.radians(args.max_tilt), sensor_model=args.sensor_model or "")
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    d = result.as_dict(args.base_frame, args.optical_frame)
    if args.plot and result.found:
        from ..tools.calibrate import plot_calibration

        plot_calibration(frames[0][1], cam, result, Path(args.plot), Path(frames[0][0]).name)
    if args.json:
        print(json.dumps(d, indent=1))
    elif result.found:
        print(
            f"height {result.height:.4f} m +- {result.height_std:.4f}, pitch {math.degrees(result.pitch):+.3f} deg "
            f"+- {math.degrees(result.pitch_std):.3f}, roll {math.degrees(result.roll):+.3f} deg "
            f"+- {math.degrees(result.roll_std):.3f}; floor {100 * result.floor_fraction:.1f} % of the pixels, "
            f"{len(frames)} frame(s)"
        )
        print(f"launch args: {d['launch_args']}")
        print("YAML:\n" + "\n".join(f"{k}: {v}" for k, v in d["yaml"].items()))
        print(f"static tf: {d['static_transform']}")
        if args.plot:
            print(f"plot: {args.plot}")
    for warning in result.warnings:
        print(f"kinect-pipeline calibrate: warning: {warning}", file=sys.stderr)
    if not result.found:
        print(f"kinect-pipeline calibrate: {result.message}", file=sys.stderr)
        return 1
    return 0


def _run_bag(args: argparse.Namespace) -> int:
    """calibrate --bag: the tf-provided pose against the floor seen in each frame."""
    from ..tools.calibrate import CalibrationError, check_tf, describe_tf_check, plot_tf_check

    if args.files:
        raise ToolError(f"--bag checks a bag: give no frame files as well (got {' '.join(args.files)})")
    check([Path(args.bag)], [named("--plot", args.plot)])
    try:
        result = check_tf(
            Path(args.bag),
            depth_topic=args.depth_topic,
            info_topic=args.info_topic,
            base_frame=args.base_frame,
            base_frame_height=args.base_frame_height,
            max_depth=args.max_depth,
            max_tilt=math.radians(args.max_tilt),
            show_progress=not args.json,
            intrinsics=intrinsics_of(args),
            sensor_model=args.sensor_model,
            rectify=args.rectify,
        )
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    for w in result.warnings:
        warn(NAME, w)
    if result.summary()["frames_with_floor"] == 0:
        raise ToolError(f"no floor found in any of the {len(result.frames)} frames of {args.bag}")
    if args.plot:
        plot_tf_check(result, Path(args.plot))
    if args.json:
        print(json.dumps(result.as_dict(), indent=1))
    else:
        print(describe_tf_check(result))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0
