"""kinect-pipeline bench-ros: image -> scan latency through the node, the nodelet and a bare relay."""

from __future__ import annotations

import argparse

from ._common import count, number

NAME = "bench-ros"
HELP = "image->scan latency and CPU: node, nodelet, bare image_transport relay (own roscore)"


def add_rate_and_threads(p: argparse.ArgumentParser) -> None:
    """--rate and --threads of the runs through a roscore (bench-ros, soak)."""
    p.add_argument("--rate", type=number(hi=1000.0, above=0.0), default=30.0, help="frames per second [Hz]")
    p.add_argument(
        "--threads",
        type=count(0, 1024),
        default=1,
        help="the pipeline's num_threads [threads] (default: 1, as the node's; 0: OpenMP's default)",
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=count(), default=300, help="frames per subject [frames]")
    add_rate_and_threads(p)
    p.add_argument(
        "--sequential",
        action="store_true",
        help="run the subjects one after the other (default: their frames interleaved)",
    )


def run(args: argparse.Namespace) -> int:
    from ..tools.bench_ros import report, run

    results = run(frames=args.frames, rate=args.rate, threads=args.threads, sequential=args.sequential)
    print(
        f"image -> output latency at {args.rate:g} Hz, 512x424 16UC1, {args.frames} frames each, "
        f"num_threads {args.threads}, same run, "
        + ("one subject after the other:" if args.sequential else "interleaved:")
    )
    print(report(results))
    return 0
