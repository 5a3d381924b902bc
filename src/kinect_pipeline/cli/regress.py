"""kinect-pipeline regress: the seeded reference bags against the golden outputs."""

from __future__ import annotations

import argparse
import sys

from ._common import add_param, parse_params

NAME = "regress"
HELP = "replay seeded reference bags and compare with the golden outputs (test/golden)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--update", action="store_true", help="rewrite the golden files test/golden/*.npz (default: compare only)"
    )
    add_param(p, "run with a core Config field changed")


def run(args: argparse.Namespace) -> int:
    from ..evaluation.regress import regress

    lines, problems = regress(update=args.update, config_override=parse_params(args.param))
    print("\n".join(lines))
    for p in problems:
        print(p, file=sys.stderr)
    return 1 if problems else 0
