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


def frame_paths(items: list[Path], skipped: list[str] | None = None) -> list[Path]:
    """The depth frames named: files as they are, folders as the frames in them (``FRAME_SUFFIXES``, in name
    order). Colour images in a folder (datasets keep them beside the depth) are left out: one line in ``skipped``
    per folder says how many. A folder without depth frames raises CalibrationError naming it."""
    out: list[Path] = []
    for item in items:
        if not item.is_dir():
            out.append(item)
            continue
        found = sorted(p for p in item.iterdir() if p.suffix.lower() in FRAME_SUFFIXES and p.is_file())
        colour = [p for p in found if is_colour_image(p)]
        depth = [p for p in found if p not in colour]
        if colour and skipped is not None:
            more = ", ..." if len(colour) > 2 else ""
            skipped.append(
                f"{item}: {len(colour)} colour image(s) skipped ({', '.join(p.name for p in colour[:2])}{more}), "
                f"{len(depth)} depth frame(s) taken"
            )
        if not depth:
            what = f" (only {len(colour)} colour images)" if colour else ""
            sub = [d.name for d in sorted(item.iterdir()) if d.is_dir()]
            inside = f"; its folders: {', '.join(sub)}: name the one with the depth frames" if sub else ""
            raise CalibrationError(f"{item}: a folder without depth frames ({', '.join(FRAME_SUFFIXES)}){what}{inside}")
        out.extend(depth)
    return out


def is_colour_image(path: Path) -> bool:
    """Whether a PNG's header says it has colour (RGB, palette, grey + alpha, RGBA) rather than one depth channel;
    read from its first 26 bytes, so that a folder of frames is sorted without decoding them."""
    if path.suffix.lower() != ".png":
        return False
    with path.open("rb") as f:
        head = f.read(26)
    # the IHDR chunk: 8-byte signature, length, "IHDR", width, height, bit depth (byte 24), colour type (byte 25)
    return len(head) == 26 and head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR" and head[25] in (2, 3, 4, 6)


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
    metres = depth_metres(arr, depth_scale, max_depth, str(path))
    _check_plausible(metres, arr.dtype, depth_scale, path)
    return metres


#: [m]: no depth camera sees most of its frame nearer; farther than the core's bound is other units than metres
PLAUSIBLE_MEDIAN = (0.05, _core.MILLIMETRE_MEDIAN)


def _check_plausible(metres: np.ndarray, dtype: np.dtype, depth_scale: float, path: Path) -> None:
    """A frame whose valid pixels lie mostly nearer than 5 cm or beyond 100 m is in other units than its reading
    says (a wrong --depth-scale, a float file in millimetres): refused, naming them. Before, it gave "no floor
    found" or a floor at a scaled height."""
    valid = metres[metres > 0]
    if valid.size == 0:
        return
    med = float(np.median(valid))
    if PLAUSIBLE_MEDIAN[0] <= med <= PLAUSIBLE_MEDIAN[1]:
        return
    how = f"uint16 at --depth-scale {depth_scale:g} m" if dtype == np.uint16 else f"{dtype} read as metres"
    raise CalibrationError(
        f"{path}: a median depth of {med:.3g} m ({how}): expected {PLAUSIBLE_MEDIAN[0]:g} to {PLAUSIBLE_MEDIAN[1]:g} m "
        "for a depth camera (16-bit frames in mm: 0.001; TUM and slambook2: 0.0002)"
    )


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
    """Calibrates from one or more (name, metres) frames (each by :func:`fit_floor`: any mounting roll, fits that
    leave much below them refused); several frames give a mean and a spread. ``options``: of :func:`fit_floor`."""
    per: list[dict[str, Any]] = []
    for name, metres in frames:
        if metres.shape != (camera.height, camera.width):
            raise CalibrationError(
                f"{name}: {metres.shape[1]}x{metres.shape[0]} but the intrinsics are for "
                f"{camera.width}x{camera.height} (give --size W H if the principal point is off)"
            )
        r = fit_floor(metres, camera, **options)
        r["file"] = name
        per.append(r)
    good = [r for r in per if r["found"]]
    refused = [r for r in per if r.get("message")]
    if not good:
        why = refused[0]["message"] if refused else "no plane facing up with enough pixels"
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
            f"no floor found in {len(per)} frame(s): {why}",
        )
    w = np.array([r["floor_pixels"] for r in good], float)

    def mean(key: str) -> float:
        m = float(np.average(pose_values(good, key), weights=w))
        return _core.wrap_angle(m) if key == "roll" else m

    def spread(key: str) -> float:
        fit = float(np.sqrt(np.mean([r[f"{key}_std"] ** 2 for r in good])) / math.sqrt(len(good)))
        between = float(np.std(pose_values(good, key), ddof=1) / math.sqrt(len(good))) if len(good) > 1 else 0.0
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
        warnings=disagreement(good) + weak_fits(good) + refusals(refused, len(per)) + upside_down(good),
    )


