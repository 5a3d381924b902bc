"""Report of a bag: pictures people would rather see than read, and an index.html.

``kinect-pipeline report IN.bag -o DIR`` runs the core over the bag (at the pose its tf gives) and writes:
frame.png (raw, cleaned and labelled depth: thesis figs 4.11, 4.17a/b), scan.png (the Kinect scan over the LiDAR
scan in the robot frame, 1 m grid: fig 4.20b), confidence.png (before and after the intensity filter: fig 4.21),
timing.png (per-frame processing time) and index.html; with the generator's ground truth, quality.json too.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from .demo import plot_frame
from .metrics import missed_beams, phantom_beams
from .outputs import check_outputs, output_folder, save_figure, write_text
from .replay import (
    ReplayError,
    ReplayOptions,
    _pick_topics,
    _stamp,
    _typestore,
    camera_from_info,
    depth_frames,
    image_to_array,
    open_bag,
    read_tf,
)


@dataclass
class FrameRecord:
    stamp: float
    base_pitch_hint: float
    pose: tuple[float, float, float]
    sensor_xy: tuple[float, float, float]
    ranges: np.ndarray
    intensities: np.ndarray
    filtered: np.ndarray
    ms: float
    lidar: tuple[np.ndarray, float, float, tuple[float, float, float]] | None = None
    gt_scan: np.ndarray | None = None
    gt_labels: np.ndarray | None = None
    labels_match: float = math.nan
    labels: np.ndarray | None = None


@dataclass
class Collected:
    frames: list[FrameRecord] = field(default_factory=list)
    angle_min: float = 0.0
    angle_increment: float = 0.0
    showcase: tuple[np.ndarray, Any, float] | None = None  # depth, result, max_depth


def collect(bag: Path, opts: ReplayOptions, show_progress: bool = True, keep_labels: bool = False) -> Collected:
    """Runs two pipelines over the bag: the configured one, and the same with the intensity filter on."""
    ts = _typestore()
    out = Collected()
    reader = open_bag(bag)
    try:
        depth_topic, info_topic = _pick_topics(list(reader.connections), opts)
        tf = read_tf(reader)
        lidar_topic = next(
            (
                c.topic
                for c in reader.connections
                if c.msgtype == "sensor_msgs/msg/LaserScan" and "ground_truth" not in c.topic
            ),
            None,
        )
        pending: dict[str, dict[float, Any]] = {"lidar": {}, "gt_scan": {}, "gt_labels": {}}
        # Side topics first: they may come after the frame they belong to.
        side = [c for c in reader.connections if c.topic in (lidar_topic, "/ground_truth/scan", "/ground_truth/labels")]
        for conn, _, raw in reader.messages(connections=side):
            msg = ts.deserialize_ros1(raw, conn.msgtype)
            st = _stamp(msg.header)
            if conn.topic == lidar_topic:
                pending["lidar"][st] = msg
            elif conn.topic == "/ground_truth/scan":
                pending["gt_scan"][st] = np.array(msg.ranges, np.float32)
            else:
                pending["gt_labels"][st] = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width)
        config = dict(opts.config)
        pipe = pipe_f = None
        best_score = -1.0
        for msg, info in depth_frames(reader, depth_topic, info_topic, "report" if show_progress else None):
            st = _stamp(msg.header)
            cam = camera_from_info(info)
            if pipe is None:
                pipe = _core.Pipeline(cam, _core.Config(**config))
                pipe_f = _core.Pipeline(cam, _core.Config(**{**config, "intensity_filter": True}))
            depth = image_to_array(msg)
            try:
                q, t = tf.lookup(opts.base_frame, msg.header.frame_id, st, opts.tf_tolerance)
                h, p, r, yaw = _core.pose_from_optical_transform((q, t), opts.base_frame_height)
                xy = (t[0], t[1], yaw)
            except LookupError:
                h, p, r, xy = (
                    pipe.config.sensor_height,
                    pipe.config.sensor_pitch,
                    pipe.config.sensor_roll,
                    (0.0, 0.0, 0.0),
                )
            assert pipe is not None and pipe_f is not None
            res = pipe.process_pose(depth, h, p, r)
            res_f = pipe_f.process_pose(depth, h, p, r)
            rec = FrameRecord(st, 0.0, (h, p, r), xy, res.ranges, res.intensities, res_f.ranges, res.times["total"])
            out.angle_min, out.angle_increment = res.angle_min, res.angle_increment
            rec.gt_scan = pending["gt_scan"].get(st)
            if keep_labels:
                rec.labels = res.labels
            gt = pending["gt_labels"].get(st)
            if gt is not None:
                rec.labels_match = float((gt == res.labels).mean())
            lid = pending["lidar"].get(st) or (pending["lidar"][max(pending["lidar"])] if pending["lidar"] else None)
            if lid is not None:
                try:
                    lq, lt = tf.lookup(opts.base_frame, lid.header.frame_id, st, opts.tf_tolerance)
                    yaw_l = _core.roll_pitch_yaw(lq)[2]
                    rec.lidar = (
                        np.array(lid.ranges, np.float32),
                        lid.angle_min,
                        lid.angle_increment,
                        (lt[0], lt[1], yaw_l),
                    )
                except LookupError:
                    pass
            out.frames.append(rec)
            score = abs(p)
            if score > best_score:
                best_score = score
                out.showcase = (depth.copy(), res, float(pipe.config.max_depth))
    finally:
        reader.close()
    if not out.frames:
        raise ReplayError(f"{bag}: no depth frame with a camera_info on {depth_topic}")
    return out


#: What a report writes into its folder.
FILES = ("frame.png", "scan.png", "confidence.png", "timing.png", "quality.json", "index.html")


def _points(ranges: np.ndarray, angle_min: float, inc: float, pose: tuple[float, float, float]) -> np.ndarray:
    a = angle_min + inc * np.arange(len(ranges)) + pose[2]
    ok = np.isfinite(ranges)
    return np.stack([pose[0] + ranges[ok] * np.cos(a[ok]), pose[1] + ranges[ok] * np.sin(a[ok])], axis=1)


def write_report(
    bag: Path, out_dir: Path, opts: ReplayOptions | None = None, show_progress: bool = True
) -> dict[str, Any]:
    """Runs the core over ``bag`` and writes the report's pictures, ``index.html`` (and ``quality.json`` with
    ground truth) into ``out_dir``: nothing is written when the bag cannot be used, and none of the report's files
    may be the input."""
    opts = opts or ReplayOptions()
    bag, out_dir = Path(bag), Path(out_dir)
    check_outputs([bag], [out_dir / name for name in FILES], folders=[out_dir])
    c = collect(bag, opts, show_progress)
    with output_folder(out_dir):
        return _write(bag, out_dir, c)


def _write(bag: Path, out_dir: Path, c: Collected) -> dict[str, Any]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    assert c.showcase is not None
    depth, res, max_depth = c.showcase
    pictures: list[tuple[str, str]] = []

    # 1. Raw, cleaned and labelled depth.
    plot_frame(depth, res, max_depth, out_dir / "frame.png", "frame with the largest pitch")
    pictures.append(("frame.png", "Raw, cleaned and labelled depth of the frame with the largest pitch"))

    # 2. The Kinect scan over the LiDAR scan, robot frame, 1 m grid.
    fr = max(c.frames, key=lambda f: abs(f.pose[1]))
    fig, ax = plt.subplots(figsize=(7, 7))
    if fr.lidar is not None:
        lp = _points(fr.lidar[0], fr.lidar[1], fr.lidar[2], fr.lidar[3])
        ax.scatter(lp[:, 0], lp[:, 1], s=5, c="tab:cyan", label="LiDAR scan")
    kp_pts = _points(fr.ranges, c.angle_min, c.angle_increment, fr.sensor_xy)
    ax.scatter(kp_pts[:, 0], kp_pts[:, 1], s=5, c="k", label="Kinect scan")
    ax.plot([0], [0], "r^", markersize=10, label="robot")
    ax.set_xticks(np.arange(-1, 9))
    ax.set_yticks(np.arange(-5, 6))
    ax.grid(True, color="0.85")
    ax.set_aspect("equal")
    ax.set_xlim(-1, 8)
    ax.set_ylim(-4.5, 4.5)
    ax.set_xlabel("x forward [m]")
    ax.set_ylabel("y left [m]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"scan at {fr.stamp:.2f} s, pitch {math.degrees(fr.pose[1]):.1f} deg")
    save_figure(fig, out_dir / "scan.png")
    plt.close(fig)
    pictures.append(("scan.png", "The Kinect scan over the LiDAR scan in the robot frame, 1 m grid (thesis fig 4.20b)"))

    # 3. Confidence before / after the intensity filter, over the whole sequence.
    fig, ax = plt.subplots(1, 2, figsize=(13, 5.5), sharex=True, sharey=True)
    for a, key, title in ((ax[0], "ranges", "without intensity filter"), (ax[1], "filtered", "with intensity filter")):
        xs, ys, cs = [], [], []
        for f in c.frames:
            pts = _points(getattr(f, key), c.angle_min, c.angle_increment, f.sensor_xy)
            ok = np.isfinite(getattr(f, key))
            xs.append(pts[:, 0])
            ys.append(pts[:, 1])
            cs.append(f.intensities[ok])
        sc = a.scatter(np.concatenate(xs), np.concatenate(ys), s=2, c=np.concatenate(cs), cmap="autumn", vmin=0, vmax=1)
        a.set_title(title)
        a.grid(True, color="0.85")
        a.set_aspect("equal")
        a.set_xlabel("x forward [m]")
    ax[0].set_ylabel("y left [m]")
    fig.colorbar(sc, ax=ax.tolist(), shrink=0.7, label="intensity (confidence)")
    save_figure(fig, out_dir / "confidence.png")
    plt.close(fig)
    pictures.append(
        ("confidence.png", "All scans of the bag, coloured by confidence, before and after the filter (fig 4.21)")
    )

    # 4. Timing.
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot([f.ms for f in c.frames], ".-")
    ax.set_xlabel("frame")
    ax.set_ylabel("core time per frame [ms]")
    ax.grid(True, color="0.85")
    save_figure(fig, out_dir / "timing.png")
    plt.close(fig)
    pictures.append(("timing.png", "Per-frame processing time of the core"))

    summary: dict[str, Any] = {
        "bag": str(bag),
        "frames": len(c.frames),
        "ms_per_frame_median": float(np.median([f.ms for f in c.frames])),
        "pitch_deg_range": [
            math.degrees(min(f.pose[1] for f in c.frames)),
            math.degrees(max(f.pose[1] for f in c.frames)),
        ],
    }
    with_gt = [f for f in c.frames if f.gt_scan is not None]
    if with_gt:
        phantom = phantom_5cm = missed = beams = 0
        for f in with_gt:
            gt = f.gt_scan
            assert gt is not None  # with_gt
            over_5cm, over_noise = phantom_beams(f.ranges, gt)
            phantom += int(over_noise.sum())
            phantom_5cm += int(over_5cm.sum())
            missed += int(missed_beams(f.ranges, gt).sum())
            beams += len(f.ranges)
        # The goal's phantom (> 5 cm + 4 sigma short, as quality.json of the demo and `quality`), and the plain
        # 5 cm count, which a far wall's noise fills (the min over its pixels lies about 2 sigma short).
        summary["phantom_beams"] = phantom / beams
        summary["phantom_beams_5cm"] = phantom_5cm / beams
        summary["missed_beams"] = missed / beams
        summary["label_agreement_min"] = float(np.nanmin([f.labels_match for f in with_gt]))
        write_text(out_dir / "quality.json", json.dumps(summary, indent=1))
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>" for k, v in summary.items())
    figs = "".join(
        f'<figure><img src="{p}" style="max-width:100%"><figcaption>{html.escape(t)}</figcaption></figure>'
        for p, t in pictures
    )
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>kinect_pipeline report</title></head><body>"
        f"<h1>kinect_pipeline report</h1><p>{html.escape(str(bag))}</p><table>{rows}</table>{figs}</body></html>"
    )
    write_text(out_dir / "index.html", page)
    summary["pictures"] = [p for p, _ in pictures] + ["index.html"]
    return summary
