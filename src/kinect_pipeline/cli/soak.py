"""kinect-pipeline soak: the long run through a real roscore."""

from __future__ import annotations

import argparse

from ._common import number
from .bench_ros import add_rate_and_threads

NAME = "soak"
HELP = "long run through a real roscore: drops, latency, memory at start and end"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--minutes", type=number(hi=100_000.0, above=0.0), default=10.0, help="how long [min]")
    add_rate_and_threads(p)
    p.add_argument("--subject", choices=["node", "nodelet"], default="nodelet", help="what runs the pipeline")


def run(args: argparse.Namespace) -> int:
    from ..tools.bench_ros import run, soak_report

    frames = int(args.minutes * 60 * args.rate)
    results = run(frames=frames, rate=args.rate, threads=args.threads, only=args.subject)
    print(f"soak: {args.minutes:g} min at {args.rate:g} Hz, 512x424 16UC1, num_threads {args.threads}:")
    print(soak_report(results))
    return 0 if all(r.sent == r.received for r in results) else 1