def pose_values(fits: list[dict[str, Any]], key: str) -> list[float]:
    """The fits' values of a pose term; rolls turned to lie within half a turn of the first fit's (an upside-down
    camera's lie either side of +-180 deg), so that their mean and spread are those of the angles."""
    values = [r[key] for r in fits]
    return on_one_turn(values) if key == "roll" else values


def on_one_turn(angles: list[float], ref: float | None = None) -> list[float]:
    """The angles [rad], each turned by whole turns to lie within half a turn of ref (default: the first angle):
    rolls either side of +-180 deg become one run of values, for means, medians and plotted lines."""
    if not angles:
        return []
    ref = angles[0] if ref is None else ref
    return [ref + _core.wrap_angle(a - ref) for a in angles]


def upside_down(good: list[dict[str, Any]]) -> list[str]:
    """A warning where the floor was found only in the frame turned a half turn: an upright camera that sees a
    ceiling and no floor gives the same plane."""
    turned = [Path(str(r.get("file", "frame"))).name for r in good if r.get("turns") == 2]
    if not turned:
        return []
    return [
        f"{len(turned)} of {len(good)} frames ({', '.join(turned[:3])}{', ...' if len(turned) > 3 else ''}) show "
        "their floor only to a camera mounted upside down (roll near 180 deg): a ceiling seen by an upright camera "
        "that sees no floor looks the same; check the mounting"
    ]


def refusals(refused: list[dict[str, Any]], frames: int) -> list[str]:
    """One warning for the frames whose floor-like plane was refused (left out of the mean)."""
    if not refused:
        return []
    names = ", ".join(Path(str(r["file"])).name for r in refused[:3]) + (", ..." if len(refused) > 3 else "")
    return [f"{len(refused)} of {frames} frames left out ({names}): {refused[0]['message']}"]


#: How far the frames averaged may disagree before a warning, beyond their fits' own uncertainty (3 sigma):
#: a robot standing still sees one pose; hand-held frames or a base that moved give several.
DISAGREE = {"height": (0.01, "m", 1.0), "pitch": (math.radians(0.5), "deg", 180 / math.pi)}
DISAGREE["roll"] = (math.radians(0.5), "deg", 180 / math.pi)


def disagreement(good: list[dict[str, Any]]) -> list[str]:
    """Warnings for pose terms whose frames disagree by more than DISAGREE and 3 sigma of their fits."""
    out = []
    for key, (limit, unit, k) in DISAGREE.items():
        v = pose_values(good, key)
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


#: More weak fits than this in a sequence are said in one line.
WEAK_LINES = 3


