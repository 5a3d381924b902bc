"""Quality table on the generator's ground truth: per pitch condition and per geometry/projection mode, against a
static-tilt pipeline (base pitch ignored) and a single-row band scan, all in one run."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _core, kinect_v2_camera
from ..outputs import progress
from ..simulation.robot import SegwayMotion
from ..simulation.scenes import FIRST_BOX, FLOOR, Scene, ideal_scan, lab_scene, render_frame
from .metrics import missed_beams, phantom_beams

HEIGHT, TILT = 1.1, math.radians(15.0)

CONDITIONS: dict[str, Callable[[int], float]] = {
    "static": lambda i: 0.0,
    "oscillating": lambda i: math.radians(4.0) * math.sin(2 * math.pi * i / 30.0),
    "jerks": SegwayMotion(amplitude=math.radians(2.0), period_frames=60.0, jerk_frame=5).pitch,
}

#: name -> (Config fields, base pitch given to the pipeline?)
VARIANTS: dict[str, tuple[dict[str, Any] | None, bool]] = {
    "exact, horizontal (default)": ({}, True),
    "exact, horizontal, surface_band 1": ({"surface_band": 1.0}, True),
    "exact, column": ({"projection": "column"}, True),
    "thesis, column": ({"geometry": "thesis", "projection": "column"}, True),
    "static tilt (base pitch ignored)": ({}, False),
    "band scan, 1 row (no floor removal)": (None, False),
}

HEIGHT_CLASSES = ((0.05, 0.10), (0.10, 0.30), (0.30, 2.0))


def _pct(x: float) -> str:
    """A fraction as a percentage for the tables; NaN (not measured) as a dash."""
    return "–" if math.isnan(x) else f"{100 * x:.2f}"


@dataclass
class Row:
    condition: str
    variant: str
    floor_removed: float
    kept: tuple[float, ...]
    phantom: float
    phantom_noise: float
    missed: float
    range_error_cm: float

    def markdown(self) -> str:
        kept = " | ".join(_pct(k) for k in self.kept)
        err = "–" if math.isnan(self.range_error_cm) else f"{self.range_error_cm:.1f}"
        return (
            f"| {self.condition} | {self.variant} | {_pct(self.floor_removed)} | {kept} | {_pct(self.phantom)} "
            f"| {_pct(self.phantom_noise)} | {_pct(self.missed)} | {err} |"
        )


HEADER = (
    "| base pitch | pipeline | floor removed (< 6 m) % | kept 5–10 cm % | kept 10–30 cm % | kept 0.3–2 m % "
    "| phantom > 5 cm % | phantom > 5 cm + 4σ % | missed beams % | median range error [cm] |\n"
    "|---|---|---|---|---|---|---|---|---|---|"
)


def _tall_ids(scene: Scene) -> set[int]:
    return {FIRST_BOX + i for i, b in enumerate(scene.boxes) if b[5] - b[4] >= 0.10 and b[4] < 2.0}


def evaluate(frames: int = 20, encoding: str = "16UC1", seed: int = 11, show_progress: bool = False) -> list[Row]:
    cam = kinect_v2_camera()
    scene = lab_scene()
    tall = _tall_ids(scene)
    geometry = _scan_geometry(cam)
    rows: list[Row] = []
    items = [(c, v) for c in CONDITIONS for v in VARIANTS]
    sums: dict[tuple[str, str], dict[str, list[float]]] = {k: {} for k in items}
    for cond, pitch_of in CONDITIONS.items():
        pipes = {
            v: _core.Pipeline(cam, _core.Config(sensor_height=HEIGHT, sensor_pitch=TILT, **cfg))
            for v, (cfg, _) in VARIANTS.items()
            if cfg is not None
        }
        it = range(frames)
        for i in progress(it, frames, cond) if show_progress else it:
            bp = pitch_of(i)
            f = render_frame(cam, scene, HEIGHT, TILT + bp, 0.0, encoding, seed + i, tof=True)
            t = f.truth
            obj, height, rng = t["object"], t["height"], t["range"]
            obstacle = (obj >= FIRST_BOX) & (height <= 2.0)
            for v, (cfg, use_pitch) in VARIANTS.items():
                acc = sums[(cond, v)]
                if cfg is None:
                    metres = f.metres.astype(np.float32)
                    ranges = _core.band_scan(np.ascontiguousarray(metres), cam, 1)
                    labels = None
                    angle_min, inc = geometry
                else:
                    res = pipes[v].process(f.depth, bp if use_pitch else 0.0, 0.0)
                    ranges, labels = res.ranges, res.labels
                    angle_min, inc = res.angle_min, res.angle_increment
                n = len(ranges)
                if labels is not None:
                    floor = (obj == FLOOR) & (rng < 6.0)
                    acc.setdefault("floor", []).append(float((labels[floor] != 0).mean()))
                    for k, (lo, hi) in enumerate(HEIGHT_CLASSES):
                        m = obstacle & (height >= lo) & (height < hi)
                        if m.any():
                            acc.setdefault(f"kept{k}", []).append(float((labels[m] == _core.LABELS["kept"]).mean()))
                phantom, phantom4 = phantom_rates(t, ranges, angle_min, inc, obstacle)
                acc.setdefault("phantom", []).append(phantom)
                acc.setdefault("phantom4", []).append(phantom4)
                r = np.asarray(ranges, np.float64)
                fin = np.isfinite(r)
                tall_scan = ideal_scan(t, angle_min, inc, n, np.isin(obj, list(tall)) & (height <= 2.0))
                seen = np.isfinite(tall_scan)
                if seen.any():
                    miss = missed_beams(r, tall_scan)
                    acc.setdefault("missed", []).append(float(miss.sum() / seen.sum()))
                obst_scan = ideal_scan(t, angle_min, inc, n, obstacle)
                both = fin & np.isfinite(obst_scan)
                if both.any():
                    acc.setdefault("err", []).append(float(np.median(np.abs(r[both] - obst_scan[both]))))
    for cond, v in items:
        acc = sums[(cond, v)]

        def mean(key: str, acc: dict[str, list[float]] = acc) -> float:
            vals = acc.get(key, [])
            return float(np.mean(vals)) if vals else float("nan")

        rows.append(
            Row(
                cond,
                v,
                mean("floor"),
                tuple(mean(f"kept{k}") for k in range(len(HEIGHT_CLASSES))),
                mean("phantom"),
                mean("phantom4"),
                mean("missed"),
                100 * mean("err"),
            )
        )
    return rows


def phantom_rates(
    truth: dict[str, np.ndarray], ranges: Any, angle_min: float, inc: float, obstacle: np.ndarray
) -> tuple[float, float]:
    """Fractions of beams that are phantom (metrics.phantom_beams) against the nearest true obstacle: by > 5 cm,
    and by > 5 cm + 4 sigma of the sensor's noise. A kept floor pixel makes one, as navigation sees it."""
    over_5cm, over_noise = phantom_beams(ranges, ideal_scan(truth, angle_min, inc, len(ranges), obstacle))
    return float(over_5cm.mean()), float(over_noise.mean())


