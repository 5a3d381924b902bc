"""Report of a bag or of depth frames: pictures people would rather see than read, and an index.html.

``kinect-pipeline report IN -o DIR`` runs the core over IN (a bag at the pose its tf gives, or depth frames at a
given or calibrated pose) and writes: frame.png (raw, cleaned and labelled depth: thesis figs 4.11, 4.17a/b),
scan.png (the scan in the robot frame, over the LiDAR's where the bag has one: fig 4.20b), confidence.png (before
and after the intensity filter, for a sequence: fig 4.21), timing.png and index.html; with the generator's ground
truth, quality.json too. A panel appears only where its data exists; each has a caption saying what it shows.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core
from ..bags.messages import LASER_SCAN, stamp
from ..bags.reader import depth_frames, open_bag, read_side
from ..bags.tf import read_tf
from ..figures import plot_frame
from ..outputs import check_outputs, check_rewrite, output_folder, save_figure, write_text
from ..tools.replay import ReplayError, ReplayOptions
from .metrics import missed_beams, phantom_beams

#: Everything a report may write into its folder.
FILES = ("frame.png", "scan.png", "confidence.png", "timing.png", "quality.json", "index.html")
GT_SCAN, GT_LABELS = "/ground_truth/scan", "/ground_truth/labels"


@dataclass
class FrameRecord:
    stamp: float
    pose: tuple[float, float, float]  #: height [m], pitch, roll [rad]
    sensor_xy: tuple[float, float, float]  #: x, y [m], yaw [rad] of the sensor in the base frame
    ranges: np.ndarray
    intensities: np.ndarray
    filtered: np.ndarray  #: ranges with the intensity filter on
    ms: float
    cliff: int = 0  #: beams with a cliff
    lidar: tuple[np.ndarray, float, float, tuple[float, float, float]] | None = None
    gt_scan: np.ndarray | None = None
    labels_match: float = math.nan
    labels: np.ndarray | None = None  #: kept only on request (regress)


@dataclass
class Collected:
    source: str  #: what was read (a bag, frames)
    frames: list[FrameRecord] = field(default_factory=list)
    angle_min: float = 0.0
    angle_increment: float = 0.0
    showcase: tuple[np.ndarray, Any, float, str] | None = None  #: depth, result, max_depth, which frame
    pose_note: str = ""  #: where the pose came from
    camera_note: str = ""  #: where the camera's intrinsics came from
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  #: results that rest on a guess: said on stderr and the page


class _Runner:
    """Two pipelines over the same frames: the configured one, and the same with the intensity filter on."""

    def __init__(self, config: dict[str, Any], out: Collected) -> None:
        self.config, self.out = config, out
        self.pipe: Any = None
        self.pipe_f: Any = None
        self.camera: Any = None
        self.best = -1.0

    def run(self, cam: Any, depth: np.ndarray, pose: tuple[float, float, float], name: str) -> tuple[Any, Any] | None:
        """The two results, or None where the core refuses the frame (said in the problems, as the node drops it)."""
        if self.pipe is None or repr(cam) != repr(self.camera):
            self.camera = cam
            self.pipe = _core.Pipeline(cam, _core.Config(**self.config))
            self.pipe_f = _core.Pipeline(cam, _core.Config(**{**self.config, "intensity_filter": True}))
        try:
            res = self.pipe.process_pose(depth, *pose)
            res_f = self.pipe_f.process_pose(depth, *pose)
        except ValueError as exc:  # float millimetres, say: one such frame does not end the report
            self.out.problems.append(f"{name}: refused by the core: {exc}; frame skipped")
            return None
        self.out.angle_min, self.out.angle_increment = res.angle_min, res.angle_increment
        score = (
            abs(pose[1]) + float((res.labels == _core.LABELS["kept"]).mean()) * 1e-3
        )  # the largest pitch; ties: the most kept
        if score > self.best:
            self.best = score
            self.out.showcase = (depth.copy(), res, float(self.pipe.config.max_depth), name)
        return res, res_f


def _side_topics(bag: Any) -> tuple[str | None, dict[str, dict[float, Any]]]:
    """The bag's LiDAR scan topic (a LaserScan that is not ground truth) and its LiDAR and ground-truth messages
    by stamp (they may come after the frame they belong to)."""
    lidar = next(
        (c.topic for c in bag.connections if c.msgtype == LASER_SCAN and not c.topic.startswith("/ground_truth")),
        None,
    )
    side: dict[str, dict[float, Any]] = {"lidar": {}, "gt_scan": {}, "gt_labels": {}}
    topics = tuple(t for t in (lidar, GT_SCAN, GT_LABELS) if t and any(c.topic == t for c in bag.connections))
    for conn, msg in read_side(bag, topics):
        key = {lidar: "lidar", GT_SCAN: "gt_scan", GT_LABELS: "gt_labels"}[conn.topic]
        if key == "gt_scan":
            side[key][stamp(msg)] = np.array(msg.ranges, np.float32)
        elif key == "gt_labels":
            side[key][stamp(msg)] = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width)
        else:
            side[key][stamp(msg)] = msg
    return lidar, side


def collect(bag_path: Path, opts: ReplayOptions, show_progress: bool = True, keep_labels: bool = False) -> Collected:
    """Runs the core over every depth frame of a bag at its tf pose, with the LiDAR and ground truth of each frame
    where the bag has them. Where tf has no pose: the static pose of ``opts.config`` where it gives one (--param
    sensor_height ...), else the pose of the frame's own floor (a frame without one is left out)."""
    out = Collected(f"bag {bag_path}")
    bag = open_bag(bag_path)
    try:
        depth_topic, info_topic = opts.topics(bag)
        cameras = opts.cameras(bag, info_topic)
        out.source, out.camera_note = f"bag {bag_path}, {depth_topic}", cameras.source
        tf = read_tf(bag)
        _, side = _side_topics(bag)
        runner, fallback, floor = _Runner(dict(opts.config), out), 0, 0
        static = _core.Config(**opts.config)
        given = any(k in opts.config for k in POSE_FIELDS)
        for msg, cam, depth in depth_frames(
            bag, depth_topic, cameras, "report" if show_progress else None, out.problems
        ):
            st = stamp(msg)
            try:
                q, t = tf.lookup(opts.base_frame, msg.header.frame_id, st, opts.tf_tolerance)
                h, p, r, yaw = _core.pose_from_optical_transform((q, t), opts.base_frame_height)
                xy = (t[0], t[1], yaw)
            except LookupError as exc:
                xy = (0.0, 0.0, 0.0)
                if given:
                    h, p, r = static.sensor_height, static.sensor_pitch, static.sensor_roll
                else:
                    pose = _own_floor(depth, cam, static.max_depth, f"frame at {st:.3f} s", out)
                    if pose is None:
                        out.problems.append(f"{depth_topic} at {st:.3f} s: {exc}, and no floor in view; frame skipped")
                        continue
                    h, p, r = pose
                without_tf = True
            else:
                without_tf = False
            results = runner.run(cam, depth, (h, p, r), f"frame at {st:.2f} s")
            if results is None:
                continue
            if without_tf and given:
                fallback += 1
            elif without_tf:
                floor += 1
            res, res_f = results
            rec = _record(st, (h, p, r), xy, res, res_f)
            rec.gt_scan = side["gt_scan"].get(st)
            gt = side["gt_labels"].get(st)
            if gt is not None and gt.shape == res.labels.shape:
                rec.labels_match = float((gt == res.labels).mean())
            rec.lidar = _lidar_at(side["lidar"], tf, opts, st)
            rec.labels = res.labels if keep_labels else None
            out.frames.append(rec)
    finally:
        bag.close()
    if cameras.warning:
        out.warnings.append(cameras.warning)
    if not out.frames:
        why = "; ".join(out.problems[:3]) or "no depth frame in it"
        raise ReplayError(f"{bag_path}: no frame of {depth_topic} could be processed: {why}")
    n = len(out.frames)
    out.pose_note = f"pose from the bag's tf ({opts.base_frame})"
    if fallback:
        out.pose_note = f"pose from tf for {n - fallback} of {n} frames, the static pose of the parameters for the rest"
    if floor:
        out.pose_note = (
            f"pose from tf for {n - floor} of {n} frames, each frame's own floor for the rest (no tf to "
            f"{opts.base_frame} there, and no --param sensor_height / sensor_pitch / sensor_roll)"
        )
    return out


