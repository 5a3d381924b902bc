"""kinect-pipeline curve: the threshold curve t(d) from floor frames or a noise model."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from ._common import ToolError, add_frames, check, count, frame_files, frames_camera, named, number, only_with

if TYPE_CHECKING:
    from ..tools.curve import CurveFit

NAME = "curve"
HELP = "threshold curve t(d) from floor frames (or a noise model) -> YAML, plot; --compare: against constant margins"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_frames(
        p, "frames of a flat floor (as for calibrate)", "typical intrinsics for frames, its curve as the current"
    )
    p.add_argument(
        "--rate",
        type=number(hi=0.5, above=0.0),
        default=1e-4,
        help="false-obstacle rate per floor pixel [-] (default: 1e-4: a beam sees ~100 floor pixels, so this keeps "
        "phantom beams under the 0.2 %% goal)",
    )
    p.add_argument("--margin", type=number(lo=0.0), default=0.01, help="added to k sigma [m]")
    p.add_argument(
        "--from-model",
        nargs=2,
        type=number(above=0.0),
        metavar=("SIGMA0", "K"),
        help="no data: sigma(d) = SIGMA0 + K (d - 0.4)^2 [m, m/m^2] (Kinect v2: 0.0015 0.0019) (default: none)",
    )
    p.add_argument("-o", "--output", help="write the curve as YAML for rosparam / dynamic_reconfigure (default: none)")
    p.add_argument("--plot", help="write a PNG of the residuals and the curves (default: none)")
    p.add_argument("--set-node", help="set it live on this node through dynamic_reconfigure (default: none)")
    p.add_argument(
        "--compare",
        action="store_true",
        help="score it on generated noisy frames against the constant margins with the same false-obstacle and "
        "phantom-beam rates (fits on generated floor frames when no frames are given) (default: off)",
    )
    p.add_argument(
        "--compare-frames", type=count(hi=10_000), default=12, help="generated frames for --compare [frames]"
    )
    p.add_argument(
        "--compare-plot", help="with --compare: write a PNG of the curves and what they remove (default: none)"
    )
    only_with(p, "--compare", "--compare-frames", "--compare-plot")


def _fit(args: argparse.Namespace) -> CurveFit:
    from ..tools.calibrate import load_depth
    from ..tools.curve import curve_from_model, fit_curve, generated_floor_frames

    if args.from_model:
        return curve_from_model(args.from_model[0], args.from_model[1], args.rate, args.margin)
    if args.compare and not args.files:
        from .. import kinect_v2_camera

        print("fitted on 3 generated Kinect v2 floor frames (no frames given):")
        return fit_curve(generated_floor_frames(3), kinect_v2_camera(), args.rate, args.margin)
    if not args.files or not (args.intrinsics or args.sensor_model):
        raise ToolError(
            "give floor frames and --intrinsics (or --sensor-model), or --from-model SIGMA0 K, or --compare"
        )
    frames = [(str(f), load_depth(f, args.depth_scale)) for f in frame_files(args.files, NAME)]
    h, w = frames[0][1].shape
    return fit_curve(frames, frames_camera(args, w, h), args.rate, args.margin)


def run(args: argparse.Namespace) -> int:
    from .. import _core
    from ..tools.calibrate import CalibrationError
    from ..tools.curve import describe, plot, set_live, write_yaml

    if args.from_model and args.files:
        raise ToolError(f"--from-model fits no frames: give it or frames, not both (got {' '.join(args.files)})")
    outputs = [named("-o", args.output), named("--plot", args.plot), named("--compare-plot", args.compare_plot)]
    check([*map(Path, args.files), *frame_files(args.files)], outputs)
    try:
        fit = _fit(args)
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    print(describe(fit))
    if args.output:
        write_yaml(fit, Path(args.output))
        print(f"YAML: {args.output}")
    if args.plot:
        current = _core.Config(**({"sensor_model": args.sensor_model} if args.sensor_model else {}))
        plot(fit, current.threshold_curve, Path(args.plot))
        print(f"plot: {args.plot}")
    if args.compare:
        _compare(args, fit)
    if args.set_node:
        print(f"set on {args.set_node}: {set_live(args.set_node, fit)['threshold_curve']}")
    return 0


def _compare(args: argparse.Namespace, fit: CurveFit) -> None:
    from ..tools.curve import compare_with_constant, comparison_table, plot_comparison

    cmp = compare_with_constant(fit, frames=args.compare_frames)
    print(
        f"on {args.compare_frames} generated noisy frames (lab scene, Kinect v2 at 1.1 m tilted 15 deg, Segway "
        "pitching, 16UC1, noise + dropouts + flying pixels); phantom beam: shorter than the nearest true obstacle "
        "by > 5 cm + 4 sigma; goal <= 0.2 %:"
    )
    print(comparison_table(cmp.rows()))
    if args.compare_plot:
        plot_comparison(cmp.rows(), Path(args.compare_plot))
        print(f"plot: {args.compare_plot}")