def _scan_geometry(cam: _core.Camera) -> tuple[float, float]:
    res = _core.Pipeline(cam, _core.Config(projection="column")).process(np.zeros((cam.height, cam.width), np.uint16))
    return res.angle_min, res.angle_increment


def table(rows: list[Row]) -> str:
    return HEADER + "\n" + "\n".join(r.markdown() for r in rows)


# ---------------------------------------------------------------- pose errors (the floor refinement)

DEG = math.radians(1.0)

#: told pose minus true: name -> (height [m], pitch [rad], roll [rad], base pitch signal late by [s])
POSE_ERRORS: dict[str, tuple[float, float, float, float]] = {
    "exact": (0.0, 0.0, 0.0, 0.0),
    "pitch +1°": (0.0, DEG, 0.0, 0.0),
    "pitch −1°": (0.0, -DEG, 0.0, 0.0),
    "roll +1°": (0.0, 0.0, DEG, 0.0),
    "height +5 cm": (0.05, 0.0, 0.0, 0.0),
    "height −5 cm": (-0.05, 0.0, 0.0, 0.0),
    "+5 cm, +1°, +1°": (0.05, DEG, DEG, 0.0),
    "−5 cm, −1°, +1°": (-0.05, -DEG, DEG, 0.0),
    "base pitch 50 ms late": (0.0, 0.0, 0.0, 0.05),
}
RATE = 30.0  # frames per second of the sequences
POSE_METHODS = ("refine_floor on (default)", "refine_floor off")
RANSAC = "RANSAC plane of each frame (no pose needed)"


