"""Pose calibration from frames of a flat floor: ``kinect-pipeline calibrate FILE... --intrinsics FX FY CX CY``.

The plane search and fit are the C++ core's (``calibrate_from_floor``); this module loads frames and reports."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core


class CalibrationError(ValueError):
    """A frame that cannot be read or used; the message names it."""


#: What a folder of depth frames is read for (in name order).
FRAME_SUFFIXES = (".png", ".pgm", ".npy", ".tif", ".tiff")


def frame_paths(items: list[Path]) -> list[Path]:
    """The depth frames named: files as they are, folders as the frames in them (``FRAME_SUFFIXES``, in name
    order). A folder without frames raises CalibrationError naming it."""
    out: list[Path] = []
    for item in items:
        if item.is_dir():
            found = sorted(p for p in item.iterdir() if p.suffix.lower() in FRAME_SUFFIXES and p.is_file())
            if not found:
                raise CalibrationError(f"{item}: a folder without depth frames ({', '.join(FRAME_SUFFIXES)})")
            out.extend(found)
        else:
            out.append(item)
    return out


def is_frames(items: list[Path]) -> bool:
    """Whether ``items`` name depth frames (files with a frame suffix, or folders of them) rather than a bag."""
    for item in items:
        if item.is_dir():
            if (item / "metadata.yaml").exists():
                return False
        elif item.suffix.lower() not in FRAME_SUFFIXES:
            return False
    return bool(items)


def load_depth(path: Path, depth_scale: float = 0.001, max_depth: float = 12.0) -> np.ndarray:
    """A depth frame as float32 metres (0 = unknown): 16-bit PNG/PGM (``depth_scale`` metres per unit, mm by
    default), 8-bit PNG (normalised with ``max_depth``), or .npy (float metres, uint16 mm, uint8 normalised)."""
    path = Path(path)
    if not path.exists():
        raise CalibrationError(f"{path}: no such file")
    if path.suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as exc:
            raise CalibrationError(f"{path}: not a numpy array file ({exc})") from exc
    else:
        import cv2

        arr = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if arr is None:
            raise CalibrationError(f"{path}: not an image OpenCV can read")
    if arr.ndim != 2:
        raise CalibrationError(f"{path}: shape {arr.shape}: expected a single-channel depth image")
    return depth_metres(arr, depth_scale, max_depth, str(path))


def depth_metres(
    arr: np.ndarray, depth_scale: float = 0.001, max_depth: float = 12.0, name: str = "depth"
) -> np.ndarray:
    """A depth array as contiguous float32 metres, 0 = unknown: uint16 (``depth_scale`` m per unit), uint8
    (normalised with ``max_depth``, v < 2 unknown) or float (m)."""
    if arr.dtype == np.uint16:
        metres = arr.astype(np.float32) * np.float32(depth_scale)
    elif arr.dtype == np.uint8:
        metres = arr.astype(np.float32) * np.float32(max_depth / 255.0)
        metres[arr < 2] = 0.0
    elif arr.dtype.kind == "f":
        metres = arr.astype(np.float32)
    else:
        raise CalibrationError(f"{name}: dtype {arr.dtype}: expected uint16 (mm), uint8 (normalised) or float (m)")
    metres[~np.isfinite(metres)] = 0.0
    return np.ascontiguousarray(metres)


@dataclass
class Calibration:
    found: bool
    height: float
    pitch: float
    roll: float
    floor_fraction: float
    height_std: float
    pitch_std: float
    roll_std: float
    frames: list[dict[str, Any]]
    message: str = ""
    warnings: list[str] = field(default_factory=list)  #: frames that disagree, a weak fit

    def as_dict(self, parent: str = "base_footprint", child: str = "kinect2_depth_optical_frame") -> dict[str, Any]:
        d: dict[str, Any] = {
            "found": self.found,
            "height": self.height,
            "pitch": self.pitch,
            "roll": self.roll,
            "floor_fraction": self.floor_fraction,
            "height_std": self.height_std,
            "pitch_std": self.pitch_std,
            "roll_std": self.roll_std,
            "pitch_deg": math.degrees(self.pitch),
            "roll_deg": math.degrees(self.roll),
            "frames": self.frames,
        }
        if self.message:
            d["message"] = self.message
        d["warnings"] = list(self.warnings)
        if self.found:
            d["launch_args"] = (
                f"sensor_height:={self.height:.4f} sensor_pitch:={self.pitch:.5f} sensor_roll:={self.roll:.5f} "
                "pose_source:=static"
            )
            d["yaml"] = {
                "sensor_height": round(self.height, 4),
                "sensor_pitch": round(self.pitch, 5),
                "sensor_roll": round(self.roll, 5),
            }
            q = optical_quaternion(self.pitch, self.roll)
            d["static_transform"] = (
                f"rosrun tf2_ros static_transform_publisher 0 0 {self.height:.4f} "
                f"{q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f} {parent} {child}"
            )
        return d


def plot_calibration(metres: np.ndarray, camera: _core.Camera, result: Calibration, path: Path, name: str) -> None:
    """The frame's depth and, under the calibrated pose, the floor the pipeline then removes (green): where the
    calibration is right, the floor is green up to the walls and nothing stands on it."""
    from ..figures import plot_frame

    cfg = _core.Config(
        sensor_height=result.height,
        sensor_pitch=result.pitch,
        sensor_roll=result.roll,
        ceiling_height=max(3.0, result.height + 0.5),
    )
    depth = np.where(np.isfinite(metres), metres, 0.0).astype(np.float32)
    res = _core.Pipeline(camera, cfg).process(depth)
    plot_frame(
        depth,
        res,
        cfg.max_depth,
        path,
        f"{name}: height {result.height:.3f} m, pitch {math.degrees(result.pitch):+.2f} deg, "
        f"roll {math.degrees(result.roll):+.2f} deg, floor {100 * result.floor_fraction:.0f} % of the pixels",
    )


def optical_quaternion(pitch: float, roll: float) -> tuple[float, float, float, float]:
    """The optical frame's orientation (x, y, z, w) in a z-up base frame for a sensor at pitch / roll."""
    body = (tuple(_core.quaternion_from_rpy(roll, pitch, 0.0)), (0.0, 0.0, 0.0))
    optical = _core.compose_transforms(body, ((-0.5, 0.5, -0.5, 0.5), (0.0, 0.0, 0.0)))
    q = optical[0]
    return (q[0], q[1], q[2], q[3])


