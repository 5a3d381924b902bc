"""kinect-pipeline quality: the quality table on the generator's ground truth."""

from __future__ import annotations

import argparse

from ._common import (
    ToolError,
    add_intrinsics,
    add_param,
    add_quiet,
    add_sensor_model,
    count,
    empty_means_none,
    only_with,
)

NAME = "quality"
HELP = "quality table per pitch condition and mode vs baselines (ground truth); --bag: a bag's replay vs its truth"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from .replay import BAG_INTRINSICS, add_bag_topics

    p.add_argument(
        "--bag",
        help="instead: replay this bag (ROS 1, rosbag2, .mcap; raw or compressedDepth) and score it against the "
        "ground truth it carries (/ground_truth/scan, /ground_truth/labels, as synth writes) (default: none)",
    )
    add_bag_topics(p)
    add_intrinsics(p, BAG_INTRINSICS)
    add_sensor_model(p, "--bag: its threshold curve, range and cliff pixels (and nominal intrinsics)")
    add_param(p, "--bag: a core Config field of the replay")
    p.add_argument("--frames", type=count(), default=20, help="frames per pitch condition [frames]")
    p.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1", help="depth encoding")
    real = p.add_argument(
        "--real-frames",
        default=_default_real_frames(),
        help="folder of real RealSense frames (depth/*.png, 16-bit mm, the shared realsense_lowcam camera) for the "
        "real-floors table; empty: none",
    )
    empty_means_none(real)
    add_quiet(p)
    # the rendered tables compare fixed configurations; the bag's replay is one recording
    bag_topics = ("--depth-topic", "--info-topic", "--base-frame", "--base-frame-height")
    only_with(p, "--bag", "--param", "--intrinsics", "--sensor-model", *bag_topics)
    only_with(p, "--bag", "--frames", "--encoding", "--real-frames", absent=True)


def _default_real_frames() -> str:
    """../shared/data/real/realsense_lowcam beside the repository, where it exists."""
    from pathlib import Path

    p = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real" / "realsense_lowcam"
    return str(p.resolve()) if p.is_dir() else ""


def run(args: argparse.Namespace) -> int:
    from ..evaluation.quality import evaluate, table

    if args.bag:
        return _run_bag(args)
    _check_real_frames(args.real_frames)
    rows = evaluate(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"lab scene, Kinect v2 at 1.1 m tilted 15 deg, {args.frames} frames per condition, {args.encoding}, "
        "Kinect noise + dropouts + flying pixels + 8 m range; means over frames:"
    )
    print(table(rows))
    from ..evaluation.quality import evaluate_pose_errors, pose_table

    pose_rows = evaluate_pose_errors(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"\nthe same camera on a Segway rocking +-4 deg (25 deg/s), {args.frames} frames, told a pose off by: "
        "(the floor fit's learned correction, time constant 2 s, carries over between frames)"
    )
    print(pose_table(pose_rows))
    from ..evaluation.real_floors import table as real_floors_table

    print(
        "\nreal floors: the worst frame's floor removed (< 4 m) / phantom beams / false cliff beams, in %; a "
        "RealSense robot (0.63 m, 20 deg down, 10 deg roll, rocking +-1 deg) rendered with stereo artefacts and the "
        "realsense_d4xx preset, people around a pitching Kinect v2, and the shared real RealSense frames:"
    )
    print(real_floors_table(frames=args.frames, show_progress=not args.quiet, real_folder=args.real_frames))
    return 0


def _check_real_frames(folder: str) -> None:
    """A folder named for the real-floors table must hold frames (before, one without was left out silently)."""
    from pathlib import Path

    if folder and not sorted(Path(folder).glob("depth/*.png")):
        raise ToolError(f"--real-frames {folder}: no depth/*.png in it: expected the realsense_lowcam folder, or ''")


def _run_bag(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..evaluation.quality import bag_quality
    from ..tools.replay import ReplayError
    from .replay import bag_options

    opts = bag_options(args)
    try:
        q = bag_quality(Path(args.bag), opts, show_progress=not args.quiet)
    except ReplayError as exc:
        raise ToolError(str(exc)) from exc
    print(f"{args.bag}: {q['frames']} frames against its ground truth (fractions of all beams):")
    print("| phantom beams | phantom beams (5 cm) | missed beams | label agreement (min) |")
    print("|---|---|---|---|")
    print(
        f"| {100 * q['phantom_beams']:.2f} % | {100 * q['phantom_beams_5cm']:.2f} % | {100 * q['missed_beams']:.2f} % "
        f"| {100 * q['label_agreement_min']:.2f} % |"
    )
    return 0