def segway_pitch(t: float) -> float:
    """Base pitch [rad] of a Segway rocking +-4 deg once a second (up to 25 deg/s) at time t [s]."""
    return math.radians(4.0) * math.sin(2.0 * math.pi * t)


@dataclass
class PoseRow:
    condition: str
    method: str
    floor_removed: float
    obstacles_kept: float
    phantom: float
    false_cliff: float
    accepted: float
    ms: float

    def markdown(self) -> str:
        return (
            f"| {self.condition} | {self.method} | {_pct(self.floor_removed)} | {_pct(self.obstacles_kept)} "
            f"| {_pct(self.phantom)} | {_pct(self.false_cliff)} | {_pct(self.accepted)} | {self.ms:.2f} |"
        )


POSE_HEADER = (
    "| told pose − true | pipeline | floor removed (< 6 m) % | obstacles kept (5 cm – 1.95 m) % "
    "| phantom beams % | false cliff beams % | floor fit accepted % | ms / frame |\n"
    "|---|---|---|---|---|---|---|---|"
)


def _frame_scores(res: Any, frame: Any) -> dict[str, float]:
    from .metrics import frame_quality

    t = frame.truth
    q = frame_quality(res, frame)
    obstacle = (t["object"] >= FIRST_BOX) & (t["height"] <= 2.0)
    phantom = phantom_rates(t, res.ranges, res.angle_min, res.angle_increment, obstacle)[1]
    cliff = np.asarray(res.cliff_ranges)
    return {
        "floor": q.floor_removed,
        "kept": q.obstacles_kept,
        "phantom": phantom,
        "cliff": float(np.isfinite(cliff).mean()) if cliff.size else 0.0,
    }


def _ransac_pose(frame: Any, cam: _core.Camera) -> tuple[float, float, float] | None:
    metres = np.where(np.isfinite(frame.metres), frame.metres, 0.0).astype(np.float32)
    fp = _core.calibrate_from_floor(np.ascontiguousarray(metres), cam)
    return (fp["height"], fp["pitch"], fp["roll"]) if fp["found"] else None


def evaluate_pose_errors(
    frames: int = 20, encoding: str = "16UC1", seed: int = 31, show_progress: bool = False
) -> list[PoseRow]:
    """The lab scene seen from a Segway rocking +-4 deg (the quality table's camera), the pipeline told a pose off
    by each of POSE_ERRORS, with the floor refinement on and off, and, as the baseline, the pose of a RANSAC plane
    fitted to each frame (calibrate's MSAC + least squares, which needs no pose). Means over the frames."""
    import time

    cam = kinect_v2_camera()
    scene = lab_scene()
    rendered = []
    for i in progress(range(frames), frames, "render") if show_progress else range(frames):
        t = i / RATE
        rendered.append(
            (t, render_frame(cam, scene, HEIGHT, TILT + segway_pitch(t), 0.0, encoding, seed + i, tof=True))
        )
    rows: list[PoseRow] = []
    for cond, (dh, dp, dr, lag) in POSE_ERRORS.items():
        for method in POSE_METHODS:
            cfg = _core.Config(
                sensor_height=HEIGHT + dh,
                sensor_pitch=TILT + dp,
                sensor_roll=dr,
                refine_floor=method == POSE_METHODS[0],
            )
            pipe = _core.Pipeline(cam, cfg)
            acc: dict[str, list[float]] = {}
            for t, f in rendered:
                t0 = time.perf_counter()
                res = pipe.process(f.depth, segway_pitch(t - lag), 0.0, stamp=t)
                acc.setdefault("ms", []).append(1000 * (time.perf_counter() - t0))
                acc.setdefault("accepted", []).append(float(res.floor_fit.accepted))
                for k, v in _frame_scores(res, f).items():
                    acc.setdefault(k, []).append(v)
            rows.append(_pose_row(cond, method, acc))
    acc = {}
    pipe = _core.Pipeline(cam, _core.Config(refine_floor=False))
    for _, f in rendered:
        t0 = time.perf_counter()
        pose = _ransac_pose(f, cam)
        res = pipe.process_pose(f.depth, *pose) if pose else pipe.process_pose(f.depth, HEIGHT, TILT, 0.0)
        acc.setdefault("ms", []).append(1000 * (time.perf_counter() - t0))
        acc.setdefault("accepted", []).append(float(pose is not None))
        for k, v in _frame_scores(res, f).items():
            acc.setdefault(k, []).append(v)
    rows.append(_pose_row("any", RANSAC, acc))
    return rows


