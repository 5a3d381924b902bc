"""Threshold-curve design from data: ``kinect-pipeline curve FILE... --intrinsics FX FY CX CY``.

From frames of a flat floor: calibrate the pose (core), take each floor pixel's depth residual against the floor
the core predicts at that pose, fit the noise sigma(d) = a + b (d - 0.4)^2 to robust per-depth spreads, and make
t(d) = k sigma(d) + margin with k set by the chosen false-obstacle rate (the chance that a floor pixel reads
nearer than t). Also a curve from a noise model alone, for users without data."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from statistics import NormalDist
from typing import Any

import numpy as np

from .. import _core
from ..outputs import write_text
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
    false_obstacle_rate: float = 1e-4,
    margin: float = 0.01,
    bin_width: float = 0.25,
    min_samples: int = 50,
) -> CurveFit:
    cal = calibrate(frames, camera)
    if not cal.found:
        raise ValueError(f"curve: {cal.message}")
    # Residuals against the calibrated plane itself: no floor profile learned from the frames being measured.
    pipe = _core.Pipeline(camera, _core.Config(open_kernel_size=0, floor_profile_max=0.0))
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
    write_text(path, text)


def plot(fit: CurveFit, current: list[tuple[float, float]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..outputs import save_figure

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
    save_figure(fig, path)
    plt.close(fig)


def set_live(node: str, fit: CurveFit, timeout: float = 10.0) -> dict[str, Any]:
    """Sets the curve on a running node through dynamic_reconfigure; returns the configuration the node reports.
    A node that is not there, or that refuses the curve, raises ValueError."""
    import rosgraph
    import rospy
    from dynamic_reconfigure.client import Client

    if not rosgraph.is_master_online():
        raise ValueError(f"--set-node {node}: no ROS master at {rosgraph.get_master_uri()}")
    if not rospy.core.is_initialized():
        rospy.init_node("kinect_pipeline_curve", anonymous=True, disable_signals=True)
    try:
        client = Client(node, timeout=timeout)
    except rospy.ROSException as exc:
        raise ValueError(
            f"--set-node {node}: no dynamic_reconfigure server there within {timeout:g} s ({exc})"
        ) from exc
    try:
        got = dict(client.update_configuration({"threshold_curve": fit.text}))
    finally:
        client.close()
    now = got.get("threshold_curve", "")
    try:
        same = (
            _core.Config(threshold_curve=now).threshold_curve == _core.Config(threshold_curve=fit.text).threshold_curve
        )
    except ValueError:
        same = False
    if not same:
        raise ValueError(f"--set-node {node}: the node kept threshold_curve {now!r} instead of {fit.text!r}")
    return got


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


# -- the fitted curve against a constant margin, on generated noisy frames ------------------------------------


@dataclass
class CurveScore:
    """What a threshold curve does on the generated frames (fractions in [0, 1])."""

    name: str
    curve: str  #: threshold_curve text
    false_obstacle: float  #: floor pixels (true range < 8 m) kept as obstacles
    phantom: float  #: beams shorter than the nearest true obstacle by > 5 cm + 4 sigma (kept floor, noise allowed)
    removed: tuple[float, ...]  #: obstacle pixels removed, per height class (5-10 cm, 10-30 cm, 0.3-2 m)


@dataclass
class _Rendered:
    depth: np.ndarray
    base_pitch: float
    floor: np.ndarray
    classes: list[np.ndarray]
    obstacle: np.ndarray
    truth: dict[str, np.ndarray]


def render_noisy_frames(frames: int = 12, encoding: str = "16UC1", seed: int = 31) -> list[_Rendered]:
    """The quality table's lab scene on the pitching Segway (Kinect v2 noise, dropouts, flying pixels, 8 m range)."""
    from .. import kinect_v2_camera
    from ..evaluation.quality import CONDITIONS, HEIGHT, HEIGHT_CLASSES, TILT
    from ..simulation.scenes import FIRST_BOX, FLOOR, lab_scene, render_frame

    cam = kinect_v2_camera()
    out = []
    for i in range(frames):
        bp = CONDITIONS["oscillating"](i * 7)
        f = render_frame(cam, lab_scene(), HEIGHT, TILT + bp, 0.0, encoding, seed + i, tof=True)
        t = f.truth
        obj, height, rng = t["object"], t["height"], t["range"]
        obstacle = (obj >= FIRST_BOX) & (height <= 2.0)
        classes = [obstacle & (height >= lo) & (height < hi) for lo, hi in HEIGHT_CLASSES]
        out.append(_Rendered(f.depth, bp, (obj == FLOOR) & (rng < 8.0), classes, obstacle, t))
    return out