def weak_fits(good: list[dict[str, Any]]) -> list[str]:
    """Warnings for frames whose floor is small, thin or far from flat: one per frame, or, for more than
    WEAK_LINES frames, one line counting them by reason."""
    weak = [(Path(str(r.get("file", "frame"))).name, why) for r in good if (why := weak_reasons(r))]
    if len(weak) <= WEAK_LINES:
        return [
            f"{name}: weak floor fit: {'; '.join(why.values())}: check the pose in the plot (--plot)"
            for name, why in weak
        ]
    counts: dict[str, int] = {}
    for _, why in weak:
        for kind in why:
            counts[kind] = counts.get(kind, 0) + 1
    names = ", ".join(name for name, _ in weak[:3])
    return [
        f"{len(weak)} of {len(good)} frames have a weak floor fit ("
        + ", ".join(f"{k}: {n}" for k, n in counts.items())
        + f"; e.g. {names}): check the pose in the plot (--plot); --json gives every frame's fit"
    ]


def weak_reasons(r: dict[str, Any]) -> dict[str, str]:
    """Why a frame's floor fit is weak, by kind (empty: it is not)."""
    why = {}
    if r["floor_fraction"] < WEAK_FRACTION:
        why["a small floor"] = f"the floor holds only {100 * r['floor_fraction']:.1f} % of the valid pixels"
    if r["floor_pixels"] < WEAK_PIXELS:
        why["few floor pixels"] = f"only {r['floor_pixels']} floor pixels"
    if r["rms"] > WEAK_RMS:
        why["a loose plane"] = f"its pixels lie {100 * r['rms']:.1f} cm (rms) off the fitted plane"
    if r["height_std"] > 0.01 or max(r["pitch_std"], r["roll_std"]) > math.radians(0.5):
        why["an uncertain fit"] = (
            "the fit is uncertain (height +- {:.3f} m, pitch +- {:.2f} deg, roll +- {:.2f} deg)".format(
                r["height_std"], math.degrees(r["pitch_std"]), math.degrees(r["roll_std"])
            )
        )
    return why


# -- check of the tf-provided pose against the floor seen in each frame of a bag (moving base) --------------------

TF_QUANTITIES = (("height", "m", 1.0), ("pitch", "deg", 180.0 / math.pi), ("roll", "deg", 180.0 / math.pi))


@dataclass
class TfCheck:
    """Per depth frame of a bag: the pose tf gives (URDF + IMU/odometry) and the pose of the floor seen in it."""

    bag: str
    depth_topic: str
    frames: list[dict[str, Any]]  #: stamp, tf_*, floor_*, diff_* (tf - floor; m, rad), floor_fraction, found
    camera: str = ""  #: where the camera's intrinsics came from
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """Per quantity: median of tf - floor (signed: tf's bias), median / p95 / max of |tf - floor|, in m and rad;
        ``floor``: the median of the floor's pose over the frames it was found in (a bag without tf has only it)."""
        good = [f for f in self.frames if f["found"] and "diff_height" in f]
        floors = [f for f in self.frames if f["found"]]
        out: dict[str, Any] = {
            "frames": len(self.frames),
            "frames_with_floor": len(floors),
            "frames_with_tf": sum("tf_height" in f for f in self.frames),
            "floor": {q: self._median_of(floors, f"floor_{q}") for q, _, _ in TF_QUANTITIES} if floors else None,
        }
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

    @staticmethod
    def _median_of(frames: list[dict[str, Any]], key: str) -> float:
        """The median of a pose term over frames; rolls taken on one turn (an upside-down camera's straddle +-180)."""
        values = [f[key] for f in frames]
        if not key.endswith("roll"):
            return float(np.median(values))
        return _core.wrap_angle(float(np.median(on_one_turn(values))))

    def series(self) -> dict[str, dict[str, np.ndarray]]:
        """What plot_tf_check draws, per quantity [m, rad]: ``t``, ``tf``, ``floor`` at the frames with both (times
        from the first frame), ``t_floor``, ``floor_all`` at every frame with a floor, and ``diff`` (tf - floor,
        wrapped for the roll). Rolls on one turn, around tf's first (or the floor's): no jump at +-180 deg."""
        good = [f for f in self.frames if f["found"] and "diff_height" in f]
        floors = [f for f in self.frames if f["found"]]
        t0 = self.frames[0]["stamp"]
        out: dict[str, dict[str, np.ndarray]] = {}
        for q, _, _ in TF_QUANTITIES:
            tf_v = [f[f"tf_{q}"] for f in good]
            fl_all = [f[f"floor_{q}"] for f in floors]
            fl_v = [f[f"floor_{q}"] for f in good]
            if q == "roll":
                ref = (tf_v or fl_all or [0.0])[0]
                tf_v, fl_v, fl_all = on_one_turn(tf_v, ref), on_one_turn(fl_v, ref), on_one_turn(fl_all, ref)
            out[q] = {
                "t": np.array([f["stamp"] - t0 for f in good]),
                "tf": np.array(tf_v, float),
                "floor": np.array(fl_v, float),
                "t_floor": np.array([f["stamp"] - t0 for f in floors]),
                "floor_all": np.array(fl_all, float),
                "diff": np.array([f[f"diff_{q}"] for f in good], float),
            }
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "bag": self.bag,
            "depth_topic": self.depth_topic,
            "camera": self.camera,
            "warnings": self.warnings,
            "summary": self.summary(),
            "frames": self.frames,
        }


