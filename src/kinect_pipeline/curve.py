"""Threshold-curve design from data: ``kinect-pipeline curve FILE... --intrinsics FX FY CX CY``.

From frames of a flat floor: calibrate the pose (core), take each floor pixel's depth residual against the floor
the core predicts at that pose, fit the noise sigma(d) = a + b (d - 0.4)^2 to robust per-depth spreads, and make
t(d) = k sigma(d) + margin with k set by the chosen false-obstacle rate (the chance that a floor pixel reads
nearer than t). Also a curve from a noise model alone, for users without data."""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist
from typing import Any

import numpy as np

from . import _core
from .calibrate import calibrate

DEPTHS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0)


@dataclass
class CurveFit:
    sigma0: float
    k_quad: float
    k: float
    margin: float
    points: list[tuple[float, float]]
    bins: list[tuple[float, float, int]] = field(default_factory=list)  # depth, robust sigma, samples
    residuals: tuple[np.ndarray, np.ndarray] | None = None  # depth, residual (a subsample)
    pose: tuple[float, float, float] | None = None

    @property
    def text(self) -> str:
        return ", ".join(f"{d:g}:{t:.4f}" for d, t in self.points)


def curve_from_model(
    sigma0: float, k_quad: float, false_obstacle_rate: float, margin: float, depths: tuple[float, ...] = DEPTHS
) -> CurveFit:
    k = NormalDist().inv_cdf(1.0 - false_obstacle_rate)
    pts, last = [], 0.0
    for d in depths:
        t = k * float(_core.kinect_sigma(d, sigma0, k_quad)) + margin
        last = max(last, t)  # never decreasing: the pipeline refuses such a curve
        pts.append((d, round(last, 4)))
    return CurveFit(sigma0, k_quad, k, margin, pts)


def fit_curve(
    frames: list[tuple[str, np.ndarray]],
    camera: _core.Camera,
    false_obstacle_rate: float = 1e-3,
    margin: float = 0.01,
    bin_width: float = 0.25,
    min_samples: int = 50,
) -> CurveFit:
    cal = calibrate(frames, camera)
    if not cal.found:
        raise ValueError(f"curve: {cal.message}")
    pipe = _core.Pipeline(camera, _core.Config(open_kernel_size=0))
    depths, residuals = [], []
    for _, metres in frames:
        pipe.process_pose(metres, cal.height, cal.pitch, cal.roll)
        zf = pipe.predicted_floor()
        ok = np.isfinite(zf) & (metres > 0) & (zf < 12.0)
        r = (metres - zf)[ok]
        d = zf[ok]
        # Floor pixels: within a generous band of the prediction (5 sigma of a pessimistic model, >= 10 cm).
        band = np.maximum(0.10, 5 * _core.kinect_sigma(d, 0.003, 0.004))
        keep = np.abs(r) < band
        depths.append(d[keep])
        residuals.append(r[keep])
    d_all = np.concatenate(depths)
    r_all = np.concatenate(residuals)
    if len(d_all) < 500:
        raise ValueError(f"curve: only {len(d_all)} floor pixels: expected at least 500")
    sigma0, k_quad = 0.003, 0.004
    bins: list[tuple[float, float, int]] = []
    for _ in range(3):
        # Re-select the floor with the last fit (4 sigma): clutter lying on the floor drops out.
        keep = np.abs(r_all) < np.maximum(0.02, 4 * _core.kinect_sigma(d_all, sigma0, k_quad))
        d, r = d_all[keep], r_all[keep]
        bins = []
        for lo in np.arange(0.0, 12.0, bin_width):
            m = (d >= lo) & (d < lo + bin_width)
            if m.sum() >= min_samples:
                x = r[m]
                sigma = 1.4826 * float(np.median(np.abs(x - np.median(x))))
                bins.append((lo + bin_width / 2, sigma, int(m.sum())))
        if len(bins) < 2:
            raise ValueError("curve: the floor spans fewer than two depth bins: need floor at more depths")
        bd = np.array([b[0] for b in bins])
        bs = np.array([b[1] for b in bins])
        bw = np.sqrt(np.array([b[2] for b in bins], float))
        a = np.stack([np.ones_like(bd), (bd - 0.4) ** 2], axis=1)
        coef, *_ = np.linalg.lstsq(a * bw[:, None], bs * bw, rcond=None)
        sigma0, k_quad = max(float(coef[0]), 1e-4), max(float(coef[1]), 0.0)
    fit = curve_from_model(sigma0, k_quad, false_obstacle_rate, margin)
    fit.bins = bins
    sub = np.random.default_rng(0).choice(len(d), size=min(len(d), 20000), replace=False)
    fit.residuals = (d[sub], r[sub])
    fit.pose = (cal.height, cal.pitch, cal.roll)
    return fit


def write_yaml(fit: CurveFit, path: Path) -> None:
    """dynamic_reconfigure / rosparam YAML with the curve (written atomically)."""
    text = (
        f"# kinect-pipeline curve: sigma(d) = {fit.sigma0:.5f} + {fit.k_quad:.5f} (d - 0.4)^2, "
        f't = {fit.k:.2f} sigma + {fit.margin:g}\nthreshold_curve: "{fit.text}"\n'
    )
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def plot(fit: CurveFit, current: list[tuple[float, float]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .demo import _save_atomic

    fig, ax = plt.subplots(figsize=(8, 5))
    if fit.residuals is not None:
        ax.scatter(fit.residuals[0], fit.residuals[1], s=1, c="0.6", alpha=0.4, label="floor residuals z - z_floor")
    if fit.bins:
        ax.plot([b[0] for b in fit.bins], [b[1] for b in fit.bins], "k.", label="robust sigma per depth")
    for pts, style, name in ((fit.points, "b-", "fitted t(d)"), (current, "r--", "current t(d)")):
        x = [p[0] for p in pts]
        y = [p[1] for p in pts]
        ax.plot(x, y, style, label=name)
        ax.plot(x, [-v for v in y], style)
    ax.set_xlabel("depth [m]")
    ax.set_ylabel("residual / threshold [m]")
    ax.set_xlim(0, 8)
    ax.set_ylim(-0.6, 0.6)
    ax.grid(True, color="0.85")
    ax.legend(fontsize=8)
    ax.set_title(f"threshold curve: k = {fit.k:.2f}, margin {fit.margin:g} m")
    _save_atomic(fig, path)
    plt.close(fig)


def set_live(node: str, fit: CurveFit, timeout: float = 5.0) -> dict[str, Any]:
    """Sets the curve on a running node through dynamic_reconfigure."""
    from dynamic_reconfigure.client import Client

    client = Client(node, timeout=timeout)
    return dict(client.update_configuration({"threshold_curve": fit.text}))


def describe(fit: CurveFit) -> str:
    lines = [
        f"sigma(d) = {1000 * fit.sigma0:.2f} mm + {1000 * fit.k_quad:.2f} mm (d - 0.4 m)^2; "
        f"t = {fit.k:.2f} sigma + {fit.margin:g} m"
    ]
    if fit.pose:
        lines.append(
            f"pose: height {fit.pose[0]:.3f} m, pitch {math.degrees(fit.pose[1]):+.2f} deg, "
            f"roll {math.degrees(fit.pose[2]):+.2f} deg"
        )
    lines.append(f'threshold_curve: "{fit.text}"')
    return "\n".join(lines)