def calibrate(frames: list[tuple[str, np.ndarray]], camera: _core.Camera, **options: Any) -> Calibration:
    """Calibrates from one or more (name, metres) frames; several frames give a mean and a spread."""
    per: list[dict[str, Any]] = []
    for name, metres in frames:
        if metres.shape != (camera.height, camera.width):
            raise CalibrationError(
                f"{name}: {metres.shape[1]}x{metres.shape[0]} but the intrinsics are for "
                f"{camera.width}x{camera.height} (give --size W H if the principal point is off)"
            )
        r = dict(_core.calibrate_from_floor(metres, camera, **options))
        r["file"] = name
        per.append(r)
    good = [r for r in per if r["found"]]
    if not good:
        return Calibration(
            False,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            per,
            f"no floor found in {len(per)} frame(s): no plane facing up with enough pixels",
        )
    w = np.array([r["floor_pixels"] for r in good], float)

    def mean(key: str) -> float:
        return float(np.average([r[key] for r in good], weights=w))

    def spread(key: str) -> float:
        fit = float(np.sqrt(np.mean([r[f"{key}_std"] ** 2 for r in good])) / math.sqrt(len(good)))
        between = float(np.std([r[key] for r in good], ddof=1) / math.sqrt(len(good))) if len(good) > 1 else 0.0
        return max(fit, between)

    return Calibration(
        True,
        mean("height"),
        mean("pitch"),
        mean("roll"),
        mean("floor_fraction"),
        spread("height"),
        spread("pitch"),
        spread("roll"),
        per,
        warnings=disagreement(good) + weak_fits(good),
    )


#: How far the frames averaged may disagree before a warning, beyond their fits' own uncertainty (3 sigma):
#: a robot standing still sees one pose; hand-held frames or a base that moved give several.
DISAGREE = {"height": (0.01, "m", 1.0), "pitch": (math.radians(0.5), "deg", 180 / math.pi)}
DISAGREE["roll"] = (math.radians(0.5), "deg", 180 / math.pi)