def check_tf(
    bag: Path,
    depth_topic: str | None = None,
    info_topic: str | None = None,
    base_frame: str = "base_footprint",
    base_frame_height: float = 0.0,
    max_depth: float = 12.0,
    max_tilt: float = math.radians(40.0),
    show_progress: bool = False,
    intrinsics: Any = None,
    sensor_model: str | None = None,
    rectify: str = "auto",
) -> TfCheck:
    """For every depth frame of ``bag``: the optical frame's pose in ``base_frame`` that tf gives at the frame's
    stamp, and the pose of the floor fitted in that frame (the core's ``calibrate_from_floor``); their differences
    check the robot's URDF (a constant offset) and its IMU / base pitch (an offset that follows the motion). Frames
    without tf keep their floor's pose (a bag without tf: the floor's pose per frame). The camera: ``intrinsics``
    (:class:`kinect_pipeline.intrinsics.Intrinsics`) where given, else the camera_info of each frame's stamp, else
    ``sensor_model``'s nominal camera (with a warning)."""
    from ..bags.messages import stamp
    from ..bags.reader import Cameras, depth_frames, open_bag, pick_topics
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
    fits: list[dict[str, Any]] = []
    problems: list[str] = []
    try:
        need_info = intrinsics is None and not sensor_model
        depth_topic, info_topic = pick_topics(list(reader.connections), depth_topic, info_topic, need_info)
        cameras = Cameras(reader, info_topic, intrinsics, sensor_model, rectify=rectify)
        tf = read_tf(reader)
        progress = "calibrate" if show_progress else None
        for img, cam, depth in depth_frames(reader, depth_topic, cameras, progress, problems):
            at = stamp(img)
            rec: dict[str, Any] = {"stamp": at, "found": False}
            frames.append(rec)
            fit = fit_floor(depth_metres(depth, 0.001, max_depth, depth_topic), cam, max_tilt, sensor_model or "")
            rec["floor_fraction"] = float(fit["floor_fraction"])
            fits.append({**fit, "file": f"frame at {at:.3f} s"})
            if fit["found"]:
                rec.update(found=True, floor_height=fit["height"], floor_pitch=fit["pitch"], floor_roll=fit["roll"])
            else:
                rec["message"] = fit.get("message", "no floor found")
            try:
                q, t = tf.lookup(base_frame, img.header.frame_id, at, tolerance)
            except LookupError as exc:
                rec["message"] = f"no tf: {exc}" + ("; no floor found" if not fit["found"] else "")
                continue
            h, p, r, _ = _core.pose_from_optical_transform((q, t), base_frame_height)
            rec.update(tf_height=h, tf_pitch=p, tf_roll=r)
            if fit["found"]:
                rec.update({f"diff_{k}": rec[f"tf_{k}"] - fit[k] for k in ("height", "pitch")})
                rec["diff_roll"] = _core.wrap_angle(rec["tf_roll"] - fit["roll"])
    except BagError as exc:
        raise CalibrationError(str(exc)) from exc
    finally:
        reader.close()
    if not frames:
        raise CalibrationError(f"{bag}: no frame of {depth_topic} could be used: {'; '.join(problems[:3])}")
    if tf.parent and not any("tf_height" in f for f in frames):  # a tf the frames cannot use: nothing was checked
        first = next(f["message"] for f in frames if "message" in f)
        known = ", ".join(sorted(set(tf.parent) | set(tf.parent.values())))
        raise CalibrationError(
            f"{bag}: no frame of {depth_topic} has a tf from the base frame '{base_frame}' ({first}): expected a "
            f"frame of the bag's tf tree ({known}), connected to the camera's"
        )
    warnings = [cameras.warning] if cameras.warning else []
    found = [f for f in fits if f["found"]]
    warnings += weak_fits(found) + refusals([f for f in fits if f.get("message")], len(fits)) + upside_down(found)
    return TfCheck(str(bag), depth_topic, frames, cameras.source, warnings)