def score_curve(name: str, curve: str, rendered: list[_Rendered]) -> CurveScore:
    """Runs the pipeline (default config, this threshold curve, the base pitch given) over the rendered frames."""
    from .. import kinect_v2_camera
    from ..evaluation.quality import HEIGHT, TILT, phantom_rates

    pipe = _core.Pipeline(
        kinect_v2_camera(), _core.Config(sensor_height=HEIGHT, sensor_pitch=TILT, threshold_curve=curve)
    )
    floor_kept = floor_n = 0
    removed = np.zeros(len(rendered[0].classes))
    counts = np.zeros(len(rendered[0].classes))
    phantom = []
    for r in rendered:
        res = pipe.process(r.depth, r.base_pitch, 0.0)
        kept = res.labels == _core.LABELS["kept"]
        floor_kept += int((kept & r.floor).sum())
        floor_n += int(r.floor.sum())
        for k, m in enumerate(r.classes):
            removed[k] += int((m & ~kept).sum())
            counts[k] += int(m.sum())
        phantom.append(phantom_rates(r.truth, res.ranges, res.angle_min, res.angle_increment, r.obstacle)[1])
    return CurveScore(
        name,
        curve,
        floor_kept / max(floor_n, 1),
        float(np.mean(phantom)),
        tuple(float(x) for x in removed / np.maximum(counts, 1)),
    )


def constant_curve(margin: float) -> str:
    return f"0.5:{margin:.4f}, 12:{margin:.4f}"


def _match_constant(
    rendered: list[_Rendered], target: float, key: str, lo: float = 0.002, hi: float = 1.5, steps: int = 14
) -> tuple[CurveScore, CurveScore | None]:
    """The smallest constant margin whose ``key`` (false_obstacle or phantom) is at most ``target``, and the largest
    one tried whose ``key`` is above it (bisection: both rates fall as the margin grows)."""
    best = score_curve("", constant_curve(hi), rendered)
    below: CurveScore | None = None
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        s = score_curve("", constant_curve(mid), rendered)
        if getattr(s, key) <= target:
            hi, best = mid, s
        else:
            lo, below = mid, s
    return best, below


@dataclass
class Comparison:
    fitted: CurveScore
    same_rate: CurveScore  #: the smallest constant with a false-obstacle rate <= the fitted curve's
    same_phantom: CurveScore  #: the smallest constant with a phantom-beam rate <= the fitted curve's
    more_phantom: CurveScore | None  #: the largest constant tried with more phantom beams than the fitted curve
    default: CurveScore

    def rows(self) -> list[CurveScore]:
        return [self.fitted, self.same_rate, self.same_phantom, self.default]


