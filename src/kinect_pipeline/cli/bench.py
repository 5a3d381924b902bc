"""kinect-pipeline bench: the C++ core benchmark."""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path

from ._common import ToolError, count

NAME = "bench"
HELP = "time per stage and per frame vs memcpy, 1 and 2 threads (C++ benchmark)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=count(), default=300, help="frames per measurement [frames]")
    p.add_argument("--kernel", type=int, default=3, help="opening kernel size [px]")
    p.add_argument("--projection", choices=["horizontal", "column"], default="horizontal", help="scan projection")
    p.add_argument("--threads", help="comma-separated thread counts, e.g. 1,2,4,8 [threads] (default: 1,2)")
    p.add_argument("--encodings", help="comma-separated subset of 8UC1,16UC1,32FC1 (default: all three)")
    p.add_argument("--surface-band", type=float, default=0.0, help="the pipeline's surface_band [-]")
    p.add_argument(
        "--roll",
        help="the mount's roll(s) the frames are rendered and processed at, comma-separated, measured side by side "
        "(e.g. 0,0.0087) [rad]: any roll but 0 or +-pi takes the per-pixel labels, as a base's roll from an IMU "
        "does; a list that starts with a negative roll takes '=' (--roll=-0.01,0) (default: 0)",
    )
    p.add_argument(
        "--no-refine-floor",
        action="store_true",
        help="the frames without the floor refinement (refine_floor false), to see what it costs (default: on)",
    )
    p.add_argument(
        "--simd",
        help="SIMD target(s) of the kernels, comma-separated, measured side by side: native, avx512, avx2, sse4, "
        "scalar (aarch64: sve2_128 on CPUs of 128-bit SVE2 vectors, sve2, sve, neon); the table names the one "
        "that ran (default: the one KINECT_PIPELINE_SIMD names, else native)",
    )
    p.add_argument(
        "--reference",
        default="none",
        help="fast paths replaced by their plain reference, comma-separated sets measured side by side: none, all, "
        "or labels, binning, opening, portable joined by '+' (e.g. none,labels,labels+opening); what each fast path "
        "buys (default: none)",
    )
    p.add_argument("--markdown", action="store_true", help="print a Markdown table (default: plain text)")


def bench_binary() -> Path:
    from .. import _core

    # devel or install space: <prefix>/lib/python3/dist-packages/kinect_pipeline/_core.so
    #                      -> <prefix>/lib/kinect_pipeline/kinect_pipeline_bench
    here = Path(_core.__file__).resolve()
    cand = here.parents[3] / "kinect_pipeline" / "kinect_pipeline_bench"
    if cand.exists():
        return cand
    raise ToolError(f"kinect_pipeline_bench not found next to {here}: build the package first")


def run(args: argparse.Namespace) -> int:
    cmd = [str(bench_binary()), "--frames", str(args.frames), "--kernel", str(args.kernel)]
    cmd += ["--projection", args.projection]
    if args.threads is not None:  # an empty list too: the benchmark refuses it, naming the option
        cmd += ["--threads", args.threads]
    if args.encodings is not None:
        cmd += ["--encodings", args.encodings]
    if args.surface_band:
        cmd += ["--surface-band", str(args.surface_band)]
    if args.roll is not None:  # an empty list too: the benchmark refuses it, naming the option
        cmd += ["--roll", args.roll]
    if args.no_refine_floor:
        cmd.append("--no-refine-floor")
    if args.simd is not None:  # else the benchmark takes KINECT_PIPELINE_SIMD's target (and refuses a bad one)
        cmd += ["--simd", args.simd]
    cmd += ["--reference", args.reference]
    if args.markdown:
        cmd.append("--markdown")
    return subprocess.call(cmd)