def disagreement(good: list[dict[str, Any]]) -> list[str]:
    """Warnings for pose terms whose frames disagree by more than DISAGREE and 3 sigma of their fits."""
    out = []
    for key, (limit, unit, k) in DISAGREE.items():
        v = [r[key] for r in good]
        if len(v) < 2:
            continue
        span, fit = max(v) - min(v), 3 * max(r[f"{key}_std"] for r in good)
        if span > max(limit, fit):
            fmt, fine = ("{:.3f}", "{:.4f}") if unit == "m" else ("{:.1f}", "{:.2f}")
            out.append(
                f"the {len(v)} frames disagree: {key} spans {fmt.format(k * min(v))}..{fmt.format(k * max(v))} "
                f"{unit} (each fit is within {fine.format(k * fit / 3)} {unit}): was the sensor moving? the mean is "
                "no frame's pose; calibrate from frames of the robot standing still"
            )
    return out


#: A fit is weak with less floor than this fraction of the valid pixels, fewer floor pixels, or a looser plane.
WEAK_FRACTION, WEAK_PIXELS, WEAK_RMS = 0.10, 2000, 0.03


def weak_fits(good: list[dict[str, Any]]) -> list[str]:
    """Warnings for frames whose floor is small, thin or far from flat."""
    out = []
    for r in good:
        name = Path(str(r.get("file", "frame"))).name
        why = []
        if r["floor_fraction"] < WEAK_FRACTION:
            why.append(f"the floor holds only {100 * r['floor_fraction']:.1f} % of the valid pixels (5 % needed)")
        if r["floor_pixels"] < WEAK_PIXELS:
            why.append(f"only {r['floor_pixels']} floor pixels")
        if r["rms"] > WEAK_RMS:
            why.append(f"its pixels lie {100 * r['rms']:.1f} cm (rms) off the fitted plane")
        if r["height_std"] > 0.01 or max(r["pitch_std"], r["roll_std"]) > math.radians(0.5):
            why.append(
                "the fit is uncertain (height +- {:.3f} m, pitch +- {:.2f} deg, roll +- {:.2f} deg)".format(
                    r["height_std"], math.degrees(r["pitch_std"]), math.degrees(r["roll_std"])
                )
            )
        if why:
            out.append(f"{name}: weak floor fit: {'; '.join(why)}: check the pose in the plot (--plot)")
    return out


# -- check of the tf-provided pose against the floor seen in each frame of a bag (moving base) --------------------

TF_QUANTITIES = (("height", "m", 1.0), ("pitch", "deg", 180.0 / math.pi), ("roll", "deg", 180.0 / math.pi))


@dataclass
class TfCheck:
    """Per depth frame of a bag: the pose tf gives (URDF + IMU/odometry) and the pose of the floor seen in it."""

    bag: str
    depth_topic: str
    frames: list[dict[str, Any]]  #: stamp, tf_*, floor_*, diff_* (tf - floor; m, rad), floor_fraction, found

    def summary(self) -> dict[str, Any]:
        """Per quantity: median of tf - floor (signed: tf's bias), median / p95 / max of |tf - floor|, in m and rad."""
        good = [f for f in self.frames if f["found"]]
        out: dict[str, Any] = {"frames": len(self.frames), "frames_with_floor": len(good)}
        for q, _, _ in TF_QUANTITIES:
            d = np.array([f[f"diff_{q}"] for f in good], float)
            a = np.abs(d)
            out[q] = (
                {
                    "median": float(np.median(d)),
                    "median_abs": float(np.median(a)),
                    "p95_abs": float(np.percentile(a, 95)),
                    "max_abs": float(a.max()),
                }
                if len(d)
                else None
            )
        return out

    def as_dict(self) -> dict[str, Any]:
        return {"bag": self.bag, "depth_topic": self.depth_topic, "summary": self.summary(), "frames": self.frames}


