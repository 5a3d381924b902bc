"""``kinect-pipeline``: one console entry point, a subcommand per tool."""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path


class ToolError(Exception):
    """A known failure: printed as one line, exit status 1."""


def parse_params(items: list[str] | None) -> dict[str, object]:
    """``NAME=VALUE`` options as Config fields: JSON values (numbers, true/false, quoted strings) or plain text."""
    out: dict[str, object] = {}
    for item in items or []:
        key, _, value = item.partition("=")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def _bench_binary() -> Path:
    from . import _core

    # devel or install space: <prefix>/lib/python3/dist-packages/kinect_pipeline/_core.so
    #                      -> <prefix>/lib/kinect_pipeline/kinect_pipeline_bench
    here = Path(_core.__file__).resolve()
    for cand in (here.parents[3] / "kinect_pipeline" / "kinect_pipeline_bench",):
        if cand.exists():
            return cand
    raise ToolError(f"kinect_pipeline_bench not found next to {here}: build the package first")


def cmd_demo(args: argparse.Namespace) -> int:
    from .bag import write_sequence_bag
    from .demo import run_demo
    from .replay import format_report, partial_path, replay
    from .report import write_report

    out = Path(args.out)
    summary = run_demo(out, frames=args.frames, encoding=args.encoding, seed=args.seed)
    print(json.dumps(summary, indent=1))
    # The bag tooling on the same kind of sequence: a small seeded bag, replayed offline, and its report.
    bag, replayed = out / "demo.bag", out / "demo_replayed.bag"
    for p in (bag, replayed, partial_path(replayed)):  # the demo's own outputs of an earlier (interrupted) run
        p.unlink(missing_ok=True)
    write_sequence_bag(bag, frames=args.frames, encoding=args.encoding, seed=args.seed)
    print(format_report(replay(bag, replayed, show_progress=True)))
    report = write_report(replayed, out / "report", show_progress=True)
    print(json.dumps({k: v for k, v in report.items() if k != "pictures"}, indent=1))
    print(f"pictures: {out / 'frame.png'}  {out / 'scan.png'}  report: {out / 'report' / 'index.html'}")
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from .bag import write_sequence_bag

    summary = write_sequence_bag(
        Path(args.output),
        frames=args.frames,
        encoding=args.encoding,
        seed=args.seed,
        show_progress=not args.quiet,
        tf_error=(args.tf_error_height, math.radians(args.tf_error_pitch), math.radians(args.tf_error_roll)),
    )
    print(json.dumps(summary))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    cmd = [
        str(_bench_binary()),
        "--frames",
        str(args.frames),
        "--kernel",
        str(args.kernel),
        "--projection",
        args.projection,
    ]
    if args.threads:
        cmd += ["--threads", args.threads]
    if args.encodings:
        cmd += ["--encodings", args.encodings]
    if args.surface_band:
        cmd += ["--surface-band", str(args.surface_band)]
    if args.markdown:
        cmd.append("--markdown")
    return subprocess.call(cmd)


def cmd_replay(args: argparse.Namespace) -> int:
    from .replay import ReplayError, ReplayOptions, format_report, partial_path, replay

    config = parse_params(args.param)
    opts = ReplayOptions(
        depth_topic=args.depth_topic,
        info_topic=args.info_topic,
        base_frame=args.base_frame,
        base_frame_height=args.base_frame_height,
        pose_fallback=args.pose_fallback,
        skip_bad=args.skip_bad,
        config=config,
    )
    out = Path(args.output)
    try:
        report = replay(
            Path(args.input),
            out,
            opts,
            show_progress=not args.quiet,
            resume=args.resume,
            max_frames=args.max_frames,
        )
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
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    from . import _core
    from .calibrate import CalibrationError, calibrate, load_depth

    if args.bag:
        return _calibrate_bag(args)
    if not args.files or not args.intrinsics:
        raise ToolError(
            "give depth frames and --intrinsics FX FY CX CY, or --bag BAG to check its tf against the floor"
        )
    try:
        frames = [(f, load_depth(Path(f), args.depth_scale, args.max_depth)) for f in args.files]
        h, w = frames[0][1].shape
        fx, fy, cx, cy = args.intrinsics
        cam = _core.Camera(w, h, fx, fy, cx, cy)
        result = calibrate(frames, cam, max_tilt=math.radians(args.max_tilt))
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    d = result.as_dict(args.base_frame, args.optical_frame)
    if args.plot and result.found:
        from .calibrate import plot_calibration

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
    if not result.found:
        print(f"kinect-pipeline calibrate: {result.message}", file=sys.stderr)
        return 1
    return 0


