"""What every command shares: the help format, the options several commands take (``--param``, ``--intrinsics``,
frames, ``--quiet``) with their checks, and the one-line error every known failure becomes."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from ..outputs import Named, check_outputs

COMMAND = "kinect-pipeline"


class ToolError(Exception):
    """A known failure: printed as one line, exit status 1."""


def warn(command: str, text: str) -> None:
    """A result that rests on a guess or is doubtful: one WARNING line on stderr."""
    print(f"{COMMAND} {command}: WARNING: {text}", file=sys.stderr)


class Formatter(argparse.RawDescriptionHelpFormatter):
    """Help that states each option's default (unless its text already does)."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default
        if "default" in text or d is None or d is False or d == argparse.SUPPRESS or action.required:
            return text
        return text + " (default: %(default)s)"


# -- typed options: the parser refuses a bad value, naming the option, the value and what was expected -------------


def count(lo: int = 1, hi: int = 1_000_000) -> Callable[[str], int]:
    """An option's type: a whole number in lo..hi (frames, seeds, workers, threads)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"'{text}': expected a whole number {lo}..{hi}")
        return value

    parse.__name__ = "count"
    return parse


def number(lo: float = -math.inf, hi: float = math.inf, *, above: float | None = None) -> Callable[[str], float]:
    """An option's type: a finite number in [lo, hi], or (``above``) greater than that."""
    bounds = [f"> {above:g}" if above is not None else f">= {lo:g}" if math.isfinite(lo) else "", f"<= {hi:g}"]
    span = " and ".join(b for b in bounds if b and "inf" not in b)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and lo <= value <= hi and (above is None or value > above)):
            raise argparse.ArgumentTypeError(f"'{text}': expected a finite number {span}".rstrip())
        return value

    parse.__name__ = "number"
    return parse


def empty_means_none(action: argparse.Action) -> None:
    """Marks an option whose empty value says "none" (its help says so): refuse_empty lets it be."""
    action.empty_means_none = True  # type: ignore[attr-defined]