def check_tf(
    bag: Path,
    depth_topic: str | None = None,
    info_topic: str | None = None,
    base_frame: str = "base_footprint",
    base_frame_height: float = 0.0,
    max_depth: float = 12.0,
    max_tilt: float = math.radians(40.0),
    show_progress: bool = False,
) -> TfCheck:
    """For every depth frame of ``bag``: the optical frame's pose in ``base_frame`` that tf gives at the frame's
    stamp, and the pose of the floor fitted in that frame (the core's ``calibrate_from_floor``); their differences
    check the robot's URDF (a constant offset) and its IMU / base pitch (an offset that follows the motion)."""
    from ..bags.messages import stamp
    from ..bags.reader import depth_frames, open_bag, pick_topics
    from ..bags.ros1 import BagError
    from ..bags.tf import read_tf

    if not isinstance(bag, (str, Path)):
        raise TypeError(f"bag: {type(bag).__name__}, expected a path")
    tolerance = 0.1
    try:
        reader = open_bag(Path(bag))
    except BagError as exc:
        raise CalibrationError(str(exc)) from exc
    frames: list[dict[str, Any]] = []
    problems: list[str] = []
    try:
        depth_topic, info_topic = pick_topics(list(reader.connections), depth_topic, info_topic)
        tf = read_tf(reader)
        progress = "calibrate" if show_progress else None
        for img, cam, depth in depth_frames(reader, depth_topic, info_topic, progress, problems):
            at = stamp(img)
            rec: dict[str, Any] = {"stamp": at, "found": False}
            frames.append(rec)
            try:
                q, t = tf.lookup(base_frame, img.header.frame_id, at, tolerance)
            except LookupError as exc:
                rec["message"] = f"no tf: {exc}"
                continue
            h, p, r, _ = _core.pose_from_optical_transform((q, t), base_frame_height)
            rec.update(tf_height=h, tf_pitch=p, tf_roll=r)
            fit = dict(
                _core.calibrate_from_floor(depth_metres(depth, 0.001, max_depth, depth_topic), cam, max_tilt=max_tilt)
            )
            rec["floor_fraction"] = float(fit["floor_fraction"])
            if fit["found"]:
                rec.update(found=True, floor_height=fit["height"], floor_pitch=fit["pitch"], floor_roll=fit["roll"])
                rec.update({f"diff_{k}": rec[f"tf_{k}"] - fit[k] for k in ("height", "pitch", "roll")})
            else:
                rec["message"] = "no floor found"
    except BagError as exc:
        raise CalibrationError(str(exc)) from exc
    finally:
        reader.close()
    if not frames:
        raise CalibrationError(f"{bag}: no frame of {depth_topic} could be used: {'; '.join(problems[:3])}")
    return TfCheck(str(bag), depth_topic, frames)


def describe_tf_check(check: TfCheck) -> str:
    s = check.summary()
    lines = [
        f"{check.bag}: {s['frames']} frames of {check.depth_topic}, floor found in {s['frames_with_floor']}; "
        "tf minus floor (tf's error, the floor taken as the truth):",
        "| quantity | median (bias) | median abs | p95 abs | max abs |",
        "|---|---|---|---|---|",
    ]
    for q, unit, k in TF_QUANTITIES:
        v = s[q]
        if v is None:
            lines.append(f"| {q} [{unit}] | – | – | – | – |")
        else:
            f = "{:+.4f}" if unit == "m" else "{:+.3f}"
            g = "{:.4f}" if unit == "m" else "{:.3f}"
            lines.append(
                f"| {q} [{unit}] | {f.format(k * v['median'])} | {g.format(k * v['median_abs'])} "
                f"| {g.format(k * v['p95_abs'])} | {g.format(k * v['max_abs'])} |"
            )
    return "\n".join(lines)


def plot_tf_check(check: TfCheck, path: Path) -> None:
    """Per frame: tf's and the floor's height, pitch and roll over time, and their difference (PNG, atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..outputs import save_figure

    good = [f for f in check.frames if f["found"]]
    t0 = check.frames[0]["stamp"]
    t = np.array([f["stamp"] - t0 for f in good])
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    for row, (q, unit, k) in enumerate(TF_QUANTITIES):
        tf_v = np.array([f[f"tf_{q}"] for f in good]) * k
        fl_v = np.array([f[f"floor_{q}"] for f in good]) * k
        ax = axes[row, 0]
        ax.plot(t, tf_v, "b.-", ms=3, label="tf (URDF + base pitch)")
        ax.plot(t, fl_v, "r.-", ms=3, label="floor seen in the frame")
        ax.set_ylabel(f"{q} [{unit}]")
        ax.grid(True, color="0.85")
        ax = axes[row, 1]
        ax.plot(t, tf_v - fl_v, "k.-", ms=3)
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(f"tf - floor [{unit}]")
        ax.grid(True, color="0.85")
    axes[0, 0].legend(fontsize=8)
    axes[0, 0].set_title("pose per frame")
    axes[0, 1].set_title("disagreement")
    axes[2, 0].set_xlabel("time [s]")
    axes[2, 1].set_xlabel("time [s]")
    s = check.summary()
    if s["pitch"] is not None:
        fig.suptitle(
            f"tf vs the floor seen, {s['frames_with_floor']} frames: "
            f"tf's pitch bias {math.degrees(s['pitch']['median']):+.2f} deg, "
            f"height bias {100 * s['height']['median']:+.1f} cm (median of tf - floor)"
        )
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