def _calibrate_bag(args: argparse.Namespace) -> int:
    """calibrate --bag: the tf-provided pose against the floor seen in each frame."""
    from .calibrate import CalibrationError, check_tf, describe_tf_check, plot_tf_check

    if args.files:
        raise ToolError(f"--bag checks a bag: give no frame files as well (got {args.files})")
    try:
        check = check_tf(
            Path(args.bag),
            depth_topic=args.depth_topic,
            base_frame=args.base_frame,
            base_frame_height=args.base_frame_height,
            max_depth=args.max_depth,
            max_tilt=math.radians(args.max_tilt),
            show_progress=not args.json,
        )
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    if args.plot:
        plot_tf_check(check, Path(args.plot))
    if args.json:
        print(json.dumps(check.as_dict(), indent=1))
    else:
        print(describe_tf_check(check))
        if args.plot:
            print(f"plot: {args.plot}")
    if check.summary()["frames_with_floor"] == 0:
        print(f"kinect-pipeline calibrate: no floor found in any frame of {args.bag}", file=sys.stderr)
        return 1
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from .replay import ReplayError, ReplayOptions
    from .report import write_report

    opts = ReplayOptions(depth_topic=args.depth_topic, base_frame=args.base_frame)
    try:
        summary = write_report(Path(args.input), Path(args.out), opts, show_progress=not args.quiet)
    except ReplayError as exc:
        raise ToolError(str(exc)) from exc
    print(json.dumps(summary, indent=1))
    print(f"report: {Path(args.out) / 'index.html'}")
    return 0


def cmd_regress(args: argparse.Namespace) -> int:
    from .regress import regress

    override = parse_params(args.param)
    lines, problems = regress(update=args.update, config_override=override)
    print("\n".join(lines))
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0


def cmd_curve(args: argparse.Namespace) -> int:
    from . import _core
    from .calibrate import CalibrationError, load_depth
    from .curve import curve_from_model, describe, fit_curve, generated_floor_frames, plot, set_live, write_yaml

    try:
        if args.from_model:
            fit = curve_from_model(args.from_model[0], args.from_model[1], args.rate, args.margin)
        elif args.compare and not args.files:
            print("fitted on 3 generated Kinect v2 floor frames (no frames given):")
            frames = generated_floor_frames(3)
            h, w = frames[0][1].shape
            from . import kinect_v2_camera

            fit = fit_curve(frames, kinect_v2_camera(), args.rate, args.margin)
        else:
            if not args.files or not args.intrinsics:
                raise ToolError("give floor frames and --intrinsics, or --from-model SIGMA0 K, or --compare")
            frames = [(f, load_depth(Path(f), args.depth_scale)) for f in args.files]
            h, w = frames[0][1].shape
            fit = fit_curve(frames, _core.Camera(w, h, *args.intrinsics), args.rate, args.margin)
    except CalibrationError as exc:
        raise ToolError(str(exc)) from exc
    print(describe(fit))
    if args.output:
        write_yaml(fit, Path(args.output))
        print(f"YAML: {args.output}")
    if args.plot:
        plot(fit, _core.Config().threshold_curve, Path(args.plot))
        print(f"plot: {args.plot}")
    if args.compare:
        from .curve import compare_with_constant, comparison_table, plot_comparison

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
    if args.set_node:
        print(f"set on {args.set_node}: {set_live(args.set_node, fit)['threshold_curve']}")
    return 0


def cmd_bench_ros(args: argparse.Namespace) -> int:
    from .bench_ros import report, run

    if args.sequential:
        results = [m for s in ("relay", "node", "nodelet") for m in run(args.frames, args.rate, args.threads, s)]
    else:
        results = run(frames=args.frames, rate=args.rate, threads=args.threads)
    print(
        f"image -> output latency at {args.rate:g} Hz, 512x424 16UC1, {args.frames} frames each, "
        f"num_threads {args.threads}, same run, "
        + ("one subject after the other:" if args.sequential else "interleaved:")
    )
    print(report(results))
    return 0


def cmd_quality(args: argparse.Namespace) -> int:
    from .quality import evaluate, table

    rows = evaluate(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"lab scene, Kinect v2 at 1.1 m tilted 15 deg, {args.frames} frames per condition, {args.encoding}, "
        "Kinect noise + dropouts + flying pixels + 8 m range; means over frames:"
    )
    print(table(rows))
    from .quality import evaluate_pose_errors, pose_table

    pose_rows = evaluate_pose_errors(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"\nthe same camera on a Segway rocking +-4 deg (25 deg/s), {args.frames} frames, told a pose off by: "
        "(the floor fit's learned correction, time constant 2 s, carries over between frames)"
    )
    print(pose_table(pose_rows))
    return 0


