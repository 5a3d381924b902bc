"""kinect-pipeline: the tools of kinect_pipeline, one subcommand each (``kinect-pipeline COMMAND --help``).

Every command is a module of this package with ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args)``: it
parses, calls the library (``kinect_pipeline.*``, the C++ core underneath) and prints."""

from __future__ import annotations

import argparse
import sys
from types import ModuleType

from . import (
    bench,
    bench_ros,
    calibrate,
    cliff,
    curve,
    demo,
    evaluate,
    fleet,
    quality,
    regress,
    replay,
    report,
    soak,
    synth,
)
from ._common import (
    COMMAND,
    Formatter,
    ToolError,
    given_dests,
    join_intrinsics,
    parse_params,
    refuse_empty,
    refuse_unused,
)

COMMANDS: tuple[ModuleType, ...] = (
    demo,
    synth,
    replay,
    fleet,
    report,
    calibrate,
    curve,
    quality,
    cliff,
    regress,
    evaluate,
    bench,
    bench_ros,
    soak,
)

DESCRIPTION = """\
Tools of kinect_pipeline: the C++ core over bags and depth frames, calibration, threshold curves, quality
tables and benchmarks. Bags: ROS 1 (.bag) and rosbag2 (sqlite3 or mcap folders, .mcap files).
Run 'kinect-pipeline COMMAND --help' for a command's options."""

__all__ = ["COMMANDS", "ToolError", "build_parser", "main", "parse_params"]


def build_parser() -> argparse.ArgumentParser:
    return _parsers()[0]


def _parsers() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The command line's parser, and each command's own by name."""
    p = argparse.ArgumentParser(prog=COMMAND, description=DESCRIPTION, formatter_class=Formatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands = {}
    for mod in COMMANDS:
        c = commands[mod.NAME] = sub.add_parser(
            mod.NAME, help=mod.HELP, description=mod.HELP, formatter_class=Formatter
        )
        mod.add_arguments(c)
        c.set_defaults(func=mod.run)
    return p, commands


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    return str(exc)


def main(argv: list[str] | None = None) -> int:
    parser, commands = _parsers()
    argv = join_intrinsics(sys.argv[1:] if argv is None else list(argv))
    args = parser.parse_args(argv)
    refuse_empty(commands[args.command], args)
    again, again_commands = _parsers()
    args.given = given_dests(again, argv, again_commands[args.command])  # for a mode set by the input (report)
    refuse_unused(commands[args.command], args, args.given)
    try:
        return int(args.func(args))
    except (ToolError, ValueError, OSError) as exc:
        print(f"{COMMAND} {args.command}: {_message(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
