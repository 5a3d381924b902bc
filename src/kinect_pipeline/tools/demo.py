"""The bundled default job: a synthetic Segway sequence through the pipeline, with pictures and numbers."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core, kinect_v2_camera
from ..evaluation.metrics import FrameQuality, frame_quality
from ..figures import plot_frame
from ..outputs import progress, save_figure, write_text
from ..simulation.robot import SegwayMotion
from ..simulation.scenes import Frame, Scene, ideal_scan, lab_scene, render_frame


def plot_scan(frame: Frame, res: _core.Result, path: Path, title: str) -> None:
    """Top view of the Kinect scan over the true nearest obstacle per beam, 1 m grid (thesis fig 4.20b)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(res.ranges)
    angles = res.angle_min + res.angle_increment * np.arange(n)
    truth = frame.truth
    real = ideal_scan(truth, res.angle_min, res.angle_increment, n, (truth["object"] >= 10) & (truth["height"] < 2.0))
    fig, ax = plt.subplots(figsize=(7, 7))
    ok = np.isfinite(real)
    ax.scatter(
        real[ok] * np.cos(angles[ok]), real[ok] * np.sin(angles[ok]), s=10, c="tab:cyan", label="true nearest obstacle"
    )
    r = res.ranges
    ok = np.isfinite(r)
    sc = ax.scatter(
        r[ok] * np.cos(angles[ok]),
        r[ok] * np.sin(angles[ok]),
        s=4,
        c=res.intensities[ok],
        cmap="autumn",
        vmin=0,
        vmax=1,
        label="Kinect scan (colour: confidence)",
    )
    fig.colorbar(sc, ax=ax, shrink=0.7, label="intensity (confidence)")
    ax.plot([0], [0], "k^", markersize=10, label="robot")
    ax.set_xlim(-0.5, 7)
    ax.set_ylim(-3.75, 3.75)
    ax.set_xticks(np.arange(0, 8))
    ax.set_yticks(np.arange(-3, 4))
    ax.grid(True, color="0.8")
    ax.set_aspect("equal")
    ax.set_xlabel("x forward [m]")
    ax.set_ylabel("y left [m]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title)
    save_figure(fig, path)
    plt.close(fig)


def run_demo(
    out: Path,
    frames: int = 40,
    encoding: str = "8UC1",
    seed: int = 1,
    sensor_height: float = 1.1,
    sensor_pitch: float = math.radians(15.0),
    scene: Scene | None = None,
) -> dict[str, Any]:
    """Renders a seeded Segway sequence, runs the pipeline on every frame at the known pose, writes
    ``frame.png``, ``scan.png`` and ``quality.json`` into ``out`` and returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    cam = kinect_v2_camera()
    scene = scene or lab_scene()
    cfg = _core.Config(sensor_height=sensor_height, sensor_pitch=sensor_pitch)
    pipe = _core.Pipeline(cam, cfg)
    motion = SegwayMotion()
    qualities: list[FrameQuality] = []
    times: list[float] = []
    worst: tuple[float, int, Frame, Any] | None = None
    for i in progress(range(frames), frames, "demo"):
        base_pitch = motion.pitch(i)
        frame = render_frame(cam, scene, sensor_height, sensor_pitch + base_pitch, 0.0, encoding, seed + i)
        res = pipe.process(frame.depth, base_pitch, 0.0)
        q = frame_quality(res, frame, cfg.ceiling_height)
        qualities.append(q)
        times.append(res.times["total"])
        score = abs(base_pitch)
        if worst is None or score > worst[0]:
            worst = (score, i, frame, res)
    assert worst is not None
    _, wi, wframe, wres = worst
    title = f"frame {wi}: base pitch {math.degrees(motion.pitch(wi)):+.1f} deg, {encoding}"
    plot_frame(wframe.depth, wres, cfg.max_depth, out / "frame.png", title)
    plot_scan(wframe, wres, out / "scan.png", title)

    def agg(name: str, fn: Any) -> float:
        vals = [getattr(q, name) for q in qualities]
        vals = [v for v in vals if not math.isnan(v)]
        return float(fn(vals)) if vals else float("nan")

    summary = {
        "frames": frames,
        "encoding": encoding,
        "sensor_height": sensor_height,
        "sensor_pitch": sensor_pitch,
        "floor_removed_min": agg("floor_removed", min),
        "obstacles_kept_min": agg("obstacles_kept", min),
        "above_ceiling_removed_min": agg("above_ceiling_removed", min),
        "phantom_beams_max": agg("phantom_beams", max),
        "ms_per_frame_median": float(np.median(times)),
        "pictures": ["frame.png", "scan.png"],
    }
    write_text(
        out / "quality.json", json.dumps({"summary": summary, "frames": [q.as_dict() for q in qualities]}, indent=1)
    )
    return summary