def cmd_cliff(args: argparse.Namespace) -> int:
    from .cliff import EDGE, STEP, evaluate, picture, table

    rows = evaluate(frames=args.frames, encoding=args.encoding, show_progress=not args.quiet)
    print(
        f"negative obstacles: a stair down {EDGE:g} m ahead ({STEP * 100:g} cm step) and a flat floor, Kinect v2 at "
        f"1.1 m tilted 0.3 rad, {args.frames} frames per condition, {args.encoding} with noise, dropouts and "
        "flying pixels; cliff_in_scan on:"
    )
    print(table(rows))
    if args.pictures:
        out = Path(args.pictures)
        out.mkdir(parents=True, exist_ok=True)
        print("pictures: " + "  ".join(str(p) for p in picture(out, args.encoding)))
    return 0


def cmd_soak(args: argparse.Namespace) -> int:
    from .bench_ros import run, soak_report

    frames = int(args.minutes * 60 * args.rate)
    results = run(frames=frames, rate=args.rate, threads=args.threads, only=args.subject)
    print(f"soak: {args.minutes:g} min at {args.rate:g} Hz, 512x424 16UC1, num_threads {args.threads}:")
    print(soak_report(results))
    return 0 if all(r.sent == r.received for r in results) else 1


def cmd_evaluate(args: argparse.Namespace) -> int:
    """Quality of the default configuration on noisy rendered frames at a known pose."""
    import numpy as np

    from . import _core, kinect_v2_camera
    from .metrics import frame_quality
    from .scenes import lab_scene, render_frame

    cam = kinect_v2_camera()
    cond = [
        (0.0, 0.0),
        (math.radians(6), math.radians(2)),
        (-math.radians(6), math.radians(2)),
        (math.radians(3), -math.radians(2)),
    ]
    print(
        "| encoding | frames | floor removed (<6 m) min | obstacles 5 cm..1.95 m kept min "
        "| above ceiling removed min | phantom beams max |"
    )
    print("|---|---|---|---|---|---|")
    for enc in args.encodings:
        rows = []
        for i in range(args.frames):
            bp, br = cond[i % len(cond)]
            pipe = _core.Pipeline(cam, _core.Config(sensor_height=args.height, sensor_pitch=args.pitch))
            f = render_frame(cam, lab_scene(), args.height, args.pitch + bp, br, enc, seed=100 + i)
            q = frame_quality(pipe.process(f.depth, bp, br), f)
            rows.append([q.floor_removed, q.obstacles_kept, q.above_ceiling_removed, q.phantom_beams])
        a = np.array(rows)
        print(
            f"| {enc} | {len(rows)} | {np.nanmin(a[:, 0]):.4f} | {np.nanmin(a[:, 1]):.4f} "
            f"| {np.nanmin(a[:, 2]):.4f} | {np.nanmax(a[:, 3]):.4f} |"
        )
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="kinect-pipeline", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("demo", help="synthetic Segway sequence through the pipeline -> PNGs + quality.json")
    d.add_argument("--out", default="out/demo", help="output folder (default: out/demo)")
    d.add_argument("--frames", type=int, default=40, help="frames to render (default 40)")
    d.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="8UC1")
    d.add_argument("--seed", type=int, default=1)
    d.set_defaults(func=cmd_demo)

    s = sub.add_parser("synth", help="write a bag of a synthetic Segway sequence (depth, camera_info, tf, LiDAR)")
    s.add_argument("output", help="bag to write (refused if it exists)")
    s.add_argument("--frames", type=int, default=30)
    s.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.add_argument(
        "--tf-error-height", type=float, default=0.0, help="add this to the mounting height the tf states [m]"
    )
    s.add_argument(
        "--tf-error-pitch", type=float, default=0.0, help="add this to the mounting pitch the tf states [deg]"
    )
    s.add_argument("--tf-error-roll", type=float, default=0.0, help="add this to the mounting roll the tf states [deg]")
    s.set_defaults(func=cmd_synth)

    b = sub.add_parser("bench", help="time per stage and per frame vs memcpy, 1 and 2 threads (C++ benchmark)")
    b.add_argument("--frames", type=int, default=300)
    b.add_argument("--kernel", type=int, default=3)
    b.add_argument("--projection", choices=["horizontal", "column"], default="horizontal")
    b.add_argument("--threads", help="comma-separated thread counts, e.g. 1,2,4,8 (default 1,2)")
    b.add_argument("--encodings", help="comma-separated subset of 8UC1,16UC1,32FC1 (default all three)")
    b.add_argument("--surface-band", type=float, default=0.0, help="the pipeline's surface_band (default 0)")
    b.add_argument("--markdown", action="store_true", help="print a Markdown table")
    b.set_defaults(func=cmd_bench)

    rp = sub.add_parser(
        "replay", help="run the pipeline over a bag at the pose its tf gives; write scan + cleaned image"
    )
    rp.add_argument("input", help="ROS 1 bag with a depth image, its camera_info and tf")
    rp.add_argument("-o", "--output", required=True, help="new bag: the input's messages plus the outputs")
    rp.add_argument("--depth-topic", help="depth Image topic (default: the only one with 'depth' in its name)")
    rp.add_argument("--info-topic", help="CameraInfo topic (default: camera_info beside the depth topic)")
    rp.add_argument("--base-frame", default="base_footprint", help="gravity-aligned frame on the floor")
    rp.add_argument("--base-frame-height", type=float, default=0.0, help="its origin's height above the floor [m]")
    rp.add_argument(
        "--pose-fallback",
        choices=["static", "skip"],
        default="static",
        help="frames without tf: static pose from the parameters, or skip them",
    )
    rp.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip damaged messages (and read a truncated or unindexed bag) instead of stopping; says how many and "
        "where",
    )
    rp.add_argument(
        "--resume",
        action="store_true",
        help="continue a replay into OUTPUT that stopped (killed: its .OUTPUT.partial file; or --max-frames): "
        "takes the frames it wrote, computes the rest; the same result as one uninterrupted run",
    )
    rp.add_argument("--max-frames", type=int, help="stop after this many depth frames (a complete, shorter bag)")
    rp.add_argument("--param", action="append", metavar="NAME=VALUE", help="a Config field, e.g. sensor_height=1.1")
    rp.add_argument("--quiet", action="store_true", help="no progress bar")
    rp.set_defaults(func=cmd_replay)

    rep = sub.add_parser(
        "report", help="pictures and an index.html for a bag (frame, scan vs LiDAR, confidence, timing)"
    )
    rep.add_argument("input", help="ROS 1 bag with a depth image, its camera_info and tf")
    rep.add_argument("-o", "--out", required=True, help="output folder")
    rep.add_argument("--depth-topic")
    rep.add_argument("--base-frame", default="base_footprint")
    rep.add_argument("--quiet", action="store_true")
    rep.set_defaults(func=cmd_report)

    g = sub.add_parser("regress", help="replay seeded reference bags and compare with the golden outputs")
    g.add_argument("--update", action="store_true", help="rewrite the golden files (test/golden/*.npz)")
    g.add_argument("--param", action="append", metavar="NAME=VALUE", help="run with a Config field changed")
    g.set_defaults(func=cmd_regress)

    cv = sub.add_parser("curve", help="threshold curve t(d) from floor frames (or a noise model) -> YAML, plot")
    cv.add_argument("files", nargs="*", help="floor frames (as for calibrate)")
    cv.add_argument("--intrinsics", nargs=4, type=float, metavar=("FX", "FY", "CX", "CY"))
    cv.add_argument("--depth-scale", type=float, default=0.001)
    cv.add_argument(
        "--rate",
        type=float,
        default=1e-4,
        help="false-obstacle rate per floor pixel (default 1e-4: a beam sees ~100 floor pixels, so this keeps "
        "phantom beams under the 0.2 %% goal)",
    )
    cv.add_argument("--margin", type=float, default=0.01, help="added to k sigma [m]")
    cv.add_argument(
        "--from-model",
        nargs=2,
        type=float,
        metavar=("SIGMA0", "K"),
        help="no data: sigma(d) = SIGMA0 + K (d - 0.4)^2 [m] (Kinect v2: 0.0015 0.0019)",
    )
    cv.add_argument("-o", "--output", help="write the curve as YAML (rosparam / dynamic_reconfigure)")
    cv.add_argument("--plot", help="write a PNG of the residuals and the curves")
    cv.add_argument("--set-node", help="set it live on this node through dynamic_reconfigure")
    cv.add_argument(
        "--compare",
        action="store_true",
        help="score it on generated noisy frames against the constant margins with the same false-obstacle and "
        "phantom-beam rates (fits on generated floor frames when no frames are given)",
    )
    cv.add_argument("--compare-frames", type=int, default=12, help="generated frames for --compare (default 12)")
    cv.add_argument("--compare-plot", help="with --compare: write a PNG of the curves and what they remove")
    cv.set_defaults(func=cmd_curve)

    c = sub.add_parser(
        "calibrate",
        help="sensor height, pitch and roll from frames of a flat floor; --bag: tf's pose vs the floor per frame",
    )
    c.add_argument("files", nargs="*", help="depth frames: 16-bit PNG/PGM (mm), 8-bit PNG, or .npy (float m)")
    c.add_argument("--intrinsics", nargs=4, type=float, metavar=("FX", "FY", "CX", "CY"))
    c.add_argument(
        "--bag",
        help="a bag of a moving base: per depth frame, how far the pose tf gives (URDF + IMU) is from the floor seen "
        "in it (median / p95 / max; intrinsics from its camera_info)",
    )
    c.add_argument("--depth-topic", help="with --bag: the depth Image topic (default: as replay)")
    c.add_argument("--base-frame-height", type=float, default=0.0, help="with --bag: base frame height [m]")
    c.add_argument(
        "--plot",
        help=(
            "write a PNG: with frames, the first one's floor under the calibrated pose; "
            "with --bag, tf vs floor per frame"
        ),
    )
    c.add_argument("--depth-scale", type=float, default=0.001, help="metres per unit of 16-bit files (TUM: 0.0002)")
    c.add_argument("--max-depth", type=float, default=12.0, help="depth of 8-bit value 255 [m]")
    c.add_argument(
        "--max-tilt",
        type=float,
        default=40.0,
        help="largest |pitch| / roll considered [deg]: a wall seen by a level camera looks like a floor "
        "seen by a steeply tilted one",
    )
    c.add_argument("--json", action="store_true", help="print JSON (height, pitch, roll [m, rad], floor_fraction, ...)")
    c.add_argument("--base-frame", default="base_footprint")
    c.add_argument("--optical-frame", default="kinect2_depth_optical_frame")
    c.set_defaults(func=cmd_calibrate)

    r = sub.add_parser("bench-ros", help="image->scan latency and CPU: node, nodelet, bare image_transport relay")
    r.add_argument("--frames", type=int, default=300)
    r.add_argument("--rate", type=float, default=30.0, help="frames per second")
    r.add_argument(
        "--threads",
        type=int,
        default=1,
        help="the pipeline's num_threads (default 1, as the node's; 0: OpenMP default)",
    )
    r.add_argument(
        "--sequential",
        action="store_true",
        help="run the subjects one after the other instead of interleaving their frames",
    )
    r.set_defaults(func=cmd_bench_ros)

    q = sub.add_parser("quality", help="quality table per pitch condition and mode vs baselines (ground truth)")
    q.add_argument("--frames", type=int, default=20, help="frames per pitch condition")
    q.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1")
    q.add_argument("--quiet", action="store_true")
    q.set_defaults(func=cmd_quality)

    cl = sub.add_parser("cliff", help="negative obstacles (stair down, hole, flat floor) per pitch condition")
    cl.add_argument("--frames", type=int, default=20, help="frames per pitch condition")
    cl.add_argument("--encoding", choices=["8UC1", "16UC1", "32FC1"], default="16UC1")
    cl.add_argument("--pictures", metavar="DIR", help="also write the stair and hole pictures into DIR")
    cl.add_argument("--quiet", action="store_true")
    cl.set_defaults(func=cmd_cliff)

    so = sub.add_parser("soak", help="long run through a real roscore: drops, latency, memory at start and end")
    so.add_argument("--minutes", type=float, default=10.0)
    so.add_argument("--rate", type=float, default=30.0)
    so.add_argument("--threads", type=int, default=1, help="the pipeline's num_threads (default 1, as the node's)")
    so.add_argument("--subject", choices=["node", "nodelet"], default="nodelet")
    so.set_defaults(func=cmd_soak)

    e = sub.add_parser("evaluate", help="quality of the default config on noisy rendered frames (table)")
    e.add_argument("--frames", type=int, default=8)
    e.add_argument("--height", type=float, default=1.1, help="sensor height [m]")
    e.add_argument("--pitch", type=float, default=math.radians(15), help="sensor tilt [rad]")
    e.add_argument("--encodings", nargs="+", default=["8UC1", "16UC1", "32FC1"])
    e.set_defaults(func=cmd_evaluate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except (ToolError, ValueError, OSError, FileExistsError) as exc:
        print(f"kinect-pipeline {args.command}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