def _pose_row(cond: str, method: str, acc: dict[str, list[float]]) -> PoseRow:
    def mean(k: str) -> float:
        v = [x for x in acc.get(k, []) if not math.isnan(x)]
        return float(np.mean(v)) if v else float("nan")

    return PoseRow(
        cond,
        method,
        mean("floor"),
        mean("kept"),
        mean("phantom"),
        mean("cliff"),
        mean("accepted"),
        float(np.median(acc["ms"])),
    )


def pose_table(rows: list[PoseRow]) -> str:
    return POSE_HEADER + "\n" + "\n".join(r.markdown() for r in rows)


def default_config_table(frames: int, height: float, pitch: float, encodings: list[str]) -> str:
    """A Markdown table of the default configuration's quality on noisy rendered frames at a known pose (the base
    pitching and rolling a few degrees), per encoding: worst frame of each measure."""
    from .metrics import frame_quality

    cam = kinect_v2_camera()
    cond = [(0.0, 0.0), (math.radians(6), math.radians(2)), (-math.radians(6), math.radians(2))]
    cond.append((math.radians(3), -math.radians(2)))
    lines = [
        "| encoding | frames | floor removed (<6 m) min | obstacles 5 cm..1.95 m kept min "
        "| above ceiling removed min | phantom beams max |",
        "|---|---|---|---|---|---|",
    ]
    for enc in encodings:
        rows = []
        for i in range(frames):
            bp, br = cond[i % len(cond)]
            pipe = _core.Pipeline(cam, _core.Config(sensor_height=height, sensor_pitch=pitch))
            f = render_frame(cam, lab_scene(), height, pitch + bp, br, enc, seed=100 + i)
            q = frame_quality(pipe.process(f.depth, bp, br), f)
            rows.append([q.floor_removed, q.obstacles_kept, q.above_ceiling_removed, q.phantom_beams])
        a = np.array(rows, float)
        cells = [_worst(a[:, i], worst) for i, worst in enumerate((np.nanmin, np.nanmin, np.nanmin, np.nanmax))]
        lines.append(f"| {enc} | {len(rows)} | {' | '.join(cells)} |")
    if any("| – |" in line for line in lines):
        lines.append("(–: no pixel or beam of that kind in any frame at this pose)")
    return "\n".join(lines)


def _worst(column: np.ndarray, worst: Any) -> str:
    """The worst of a measure over the frames, or – where no frame had anything to measure (NaN in every one)."""
    return "–" if np.isnan(column).all() else f"{worst(column):.4f}"


def bag_quality(bag: Any, opts: Any = None, show_progress: bool = False) -> dict[str, Any]:
    """The replay of a bag with the generator's ground truth (``/ground_truth/scan``, ``/ground_truth/labels``)
    scored against it, as ``report``'s quality.json: phantom and missed beams (fractions of all beams) and the
    labels' agreement. A bag without ground truth raises ReplayError."""
    from ..tools.replay import ReplayError, ReplayOptions
    from .report import GT_SCAN, collect, truth_quality

    c = collect(bag, opts or ReplayOptions(), show_progress)
    q = truth_quality(c)
    if not q:
        raise ReplayError(f"{bag}: no ground truth ({GT_SCAN}) in the bag to score against")
    return {"frames": len(c.frames), **q}