def compare_with_constant(fit: CurveFit, frames: int = 12, encoding: str = "16UC1", seed: int = 31) -> Comparison:
    """The fitted curve, the constant margins with the same false-obstacle rate and with the same phantom-beam rate,
    and the current default curve, scored on the same generated noisy frames."""
    if not isinstance(fit, CurveFit):
        raise TypeError(f"fit: {type(fit).__name__}, expected CurveFit")
    if isinstance(frames, bool) or not isinstance(frames, int):
        raise TypeError(f"frames: {type(frames).__name__}, expected int")
    if frames < 1:
        raise ValueError(f"frames = {frames}: expected >= 1")
    rendered = render_noisy_frames(frames, encoding, seed)
    fitted = score_curve("fitted t(d)", fit.text, rendered)
    same_rate, _ = _match_constant(rendered, fitted.false_obstacle, "false_obstacle")
    same_rate.name = "constant, same false-obstacle rate"
    same_phantom, more = _match_constant(rendered, fitted.phantom, "phantom")
    same_phantom.name = "constant, same phantom-beam rate"
    default = ", ".join(f"{d:g}:{t:g}" for d, t in _core.Config().threshold_curve)
    return Comparison(fitted, same_rate, same_phantom, more, score_curve("current default", default, rendered))


def generated_floor_frames(n: int = 3, scene: Any = None) -> list[tuple[str, np.ndarray]]:
    """Rendered Kinect v2 frames (float metres, 0 = unknown) of a floor seen from 1.1 m at 17 deg, for fitting."""
    from .. import kinect_v2_camera
    from ..simulation.scenes import Scene, render_frame

    out = []
    for i in range(n):
        f = render_frame(kinect_v2_camera(), scene or Scene(), 1.1, 0.3, 0.0, "32FC1", seed=60 + i)
        m = f.metres.astype(np.float32)
        m[~np.isfinite(m)] = 0
        out.append((f"generated floor {i}", np.ascontiguousarray(m)))
    return out


def comparison_table(scores: list[CurveScore]) -> str:
    lines = [
        "| threshold curve | t at 1 / 2 / 4 / 6 m [cm] | floor kept as obstacle % | phantom beams % "
        "| removed 5–10 cm % | removed 10–30 cm % | removed 0.3–2 m % |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in scores:
        t = " / ".join(f"{100 * _core.evaluate_curve(s.curve, d):.1f}" for d in (1.0, 2.0, 4.0, 6.0))
        rem = " | ".join(f"{100 * x:.2f}" for x in s.removed)
        lines.append(f"| {s.name} | {t} | {100 * s.false_obstacle:.3f} | {100 * s.phantom:.2f} | {rem} |")
    return "\n".join(lines)


def plot_comparison(scores: list[CurveScore], path: Path) -> None:
    """Left: the curves against depth; right: obstacle pixels removed per height class, floor kept, phantoms."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..outputs import save_figure

    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    d = np.linspace(0.5, 8.0, 200)
    styles = ["b-", "r--", "m:", "0.5"]
    for s, st in zip(scores, styles, strict=False):
        a.plot(d, 100 * _core.evaluate_curve(s.curve, d), st, label=s.name)
    a.set_xlabel("depth [m]")
    a.set_ylabel("threshold t(d) [cm]")
    a.set_ylim(0, 60)
    a.grid(True, color="0.85")
    a.legend(fontsize=8)
    a.set_title("threshold curves")
    groups = ["removed\n5–10 cm", "removed\n10–30 cm", "floor kept\nas obstacle", "phantom\nbeams"]
    x = np.arange(len(groups))
    w = 0.8 / len(scores)
    colors = ["tab:blue", "tab:red", "tab:purple", "0.6"]
    for i, s in enumerate(scores):
        vals = [100 * s.removed[0], 100 * s.removed[1], 100 * s.false_obstacle, 100 * s.phantom]
        bars = b.bar(x + (i - (len(scores) - 1) / 2) * w, vals, w, label=s.name, color=colors[i % len(colors)])
        b.bar_label(bars, fmt="%.3g", fontsize=6, rotation=90, padding=2)
    b.set_xticks(x, groups)
    b.set_ylabel("%")
    b.set_yscale("symlog", linthresh=0.1)
    b.set_ylim(0, 400)
    b.grid(True, axis="y", color="0.85")
    b.set_title("on generated noisy frames (Segway pitching)")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