def _own_floor(
    depth: np.ndarray, cam: Any, max_depth: float, name: str, out: Collected
) -> tuple[float, float, float] | None:
    """The pose of the floor seen in a frame of a bag, None where there is none (its warnings to out.problems)."""
    from ..tools.calibrate import calibrate, depth_metres

    cal = calibrate([(name, depth_metres(depth, 0.001, max_depth, name))], cam)
    out.problems += cal.warnings
    return (cal.height, cal.pitch, cal.roll) if cal.found else None


def _record(
    st: float, pose: tuple[float, float, float], xy: tuple[float, float, float], res: Any, res_f: Any
) -> FrameRecord:
    cliff = int(np.isfinite(res.cliff_ranges).sum()) if len(res.cliff_ranges) else 0
    return FrameRecord(st, pose, xy, res.ranges, res.intensities, res_f.ranges, res.times["total"], cliff)


def _lidar_at(lidar: dict[float, Any], tf: Any, opts: ReplayOptions, st: float) -> Any:
    if not lidar:
        return None
    msg = lidar.get(st) or lidar[min(lidar, key=lambda s: abs(s - st))]
    try:
        lq, lt = tf.lookup(opts.base_frame, msg.header.frame_id, st, opts.tf_tolerance)
    except LookupError:
        return None
    yaw = _core.roll_pitch_yaw(lq)[2]
    return (np.array(msg.ranges, np.float32), msg.angle_min, msg.angle_increment, (lt[0], lt[1], yaw))