def describe_tf_check(check: TfCheck) -> str:
    s = check.summary()
    if s["frames_with_tf"] == 0:
        fl = s["floor"]
        return (
            f"{check.bag}: {s['frames']} frames of {check.depth_topic}, floor found in {s['frames_with_floor']}; the "
            f"bag has no tf to the camera's frame, so there is nothing to check: the floor's pose (median over the "
            f"frames): height {fl['height']:.4f} m, pitch {math.degrees(fl['pitch']):+.3f} deg, roll "
            f"{math.degrees(fl['roll']):+.3f} deg (camera: {check.camera})"
        )
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

    series = check.series()
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    for row, (q, unit, k) in enumerate(TF_QUANTITIES):
        v = series[q]
        ax = axes[row, 0]
        ax.plot(v["t"], v["tf"] * k, "b.-", ms=3, label="tf (URDF + base pitch)")
        ax.plot(v["t_floor"], v["floor_all"] * k, "r.-", ms=3, label="floor seen in the frame")
        ax.set_ylabel(f"{q} [{unit}]")
        ax.grid(True, color="0.85")
        ax = axes[row, 1]
        ax.plot(v["t"], v["diff"] * k, "k.-", ms=3)
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


# -- the floor at any mounting roll ---------------------------------------------------------------------------


def rotated(metres: np.ndarray, camera: _core.Camera, k: int) -> tuple[np.ndarray, _core.Camera]:
    """The frame turned by ``k`` quarter turns counter-clockwise (``np.rot90``) and the camera that sees it: the
    same camera rolled by k * 90 deg about its optical axis (a roll r becomes r + k * 90 deg)."""
    cam = camera
    for _ in range(k % 4):  # pixel (u, v) -> (v, W - 1 - u)
        cam = _core.Camera(cam.height, cam.width, cam.fy, cam.fx, cam.cy, cam.width - 1 - cam.cx)
    return np.ascontiguousarray(np.rot90(metres, k)), cam


#: A floor fit that leaves more than this fraction of the valid pixels below it (labelled "below floor" at its
#: pose) is no floor: a table or counter taken for it (real frames: right fits 0-1.3 %, wrong ones 9-65 %).
BELOW_MAX = 0.05
#: The cone the turned searches use at least [rad]: quarter turns of 90 deg with cones of 50 deg overlap.
TURN_CONE = math.radians(50.0)


