"""kinect-pipeline fleet: many recordings at once on Dask distributed, a row of metrics per recording and
configuration in OUT/fleet.csv (and .json), the fleet at a glance in OUT/index.html."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ..outputs import Named
from ._common import (
    ToolError,
    add_intrinsics,
    add_param,
    add_quiet,
    add_sensor_model,
    check,
    count,
    number,
    only_with,
    parse_params,
    with_sensor_model,
)
from .replay import add_bag_topics, add_pose_fallback, bag_options

NAME = "fleet"
HELP = (
    "replay many recordings at once on Dask (a LocalCluster, or --scheduler ADDRESS): per recording and "
    "configuration one row of metrics in OUT/fleet.csv, plots in OUT/index.html"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "inputs",
        nargs="*",
        metavar="IN",
        help="recordings: ROS 1 bags, rosbag2 folders or .mcap files, folders of depth frames; as paths, globs "
        "('rec/**/*.bag', quoted) or text files (.txt/.lst/.list) listing them one a line",
    )
    p.add_argument(
        "-o",
        "--output",
        metavar="OUT",
        help="folder of fleet.csv, fleet.json, index.html (made if new; default: none, required unless --bench)",
    )
    p.add_argument(
        "--workers",
        type=count(1, 1024),
        help="LocalCluster: worker processes [processes] (default: one per core); with --scheduler: wait until "
        "that many workers are connected",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: a LocalCluster on this machine)",
    )
    add_bag_topics(p)
    add_pose_fallback(p)
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="go on past damaged messages, counted in the row (default: such a recording is not measured)",
    )
    p.add_argument(
        "--lidar-topic", help="LaserScan for the phantom proxy (default: the bag's LaserScan that is not ground truth)"
    )
    add_intrinsics(p, ", for folders of frames (default: --sensor-model's typical ones)")
    p.add_argument("--depth-scale", type=number(above=0.0), default=0.001, help="metres per unit of 16-bit frames [m]")
    p.add_argument(
        "--frame-rate",
        type=number(hi=10_000.0, above=0.0),
        default=30.0,
        help="of folders of frames: their stamps [Hz]",
    )
    add_sensor_model(p, "its threshold curve, range and cliff pixels (and intrinsics of frames)")
    add_param(p, "a core Config field of every configuration")
    p.add_argument(
        "--config",
        metavar="A.yaml",
        help="the configuration: Config fields as YAML, over --param (default: --param's fields, named 'default' "
        "when there are none)",
    )
    p.add_argument(
        "--compare",
        metavar="B.yaml",
        action="append",
        help="another configuration run over the same recordings and compared with the first (repeatable; "
        "default: none)",
    )
    p.add_argument(
        "--grid",
        metavar="FIELD=V1,V2",
        help="the first configuration with each of these values of one field (default: none)",
    )
    p.add_argument(
        "--threads",
        type=count(0, 1024),
        default=1,
        help="core threads per task [threads] (0: OpenMP's default; one task per worker)",
    )
    p.add_argument("--checksum", action="store_true", help="a rerun compares inputs by content (default: size, mtime)")
    p.add_argument("--redo", action="store_true", help="do every recording again (default: skip up-to-date rows)")
    p.add_argument(
        "--bench",
        action="store_true",
        help="the benchmark instead: synthetic recordings with 1 and 2 workers, against plain replay (default: off)",
    )
    p.add_argument("--bench-recordings", type=count(hi=10_000), default=4, help="--bench: recordings [recordings]")
    p.add_argument("--bench-frames", type=count(), default=150, help="--bench: frames per recording [frames]")
    p.add_argument(
        "--bench-repeat", type=count(hi=100), default=2, help="--bench: rounds, the best of each shown [rounds]"
    )
    only_with(p, "--bench", "--bench-recordings", "--bench-frames", "--bench-repeat")
    # --bench replays synthetic recordings of its own with the default options: the rest would be ignored
    rest = [a.option_strings[-1] for a in p._actions if a.option_strings and a.dest not in ("help", "quiet")]
    only_with(p, "--bench", *[o for o in rest if not o.startswith("--bench")], absent=True)
    add_quiet(p)


def configurations(args: argparse.Namespace) -> list[tuple[str, dict[str, Any]]]:
    """The configurations of the run, by name: --config (else the --param ones), each --compare, the --grid."""
    from ..tools.fleet import FleetError, grid_configs, load_config

    base = with_sensor_model(parse_params(args.param), args.sensor_model)
    try:
        configs = [(Path(args.config).stem, load_config(Path(args.config), base))] if args.config else []
        configs = configs or [("default" if not base else "params", base)]
        configs += [(Path(b).stem, load_config(Path(b), base)) for b in args.compare or []]
        if args.grid:
            configs += grid_configs(configs[0][1], args.grid)
    except FleetError as exc:
        raise ToolError(str(exc)) from exc
    names = [n for n, _ in configs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:  # a file named twice, two files of one name, or a --grid value given twice
        raise ToolError(
            f"configurations named twice: {', '.join(twice)} (of {', '.join(names)}): expected each once (rename a "
            "file, or give a --grid value once)"
        )
    return configs


def run(args: argparse.Namespace) -> int:
    from ..tools.fleet import FleetError, FleetOptions, find_recordings, run_fleet
    from ..tools.fleet_html import write_index

    if args.bench:
        from ..tools.fleet_bench import bench

        if args.inputs:
            raise ToolError(
                f"--bench replays synthetic recordings of its own: give it or IN..., not both (got {args.inputs})"
            )
        print(bench(args.bench_recordings, args.bench_frames, args.bench_repeat))
        return 0
    if not args.inputs or not args.output:
        raise ToolError("expected IN... -o OUT (or --bench)")
    configs = configurations(args)
    replay = bag_options(args, pose_fallback=args.pose_fallback, skip_bad=args.skip_bad)
    opts = FleetOptions(
        replay=replay,
        intrinsics=tuple(replay.intrinsics) if replay.intrinsics else None,
        sensor_model=args.sensor_model,
        depth_scale=args.depth_scale,
        frame_rate=args.frame_rate,
        lidar_topic=args.lidar_topic,
        threads=args.threads,
        checksum=args.checksum,
    )
    try:
        recordings = find_recordings(args.inputs)
    except FleetError as exc:
        raise ToolError(str(exc)) from exc
    out = Path(args.output)
    check(recordings, [], [Named(out, "-o")])
    if out.exists() and not out.is_dir():
        raise ToolError(f"-o {out}: a file, expected a folder")
    out.mkdir(exist_ok=True)
    try:
        result = run_fleet(recordings, out, opts, configs, args.workers, args.scheduler, args.redo, args.quiet)
    except FleetError as exc:
        raise ToolError(str(exc)) from exc
    write_index(out)
    print(
        f"{result.recordings} recording(s) x {len(configs)} configuration(s): {result.computed} done now "
        f"({result.frames} frames in {result.seconds:.1f} s), {result.skipped} up to date; table {out / 'fleet.csv'}, "
        f"page {out / 'index.html'}"
    )
    if result.failed:
        print(f"{COMMAND_NAME}: {len(result.failed)} row(s) not ok:", file=sys.stderr)
        for rec, config, status in result.failed:
            print(f"  {rec} [{config}]: {status}", file=sys.stderr)
        return 1
    return 0


COMMAND_NAME = "kinect-pipeline fleet"