def collect_frames(
    files: list[Path],
    camera: Any,
    config: dict[str, Any] | None = None,
    depth_scale: float = 0.001,
    max_depth: float = 12.0,
    show_progress: bool = True,
) -> Collected:
    """Runs the core over depth frames (one sequence, in the order given) at the pose of ``config``'s
    sensor_height / sensor_pitch / sensor_roll where it gives one, else at the pose calibrated from the frames'
    floor: one pose for frames that agree (a sensor standing still), each frame's own where they disagree (a
    moving camera; frames without a floor of their own are then left out, and none left is an error)."""
    from ..tools.calibrate import CalibrationError, load_depth

    config = dict(config or {})
    out = Collected(f"{len(files)} depth frame(s): {files[0]}{' ...' if len(files) > 1 else ''}")
    frames = [(str(f), load_depth(f, depth_scale, max_depth)) for f in files]
    for name, metres in frames:
        if metres.shape != (camera.height, camera.width):
            raise CalibrationError(f"{name}: {metres.shape[1]}x{metres.shape[0]}, but the camera is {camera!r}")
    if not any((np.isfinite(m) & (m > 0)).any() for _, m in frames):  # the pictures would show nothing at all
        raise CalibrationError(
            f"no pixel of the {len(frames)} frame(s) holds a depth (all are no return): expected depth frames "
            f"(16-bit at --depth-scale {depth_scale:g} m a unit, 8-bit up to {max_depth:g} m, float metres)"
        )
    if any(k in config for k in POSE_FIELDS):
        cfg = _core.Config(**config)
        poses: list[tuple[float, float, float] | None] = [(cfg.sensor_height, cfg.sensor_pitch, cfg.sensor_roll)] * len(
            frames
        )
        out.pose_note = "pose from the parameters"
    else:
        poses = floor_poses(frames, camera, out)
    runner = _Runner(config, out)
    items: Any = list(zip(frames, poses, strict=True))
    if show_progress:
        from ..outputs import progress

        items = progress(items, len(items), "report")
    for i, ((name, metres), pose) in enumerate(items):
        if pose is None:
            continue
        results = runner.run(camera, metres, pose, Path(name).name)
        if results is not None:
            out.frames.append(_record(float(i), pose, (0.0, 0.0, 0.0), *results))
    if not out.frames:
        raise CalibrationError(f"no frame could be processed: {'; '.join(out.problems[:3])}")
    return out