def refuse_empty(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """An option or argument given as an empty string names nothing (a file, a topic, a list): refused with the
    parser's error (exit 2), before anything runs. Before, some were ignored and some meant the current folder."""
    for action in parser._actions:  # argparse has no public list of a parser's actions
        value = getattr(args, action.dest, None)
        if getattr(action, "empty_means_none", False) or value == action.default:
            continue
        if value == "" or (isinstance(value, list) and "" in value):
            name = "/".join(action.option_strings) or action.metavar or action.dest
            parser.error(f"argument {name}: an empty value: expected {action.metavar or action.dest.upper()}")


def only_with(parser: argparse.ArgumentParser, mode: str, *options: str, absent: bool = False) -> None:
    """Marks options that mean something only with the option MODE (absent: only without it): refuse_unused refuses
    them otherwise. Before, such an option was ignored and the command did less than asked, with exit 0."""
    for o in options:
        parser._option_string_actions[o].only_with = (mode, absent)  # type: ignore[attr-defined]


def given_dests(parser: argparse.ArgumentParser, argv: list[str], command: argparse.ArgumentParser) -> set[str]:
    """The options of COMMAND (a subparser of PARSER) given on ARGV: parsed again with every default suppressed
    (argparse cannot tell a default from the same value given)."""
    for action in command._actions:
        action.default = argparse.SUPPRESS
    return set(vars(parser.parse_args(argv)))


def refuse_unused(parser: argparse.ArgumentParser, args: argparse.Namespace, given: set[str]) -> None:
    """An option marked by only_with and given where its mode says it is ignored: the parser's error (exit 2)."""
    for action in parser._actions:
        mode, absent = getattr(action, "only_with", (None, False))
        if mode is None or action.dest not in given:
            continue
        if bool(getattr(args, parser._option_string_actions[mode].dest)) == absent:
            name = "/".join(action.option_strings)
            parser.error(f"argument {name}: {'not with' if absent else 'needs'} {mode} (it would be ignored)")


def add_quiet(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quiet", action="store_true", help="no progress bar (default: a bar with frames/s on stderr)")


# -- --param NAME=VALUE ---------------------------------------------------------------------------------------------


def add_param(p: argparse.ArgumentParser, what: str = "a core Config field") -> None:
    p.add_argument(
        "--param",
        action="append",
        metavar="NAME=VALUE",
        help=f"{what}, e.g. sensor_height=1.1 (SI units: m, rad; repeat for more; default: the Config's defaults)",
    )


def config_fields() -> list[str]:
    """What --param takes: the Config fields, and sensor_model (a preset of some of them)."""
    from .. import _core

    return [*_core.Config().to_dict(), "sensor_model"]


def parse_params(items: Iterable[str] | None) -> dict[str, Any]:
    """``NAME=VALUE`` items as Config fields (values as JSON: numbers, true/false, or plain text), each checked by
    the core; a bad item raises :class:`ToolError` naming it and the valid fields."""
    from .. import _core

    out: dict[str, Any] = {}
    fields = config_fields()
    for item in items or []:
        name, eq, text = item.partition("=")
        name = name.strip()
        if not eq or not name or not text.strip():
            raise ToolError(f"--param {item!r}: expected NAME=VALUE with NAME one of {', '.join(fields)}")
        if name not in fields:
            raise ToolError(f"--param {item}: no Config field {name!r}; the fields are {', '.join(fields)}")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        try:
            _core.Config(**{name: value})
        except (TypeError, ValueError, RuntimeError) as exc:
            raise ToolError(f"--param {item}: {exc}") from exc
        out[name] = value
    return out


# -- --sensor-model NAME, --intrinsics FX FY CX CY -----------------------------------------------------------------


def add_sensor_model(p: argparse.ArgumentParser, what: str) -> None:
    from .. import _core

    p.add_argument(
        "--sensor-model",
        choices=_core.sensor_models(),
        help=f"the depth camera's preset: {what} (default: none: kinect_v2's curve, no intrinsics)",
    )


def with_sensor_model(config: dict[str, Any], name: str | None) -> dict[str, Any]:
    """Config fields with --sensor-model NAME added (explicit --param fields still win over the preset's)."""
    if name and "sensor_model" not in config:
        return {**config, "sensor_model": name}
    return config


def frames_camera(args: argparse.Namespace, width: int, height: int) -> Any:
    """The camera of frames: --intrinsics, else the --sensor-model preset's nominal camera scaled to their size
    (a WARNING on stderr says it is a guess)."""
    from ..intrinsics import HOW, IntrinsicsError, nominal_camera

    intr = intrinsics_of(args)
    try:
        if intr is not None:
            return intr.camera(width, height)
        name = getattr(args, "sensor_model", None)
        if not name:
            raise ToolError(
                f"depth frames need the camera's intrinsics: {HOW}, or --sensor-model NAME for nominal ones"
            )
        cam, warning = nominal_camera(name, width, height)
    except IntrinsicsError as exc:
        raise ToolError(str(exc)) from exc
    warn(args.command, warning)
    return cam


def add_intrinsics(p: argparse.ArgumentParser, extra: str = "") -> None:
    p.add_argument(
        "--intrinsics",
        metavar="FX,FY,CX,CY[,W,H]|FILE",
        help="the depth camera's focal lengths and principal point [px] (K of its camera_info) and optionally the "
        "image size they are for, with or without commas, or a camera_info YAML file as camera_calibration writes it"
        + (extra or " (default: none; required)"),
    )


def join_intrinsics(argv: list[str]) -> list[str]:
    """The command line with ``--intrinsics FX FY CX CY [W H]`` (numbers apart, as before commas were taken) made
    one argument, ``--intrinsics=FX,FY,CX,CY[,W,H]``, so that frames named after it stay frames."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        out.append(argv[i])
        i += 1
        if out[-1] != "--intrinsics":
            continue
        numbers: list[str] = []
        while i < len(argv) and len(numbers) < 6 and _is_number(argv[i]):
            numbers.append(argv[i])
            i += 1
        if len(numbers) > 1:
            out[-1] = "--intrinsics=" + ",".join(numbers)
        else:
            out += numbers
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def intrinsics_of(args: argparse.Namespace) -> Any:
    """``--intrinsics`` as :class:`kinect_pipeline.intrinsics.Intrinsics` (None where not given); a bad value raises
    ToolError naming it."""
    from ..intrinsics import IntrinsicsError, parse_intrinsics

    values = getattr(args, "intrinsics", None)
    if not values:
        return None
    try:
        return parse_intrinsics([str(values)])
    except IntrinsicsError as exc:
        raise ToolError(str(exc)) from exc


# -- depth frames ---------------------------------------------------------------------------------------------------


def add_frames(p: argparse.ArgumentParser, what: str, sensor_use: str, positional: bool = True) -> None:
    """The frames (positional ``files``, unless given otherwise), --depth-scale, --intrinsics and --sensor-model."""
    if positional:
        p.add_argument(
            "files",
            nargs="*",
            metavar="FRAME",
            help=f"{what}: depth frames or folders of them (16-bit PNG/PGM in mm unless --depth-scale, 8-bit PNG "
            "normalised by --max-depth, .npy float metres)",
        )
    p.add_argument(
        "--depth-scale",
        type=number(above=0.0),
        default=0.001,
        help="metres per unit of 16-bit frames [m] (TUM and slambook2 ch7: 0.0002)",
    )
    add_intrinsics(
        p,
        " (default: none; frames need them unless --sensor-model gives nominal ones; a bag: its camera_info, where it "
        "has none --sensor-model's nominal camera with a warning)",
    )
    add_sensor_model(p, sensor_use)


def frame_files(items: Iterable[str], command: str = "") -> list[Path]:
    """The frames named: files as given, folders as their depth frames in name order (colour images in them
    skipped, one line on stderr per folder saying how many, when ``command`` names the command)."""
    from ..tools.calibrate import frame_paths

    skipped: list[str] = []
    try:
        out = frame_paths([Path(p) for p in items], skipped)
    except ValueError as exc:
        raise ToolError(str(exc)) from exc
    for line in skipped if command else ():
        print(f"{COMMAND} {command}: {line}", file=sys.stderr)
    return out


def check(inputs: Iterable[Path | Named], outputs: Iterable[Named | None], folders: Iterable[Named] = ()) -> None:
    """Before anything is written: no output may be an input (see :func:`kinect_pipeline.outputs.check_outputs`)."""
    check_outputs(inputs, [o for o in outputs if o is not None and str(o.path)], folders)


def named(option: str, value: str | None) -> Named | None:
    return Named(Path(value), option) if value else None
