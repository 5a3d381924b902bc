"""The bundled default job: a synthetic Segway sequence through the pipeline, with pictures and numbers."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import _core, kinect_v2_camera
from .metrics import FrameQuality, frame_quality, ideal_scan
from .outputs import save_figure, write_text
from .scenes import Frame, Scene, lab_scene, render_frame


@dataclass
class SegwayMotion:
    """Base pitch of a Segway driving: a slow oscillation plus a jerk (a sudden stop) [rad]."""

    amplitude: float = math.radians(4.0)
    period_frames: float = 45.0
    jerk_frame: int = 20
    jerk: float = math.radians(6.0)

    def pitch(self, i: int) -> float:
        p = self.amplitude * math.sin(2 * math.pi * i / self.period_frames)
        if i >= self.jerk_frame:
            p += self.jerk * math.exp(-(i - self.jerk_frame) / 3.0) * math.cos((i - self.jerk_frame) * 1.3)
        return max(-math.radians(6.0), min(math.radians(6.0), p))


def progress(items: Iterable[Any], total: int, desc: str) -> Iterator[Any]:
    """A tqdm progress bar with frames/s when tqdm is there and stderr is a terminal or CI log."""
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is in requirements.txt
        yield from items
        return
    yield from tqdm(items, total=total, desc=desc, unit="frame", dynamic_ncols=True, mininterval=0.5)


def to_metres(depth: np.ndarray, max_depth: float) -> np.ndarray:
    """Encoded depth -> float metres for display (unknown and removed values -> NaN)."""
    if depth.dtype == np.uint8:
        m = depth.astype(np.float32) / 255.0 * max_depth
        m[(depth < 2) | (depth == 255)] = np.nan
    elif depth.dtype == np.uint16:
        m = depth.astype(np.float32) / 1000.0
        m[depth == 0] = np.nan
    else:
        m = depth.astype(np.float32).copy()
        m[~np.isfinite(m) | (m <= 0)] = np.nan
    return m


def plot_frame(depth: np.ndarray, res: _core.Result, max_depth: float, path: Path, title: str) -> None:
    """Raw depth (the encoded input), cleaned depth and labels side by side (thesis figs 4.11, 4.17a/b)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    raw = to_metres(depth, max_depth)
    clean = to_metres(res.depth, max_depth)
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
    for a, img, name in ((ax[0], raw, "raw depth"), (ax[1], clean, "cleaned depth (for the human detector)")):
        im = a.imshow(img, cmap="viridis", vmin=0, vmax=min(max_depth, 8.0))
        a.set_title(name)
        a.axis("off")
    fig.colorbar(im, ax=ax[:2].tolist(), shrink=0.8, label="depth [m]")
    ax[2].imshow(_core.colour_labels(res.depth, res.labels, max_depth))
    ax[2].set_title("labels")
    ax[2].axis("off")
    names = {1: "invalid", 2: "floor", 3: "above ceiling plane", 4: "below floor"}
    ax[2].legend(
        handles=[
            Patch(
                color=np.array(_core.colour_labels(np.zeros((1, 1), np.uint16), np.full((1, 1), k, np.uint8)))[0, 0]
                / 255,
                label=v,
            )
            for k, v in names.items()
        ]
        + [Patch(color="0.6", label="kept")],
        loc="lower center",
        bbox_to_anchor=(0.5, -0.22),
        ncol=3,
        fontsize=8,
    )
    fig.suptitle(title)
    save_figure(fig, path)
    plt.close(fig)


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