POSE_FIELDS = ("sensor_height", "sensor_pitch", "sensor_roll")


def floor_poses(
    frames: list[tuple[str, np.ndarray]], camera: Any, out: Collected
) -> list[tuple[float, float, float] | None]:
    """The pose of each frame from the floor: where the frames agree, their mean for all; where they disagree (the
    camera moved: the mean would be no frame's pose and draw the floor as obstacles), each frame's own, None for a
    frame without a floor of its own. Says which in ``out.pose_note``; the calibration's warnings go to
    ``out.problems``. No floor anywhere raises CalibrationError."""
    from ..tools.calibrate import CalibrationError, calibrate, disagreement

    cal = calibrate(frames, camera)
    if not cal.found:
        raise CalibrationError(
            f"{cal.message}: give the pose with --param sensor_height=H --param sensor_pitch=P (m, rad)"
        )
    good = [r for r in cal.frames if r["found"]]
    if not disagreement(good):
        out.pose_note = (
            f"pose calibrated from the frames' floor: height {cal.height:.3f} m, pitch "
            f"{math.degrees(cal.pitch):.2f} deg, roll {math.degrees(cal.roll):.2f} deg"
        )
        out.problems += cal.warnings
        return [(cal.height, cal.pitch, cal.roll)] * len(frames)
    poses = [(r["height"], r["pitch"], r["roll"]) if r["found"] else None for r in cal.frames]
    missing = [Path(str(r["file"])).name for r in cal.frames if not r["found"]]
    heights, pitches = [p[0] for p in poses if p], [math.degrees(p[1]) for p in poses if p]
    out.pose_note = (
        f"pose per frame, each from its own floor (the frames disagree: the camera moved): height "
        f"{min(heights):.2f}..{max(heights):.2f} m, pitch {min(pitches):.1f}..{max(pitches):.1f} deg"
    )
    out.problems += [w for w in cal.warnings if "disagree" not in w]
    if missing:
        more = ", ..." if len(missing) > 3 else ""
        out.warnings.append(
            f"{len(missing)} of {len(frames)} frames left out: no floor of their own, so their pose is not known "
            f"(a moving camera): {', '.join(missing[:3])}{more}"
        )
    return poses


def _points(ranges: np.ndarray, angle_min: float, inc: float, pose: tuple[float, float, float]) -> np.ndarray:
    a = angle_min + inc * np.arange(len(ranges)) + pose[2]
    ok = np.isfinite(ranges)
    return np.stack([pose[0] + ranges[ok] * np.cos(a[ok]), pose[1] + ranges[ok] * np.sin(a[ok])], axis=1)


def write_report(
    source: Path | list[Path],
    out_dir: Path,
    opts: ReplayOptions | None = None,
    show_progress: bool = True,
    camera: Any = None,
    depth_scale: float = 0.001,
) -> dict[str, Any]:
    """Runs the core over ``source`` and writes the report's pictures, ``index.html`` (and ``quality.json`` with
    ground truth) into ``out_dir``. ``source``: a bag of any kind, or depth frames (files or folders of them: then
    ``camera`` is needed). Nothing is written when the input cannot be used, and none of the report's files may be
    an input."""
    from ..tools.calibrate import frame_paths, is_frames

    opts = opts or ReplayOptions()
    out_dir = Path(out_dir)
    items = [Path(p) for p in source] if isinstance(source, (list, tuple)) else [Path(source)]
    check_outputs(items, [out_dir / name for name in FILES], folders=[out_dir])
    check_rewrite(out_dir, FILES, ("index.html",), "a report")
    if is_frames(items):
        if camera is None:
            raise ReplayError(f"{items[0]}: depth frames need the camera's intrinsics (--intrinsics or --sensor-model)")
        skipped: list[str] = []
        files = frame_paths(items, skipped)
        c = collect_frames(files, camera, opts.config, depth_scale, show_progress=show_progress)
        c.problems[:0] = skipped
    elif len(items) == 1:
        c = collect(items[0], opts, show_progress)
    else:
        raise ReplayError(f"one bag at a time: got {len(items)} inputs ({', '.join(map(str, items))})")
    with output_folder(out_dir):
        return _write(out_dir, c)