def fit_floor(
    metres: np.ndarray,
    camera: _core.Camera,
    max_tilt: float = math.radians(40.0),
    sensor_model: str = "",
    **options: Any,
) -> dict[str, Any]:
    """The core's floor fit (``calibrate_from_floor``) at any mounting roll, judged by what it explains.

    The frame as it is is searched first (within ``max_tilt`` of the image's up); where that finds no plausible
    floor (under WEAK_FRACTION of the pixels, or more than BELOW_MAX of them below it), the frame turned by a
    quarter turn either way (portrait and side cameras, a roll within 90 deg) and by a half turn (upside down,
    within ``max_tilt`` of the image's down) is searched too, and the plausible fit that explains the most is
    taken: a wider search only adds candidates, it never loses one. A fit that leaves more than BELOW_MAX below it
    is refused (``found`` False, ``message`` says why). Also returns ``below_floor`` (that fraction)."""
    tilt = float(max_tilt)
    cones = sorted({min(tilt, math.radians(40.0)), tilt})
    stages = [[(0, t) for t in cones], [(k, max(tilt, TURN_CONE)) for k in (1, 3)] + [(2, t) for t in cones]]
    seen: list[dict[str, Any]] = []
    for stage in stages:
        for k, cone in stage:
            r = _turned_fit(metres, camera, k, cone, tilt, sensor_model, options)
            if r is not None:
                seen.append(r)
        plausible = [c for c in seen if c["below_floor"] <= BELOW_MAX and c["floor_fraction"] >= WEAK_FRACTION]
        if plausible:
            return max(plausible, key=lambda c: c["floor_fraction"])
    kept = [c for c in seen if c["below_floor"] <= BELOW_MAX and c["turns"] == 0]
    if kept:
        return max(kept, key=lambda c: c["floor_fraction"])  # weak: weak_fits says so
    none: dict[str, Any] = {k: 0.0 for k in NO_FLOOR}
    none.update(found=False, floor_pixels=0, below_floor=0.0, turns=0)
    if seen:
        # a half turn's plane (a ceiling, seen as an upside-down camera's floor) only where no other was found
        named = [c for c in seen if c["turns"] != 2] or seen
        worst = min(named, key=lambda c: c["below_floor"])
        none["message"] = (
            f"the floor-like plane found ({worst['height']:.2f} m below the camera, pitch "
            f"{math.degrees(worst['pitch']):.0f} deg, roll {math.degrees(worst['roll']):.0f} deg) leaves "
            f"{100 * worst['below_floor']:.0f} % of the pixels below it: a table or counter, not the floor"
        )
    return none


NO_FLOOR = ("height", "pitch", "roll", "height_std", "pitch_std", "roll_std", "floor_fraction", "rms")


def _turned_fit(
    metres: np.ndarray, camera: _core.Camera, k: int, cone: float, max_tilt: float, model: str, options: dict[str, Any]
) -> dict[str, Any] | None:
    """The core's fit of the frame turned by k quarter turns, as the pose of the camera as mounted, with the
    fraction of the pixels it leaves below the floor; None where nothing is found, a turned frame's pitch is
    beyond max_tilt, or a quarter turn's roll is beyond 90 deg by more than 1 deg (a wall beside a camera rolled
    115 deg looks like a floor: real kitchen frames)."""
    m, cam = rotated(metres, camera, k)
    r = dict(_core.calibrate_from_floor(m, cam, max_tilt=cone, **options))
    if not r["found"]:
        return None
    roll = _core.wrap_angle(r["roll"] - k * math.pi / 2)
    if (k and abs(r["pitch"]) > max_tilt) or (k % 2 and abs(roll) > math.pi / 2 + math.radians(1.0)):
        return None
    r.update(roll=roll, turns=k)
    config = {"sensor_model": model} if model else {}
    cfg = _core.Config(
        **config,
        sensor_height=r["height"],
        sensor_pitch=r["pitch"],
        sensor_roll=r["roll"],
        refine_floor=False,
        ceiling_height=max(3.0, r["height"] + 0.5),
    )
    labels = np.asarray(_core.Pipeline(camera, cfg).process(metres).labels)
    valid = max(1, int((labels != _core.LABELS["invalid"]).sum()))
    r["below_floor"] = float((labels == _core.LABELS["below_floor"]).sum()) / valid
    return r
