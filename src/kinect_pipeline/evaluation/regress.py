"""Regression check: replay seeded reference bags and compare with stored golden outputs.

``kinect-pipeline regress`` compares; ``kinect-pipeline regress --update`` rewrites the golden files
(test/golden/*.npz, small) after a change that is meant to move the outputs."""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..outputs import atomic_file
from ..simulation.sequence_bag import Scenario, write_sequence_bag
from ..tools.replay import ReplayOptions
from .report import collect

GOLDEN_DIR = Path(__file__).resolve().parents[3] / "test" / "golden"


@dataclass(frozen=True)
class Case:
    name: str
    encoding: str
    frames: int
    seed: int
    config: tuple[tuple[str, Any], ...] = ()
    exact: bool = False  #: bit for bit: no tolerance


_OFF = (("refine_floor", False),)
CASES = (
    Case("lab_16uc1", "16UC1", 6, 5),
    Case("lab_8uc1_thesis_column", "8UC1", 4, 6, (("geometry", "thesis"), ("projection", "column"))),
    Case("lab_32fc1_filtered", "32FC1", 6, 7, (("intensity_filter", True),)),
    # Without the floor refinement the outputs are those of the pipeline before it existed, bit for bit (these
    # golden files were written before the refinement was added).
    Case("lab_16uc1_refine_off", "16UC1", 6, 5, _OFF, exact=True),
    Case(
        "lab_8uc1_thesis_column_refine_off",
        "8UC1",
        4,
        6,
        (("geometry", "thesis"), ("projection", "column"), *_OFF),
        exact=True,
    ),
    Case("lab_32fc1_filtered_refine_off", "32FC1", 6, 7, (("intensity_filter", True), *_OFF), exact=True),
)

#: What may move without failing: ranges and intensities (absolute), fraction of pixels whose label changed.
TOLERANCES = {"range_m": 1e-3, "intensity": 1e-3, "labels_changed": 1e-4}
EXACT = {"range_m": 0.0, "intensity": 0.0, "labels_changed": 0.0}


def run_case(case: Case, config_override: dict[str, Any] | None = None) -> dict[str, np.ndarray]:
    with tempfile.TemporaryDirectory(prefix="kp-regress-") as tmp:
        bag = Path(tmp) / f"{case.name}.bag"
        write_sequence_bag(bag, Scenario(frames=case.frames, encoding=case.encoding, seed=case.seed))
        config = dict(case.config)
        config.update(config_override or {})
        c = collect(bag, ReplayOptions(config=config), show_progress=False, keep_labels=True)
    return {
        "ranges": np.stack([f.ranges for f in c.frames]).astype(np.float32),
        "intensities": np.stack([f.intensities for f in c.frames]).astype(np.float32),
        "labels": np.stack([f.labels for f in c.frames if f.labels is not None]).astype(np.uint8),
        "angle_min": np.float64(c.angle_min),
        "angle_increment": np.float64(c.angle_increment),
    }


def save_golden(case: Case, out: dict[str, np.ndarray], directory: Path = GOLDEN_DIR) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{case.name}.npz"
    with atomic_file(path) as tmp:
        np.savez_compressed(tmp, **out)
    return path


def compare(case: Case, got: dict[str, np.ndarray], golden: dict[str, np.ndarray]) -> list[str]:
    """What moved beyond the tolerances, as lines naming frame, beam / pixels and amount; empty if nothing did."""
    problems: list[str] = []
    for key in ("ranges", "intensities", "labels"):
        if got[key].shape != golden[key].shape:
            problems.append(f"{case.name}: {key} shape {got[key].shape} != golden {golden[key].shape}")
    if problems:
        return problems
    a0, inc = float(golden["angle_min"]), float(golden["angle_increment"])
    tols = EXACT if case.exact else TOLERANCES
    for key, tol in (("ranges", tols["range_m"]), ("intensities", tols["intensity"])):
        g, w = got[key].astype(np.float64), golden[key].astype(np.float64)
        both_finite = np.isfinite(g) & np.isfinite(w)
        same_special = (np.isnan(g) & np.isnan(w)) | (np.isinf(g) & np.isinf(w) & (np.sign(g) == np.sign(w)))
        diff = np.where(both_finite, np.abs(g - w), np.where(same_special, 0.0, np.inf))
        bad = np.argwhere(diff > tol)
        if len(bad):
            f, b = bad[np.argmax(diff[tuple(bad.T)])]
            problems.append(
                f"{case.name}: {key}: {len(bad)} beam(s) moved beyond {tol:g}; worst frame {f} beam {b} "
                f"(angle {math.degrees(a0 + inc * b):+.2f} deg): {w[f, b]:.4f} -> {g[f, b]:.4f}"
            )
    changed = got["labels"] != golden["labels"]
    frac = float(changed.mean())
    if frac > tols["labels_changed"]:
        f = int(np.argmax(changed.reshape(len(changed), -1).sum(1)))
        rows, cols = np.nonzero(changed[f])
        moves: dict[tuple[int, int], int] = {}
        for r, c in zip(rows, cols, strict=False):
            key2 = (int(golden["labels"][f, r, c]), int(got["labels"][f, r, c]))
            moves[key2] = moves.get(key2, 0) + 1
        top = ", ".join(f"{a}->{b}: {n}" for (a, b), n in sorted(moves.items(), key=lambda kv: -kv[1])[:4])
        problems.append(
            f"{case.name}: labels: {100 * frac:.3f} % of pixels changed (tolerance "
            f"{100 * tols['labels_changed']:.3f} %); most in frame {f}, rows {rows.min()}..{rows.max()}, "
            f"cols {cols.min()}..{cols.max()}; label moves {top}"
        )
    return problems


def regress(
    update: bool = False, config_override: dict[str, Any] | None = None, directory: Path = GOLDEN_DIR
) -> tuple[list[str], list[str]]:
    """Returns (report lines, problems)."""
    lines, problems = [], []
    for case in CASES:
        got = run_case(case, config_override)
        path = directory / f"{case.name}.npz"
        if update:
            save_golden(case, got, directory)
            lines.append(f"{case.name}: golden written to {path} ({path.stat().st_size // 1024} KiB)")
            continue
        if not path.exists():
            problems.append(f"{case.name}: no golden file {path}: run 'kinect-pipeline regress --update'")
            continue
        with np.load(path) as z:
            golden = {k: z[k] for k in z.files}
        p = compare(case, got, golden)
        problems += p
        lines.append(f"{case.name}: {'MOVED' if p else 'ok'} ({case.frames} frames, {case.encoding})")
    return lines, problems