def _write(out_dir: Path, c: Collected) -> dict[str, Any]:
    import matplotlib

    matplotlib.use("Agg")
    pictures = [_frame_panel(out_dir, c), _scan_panel(out_dir, c)]
    if len(c.frames) > 1:
        pictures.append(_confidence_panel(out_dir, c))
        pictures.append(_timing_panel(out_dir, c))
    summary = _summary(c)
    quality = truth_quality(c)
    if quality:
        summary.update(quality)
        write_text(out_dir / "quality.json", json.dumps(summary, indent=1))
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>" for k, v in summary.items())
    notes = "".join(f"<li>{html.escape(p)}</li>" for p in c.problems[:20])
    warned = "".join(f"<p><b>WARNING</b>: {html.escape(w)}</p>" for w in c.warnings)
    figs = "".join(
        f'<figure><img src="{p}" style="max-width:100%"><figcaption>{html.escape(t)}</figcaption></figure>'
        for p, t in pictures
    )
    page = (
        "<!doctype html><html><head><meta charset='utf-8'><title>kinect_pipeline report</title></head><body>"
        f"<h1>kinect_pipeline report</h1>{warned}<p>{html.escape(c.source)}; {html.escape(c.pose_note)}"
        f"{'; camera: ' + html.escape(c.camera_note) if c.camera_note else ''}</p>"
        f"<table>{rows}</table>{f'<ul>{notes}</ul>' if notes else ''}{figs}</body></html>"
    )
    write_text(out_dir / "index.html", page)
    summary["pictures"] = [p for p, _ in pictures] + ["index.html"]
    return summary


def _frame_panel(out_dir: Path, c: Collected) -> tuple[str, str]:
    assert c.showcase is not None
    depth, res, max_depth, which = c.showcase
    what = "the frame with the largest pitch" if len(c.frames) > 1 else "the frame"
    plot_frame(depth, res, max_depth, out_dir / "frame.png", f"{which}: {what}")
    return "frame.png", (
        f"Raw, cleaned and labelled depth of {what} ({which}): green floor, blue above the ceiling plane, "
        "magenta below the floor, black invalid"
    )


