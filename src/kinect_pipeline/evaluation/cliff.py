"""Negative obstacles on generated scenes: a stair down and a hole while the Segway pitches, and the flat floor on
which nothing may fire; with the base pitch given to the pipeline and ignored (a static tilt), in one run."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import _core, kinect_v2_camera
from ..figures import plot_frame
from ..outputs import progress, save_figure
from ..simulation.scenes import Scene, hole_scene, render_frame, stair_scene
from .quality import CONDITIONS

HEIGHT, TILT = 1.1, 0.3
EDGE, STEP = 2.5, 0.17
AHEAD = 0.2  # |bearing| [rad] of the beams that look over the stair's edge, clear of its box


@dataclass
class CliffRow:
    condition: str
    pipeline: str
    stair_beams_found: float  # % of the beams ahead that report the stair (finite cliff range)
    stair_error_cm: float  # median |cliff range - first visible point of the lower level| [cm]
    stop_before_edge: (
        float  # % of frames in which the scan (cliff_in_scan) holds a beam ahead within 0.5 m past the edge
    )
    flat_false_beams: float  # % of beams reporting a cliff on a flat floor
    flat_false_frames: float  # % of flat-floor frames with any cliff beam


#: the compared pipelines: name -> is the base pitch given to it?
PIPELINES = {"pitch compensated (default)": True, "static tilt (base pitch ignored)": False}


def evaluate(frames: int = 20, encoding: str = "16UC1", seed: int = 5, show_progress: bool = False) -> list[CliffRow]:
    """The table's rows: every pitch condition x {pitch compensated, static tilt} on the same frames."""
    cam = kinect_v2_camera()
    rows: list[CliffRow] = []
    cfg = _core.Config(sensor_height=HEIGHT, sensor_pitch=TILT, cliff_in_scan=True)
    jobs = [(c, p) for c in CONDITIONS for p in PIPELINES]
    for cond, name in progress(jobs, len(jobs), "cliff") if show_progress else jobs:
        give_pitch = PIPELINES[name]
        stair_pipe, flat_pipe = _core.Pipeline(cam, cfg), _core.Pipeline(cam, cfg)
        found, errors, stops, false_beams, false_frames = [], [], [], [], []
        for i in range(frames):
            bp = CONDITIONS[cond](i)
            given = bp if give_pitch else 0.0
            st = render_frame(cam, stair_scene(EDGE, STEP), HEIGHT, TILT + bp, 0.0, encoding, seed=seed + i, tof=True)
            res = stair_pipe.process(st.depth, given)
            a = res.angle_min + res.angle_increment * np.arange(len(res.ranges))
            ahead = np.abs(a) < AHEAD
            cliff = res.cliff_ranges[ahead]
            first = EDGE / np.cos(a[ahead]) * (HEIGHT + STEP) / HEIGHT
            ok = np.isfinite(cliff)
            found.append(ok.mean())
            errors.extend(np.abs(cliff[ok] - first[ok]).tolist())
            rim = EDGE / np.cos(a[ahead])
            stops.append(bool((res.ranges[ahead] < rim + 0.5).any()))
            fl = render_frame(cam, Scene(), HEIGHT, TILT + bp, 0.0, encoding, seed=1000 + seed + i, tof=True)
            fres = flat_pipe.process(fl.depth, given)
            fire = np.isfinite(fres.cliff_ranges)
            false_beams.append(fire.mean())
            false_frames.append(bool(fire.any()))
        rows.append(
            CliffRow(
                condition=cond,
                pipeline=name,
                stair_beams_found=100.0 * float(np.mean(found)),
                stair_error_cm=100.0 * float(np.median(errors)) if errors else math.nan,
                stop_before_edge=100.0 * float(np.mean(stops)),
                flat_false_beams=100.0 * float(np.mean(false_beams)),
                flat_false_frames=100.0 * float(np.mean(false_frames)),
            )
        )
    return rows


def table(rows: list[CliffRow]) -> str:
    out = [
        "| base pitch | pipeline | stair beams found % | stair range error (median) [cm] | frames with a beam "
        "ahead stopping before the edge % | flat floor: false cliff beams % "
        "| flat floor: frames with a false cliff % |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r.condition} | {r.pipeline} | {r.stair_beams_found:.1f} | {r.stair_error_cm:.1f} | "
            f"{r.stop_before_edge:.0f} | {r.flat_false_beams:.2f} | {r.flat_false_frames:.0f} |"
        )
    return "\n".join(out)


def picture(out_dir: Path, encoding: str = "16UC1") -> list[Path]:
    """Labels of a stair down and of a hole (below floor in its own colour) and their scans seen from above."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cam = kinect_v2_camera()
    cfg = _core.Config(sensor_height=HEIGHT, sensor_pitch=TILT)
    paths = []
    for name, scene in (("stair", stair_scene(EDGE, STEP)), ("hole", hole_scene())):
        f = render_frame(cam, scene, HEIGHT, TILT, 0.0, encoding, seed=1, tof=True)
        res = _core.Pipeline(cam, cfg).process(f.depth)
        p = out_dir / f"cliff_{name}_labels.png"
        plot_frame(f.depth, res, cfg.max_depth, p, f"{name}: below-floor pixels feed the cliff scan")
        paths.append(p)
        a = res.angle_min + res.angle_increment * np.arange(len(res.ranges))
        fig, ax = plt.subplots(figsize=(6, 6))
        for r, colour, label in (
            (res.ranges, "tab:blue", "scan (obstacles)"),
            (res.cliff_ranges, "tab:red", "cliff_scan"),
        ):
            ok = np.isfinite(r)
            ax.scatter(r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok]), s=4, c=colour, label=label)
        for x0, x1, y0, y1 in scene.holes:
            x1, y0, y1 = min(x1, 5.0), max(y0, -3.0), min(y1, 3.0)
            ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ls="--", color="tab:red"))
        for b in scene.boxes:
            ax.add_patch(plt.Rectangle((b[0], b[2]), b[1] - b[0], b[3] - b[2], fill=False, color="tab:blue"))
        ax.plot([0], [0], "k^", ms=10, label="sensor")
        ax.set_xlim(-0.2, 5.0)
        ax.set_ylim(-2.6, 2.6)
        ax.set_aspect("equal")
        ax.grid(True)
        ax.set_xlabel("x forward [m]")
        ax.set_ylabel("y left [m]")
        ax.set_title(f"{name}: dashed = floor missing (truth)")
        ax.legend(loc="upper left")
        p = out_dir / f"cliff_{name}_scan.png"
        save_figure(fig, p)
        plt.close(fig)
        paths.append(p)
    return paths