def _scan_panel(out_dir: Path, c: Collected) -> tuple[str, str]:
    import matplotlib.pyplot as plt

    fr = max(c.frames, key=lambda f: abs(f.pose[1]))
    fig, ax = plt.subplots(figsize=(7, 7))
    if fr.lidar is not None:
        lp = _points(fr.lidar[0], fr.lidar[1], fr.lidar[2], fr.lidar[3])
        ax.scatter(lp[:, 0], lp[:, 1], s=5, c="tab:cyan", label="LiDAR scan")
    pts = _points(fr.ranges, c.angle_min, c.angle_increment, fr.sensor_xy)
    ax.scatter(pts[:, 0], pts[:, 1], s=5, c="k", label="depth camera scan")
    ax.plot([0], [0], "r^", markersize=10, label="robot")
    far = max(2.0, float(np.nanmax(np.abs(pts))) if len(pts) else 2.0)
    ax.set_xticks(np.arange(-1, math.ceil(far) + 1))
    ax.grid(True, color="0.85")
    ax.set_aspect("equal")
    ax.set_xlim(-1, min(math.ceil(far) + 0.5, 12))
    ax.set_ylim(-min(far, 6), min(far, 6))
    ax.set_xlabel("x forward [m]")
    ax.set_ylabel("y left [m]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"scan, pitch {math.degrees(fr.pose[1]):.1f} deg")
    save_figure(fig, out_dir / "scan.png")
    plt.close(fig)
    over = " over the LiDAR scan (cyan)" if fr.lidar is not None else ""
    return "scan.png", f"The depth camera's scan (nearest obstacle per beam){over} in the robot frame, 1 m grid"


def _confidence_panel(out_dir: Path, c: Collected) -> tuple[str, str]:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(13, 5.5), sharex=True, sharey=True)
    sc = None
    for a, key, title in ((ax[0], "ranges", "without intensity filter"), (ax[1], "filtered", "with intensity filter")):
        xs, ys, cs = [], [], []
        for f in c.frames:
            ranges = getattr(f, key)
            pts = _points(ranges, c.angle_min, c.angle_increment, f.sensor_xy)
            xs.append(pts[:, 0])
            ys.append(pts[:, 1])
            cs.append(f.intensities[np.isfinite(ranges)])
        sc = a.scatter(np.concatenate(xs), np.concatenate(ys), s=2, c=np.concatenate(cs), cmap="autumn", vmin=0, vmax=1)
        a.set_title(title)
        a.grid(True, color="0.85")
        a.set_aspect("equal")
        a.set_xlabel("x forward [m]")
    ax[0].set_ylabel("y left [m]")
    fig.colorbar(sc, ax=ax.tolist(), shrink=0.7, label="intensity (confidence)")
    save_figure(fig, out_dir / "confidence.png")
    plt.close(fig)
    return "confidence.png", (
        f"All {len(c.frames)} scans coloured by confidence, without and with the intensity filter (thesis fig 4.21)"
    )


def _timing_panel(out_dir: Path, c: Collected) -> tuple[str, str]:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot([f.ms for f in c.frames], ".-")
    ax.set_xlabel("frame")
    ax.set_ylabel("core time per frame [ms]")
    ax.grid(True, color="0.85")
    save_figure(fig, out_dir / "timing.png")
    plt.close(fig)
    return "timing.png", "The core's processing time per frame, in this process (no other load measured)"


def _summary(c: Collected) -> dict[str, Any]:
    pitches = [math.degrees(f.pose[1]) for f in c.frames]
    return {
        "input": c.source,
        "pose": c.pose_note,
        "camera": c.camera_note,
        "frames": len(c.frames),
        "ms_per_frame_median": round(float(np.median([f.ms for f in c.frames])), 3),
        "pitch_deg_range": [round(min(pitches), 2), round(max(pitches), 2)],
        "frames_with_cliff_beams": sum(f.cliff > 0 for f in c.frames),
        "problems": len(c.problems),
        "warnings": list(c.warnings),
    }


def truth_quality(c: Collected) -> dict[str, Any]:
    """Against the generator's ground truth, where the bag has it: the goal's phantom beams (> 5 cm + 4 sigma short,
    as quality.json of the demo and `quality`), the plain 5 cm count (a far wall's noise fills it), missed beams
    and the labels' agreement."""
    with_gt = [f for f in c.frames if f.gt_scan is not None]
    if not with_gt:
        return {}
    phantom = phantom_5cm = missed = beams = 0
    for f in with_gt:
        gt = f.gt_scan
        assert gt is not None
        over_5cm, over_noise = phantom_beams(f.ranges, gt)
        phantom += int(over_noise.sum())
        phantom_5cm += int(over_5cm.sum())
        missed += int(missed_beams(f.ranges, gt).sum())
        beams += len(f.ranges)
    return {
        "phantom_beams": round(phantom / beams, 5),
        "phantom_beams_5cm": round(phantom_5cm / beams, 5),
        "missed_beams": round(missed / beams, 5),
        "label_agreement_min": round(float(np.nanmin([f.labels_match for f in with_gt])), 4),
    }
