"""Offline replay: run the core over a ROS 1 bag (read and written with the PyPI ``rosbags`` library) at the pose the
bag's tf gives at each frame's stamp, and write the scan and cleaned image next to the input topics in a new bag."""

from __future__ import annotations

import bisect
import math
import os
import time
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core

Tf = tuple[tuple[float, float, float, float], tuple[float, float, float]]

DTYPES = {"8UC1": np.uint8, "mono8": np.uint8, "16UC1": np.uint16, "mono16": np.uint16, "32FC1": np.float32}


class ReplayError(ValueError):
    """A bag or an option the replay cannot use; the message says which and why."""


@dataclass
class ReplayOptions:
    depth_topic: str | None = None  #: default: the only Image topic whose name contains "depth"
    info_topic: str | None = None  #: default: camera_info beside the depth topic
    base_frame: str = "base_footprint"
    base_frame_height: float = 0.0
    scan_topic: str | None = None  #: default: <camera namespace>/scan
    cleaned_topic: str | None = None  #: default: <depth topic>/processed
    scan_frame: str = "kinect2_scan"
    pose_fallback: str = "static"  #: static | skip
    tf_tolerance: float = 0.1  #: how far beyond the first/last transform a stamp may be [s]
    skip_bad: bool = False  #: skip messages that cannot be read instead of stopping
    config: dict[str, Any] = field(default_factory=dict)  #: Config fields


@dataclass
class ReplayReport:
    frames: int = 0
    processed: int = 0
    pose_from_tf: int = 0
    pose_fallback: int = 0
    skipped_no_pose: int = 0
    bad_messages: int = 0
    seconds: float = 0.0
    depth_topic: str = ""
    scan_topic: str = ""
    problems: list[str] = field(default_factory=list)


class TfBuffer:
    """The bag's /tf and /tf_static, looked up at a stamp by composing the chain between two frames."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}
        self.static: dict[str, Tf] = {}
        self.dynamic: dict[str, tuple[list[float], list[Tf]]] = defaultdict(lambda: ([], []))

    def add(self, msg: Any, static: bool) -> None:
        for t in msg.transforms:
            child = t.child_frame_id.lstrip("/")
            self.parent[child] = t.header.frame_id.lstrip("/")
            tf: Tf = (
                (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w),
                (t.transform.translation.x, t.transform.translation.y, t.transform.translation.z),
            )
            if static:
                self.static[child] = tf
            else:
                stamps, tfs = self.dynamic[child]
                s = t.header.stamp.sec + t.header.stamp.nanosec * 1e-9
                i = bisect.bisect(stamps, s)
                stamps.insert(i, s)
                tfs.insert(i, tf)

    def _edge(self, child: str, stamp: float, tolerance: float) -> Tf:
        if child in self.static:
            return self.static[child]
        stamps, tfs = self.dynamic.get(child, ([], []))
        if not stamps:
            raise LookupError(f"no transform to '{child}'")
        i = bisect.bisect(stamps, stamp)
        if i == 0:
            if stamps[0] - stamp > tolerance:
                raise LookupError(f"'{child}': first transform at {stamps[0]:.3f} s, after the frame ({stamp:.3f} s)")
            return tfs[0]
        if i == len(stamps):
            if stamp - stamps[-1] > tolerance:
                raise LookupError(f"'{child}': last transform at {stamps[-1]:.3f} s, before the frame ({stamp:.3f} s)")
            return tfs[-1]
        a, b = stamps[i - 1], stamps[i]
        return _core.interpolate_transform(tfs[i - 1], tfs[i], (stamp - a) / (b - a) if b > a else 0.0)

    def lookup(self, target: str, source: str, stamp: float, tolerance: float) -> Tf:
        """target <- source at ``stamp``, composing the tree through their common ancestor."""
        target, source = target.lstrip("/"), source.lstrip("/")

        def chain(frame: str) -> list[str]:
            out = [frame]
            while out[-1] in self.parent and len(out) < 100:
                out.append(self.parent[out[-1]])
            return out

        up_s, up_t = chain(source), chain(target)
        common = next((f for f in up_s if f in up_t), None)
        if common is None:
            raise LookupError(f"'{source}' and '{target}' are not connected in the bag's tf tree")
        identity: Tf = ((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
        common_from_source = identity
        for f in up_s[: up_s.index(common)]:
            common_from_source = _core.compose_transforms(self._edge(f, stamp, tolerance), common_from_source)
        common_from_target = identity
        for f in up_t[: up_t.index(common)]:
            common_from_target = _core.compose_transforms(self._edge(f, stamp, tolerance), common_from_target)
        return _core.compose_transforms(_core.invert_transform(common_from_target), common_from_source)


def image_to_array(msg: Any) -> np.ndarray:
    """A depth Image message as a 2-D array (a view where the byte order is the host's)."""
    dtype = DTYPES.get(msg.encoding)
    if dtype is None:
        raise ReplayError(f"depth image encoding '{msg.encoding}': expected one of {', '.join(DTYPES)}")
    item = np.dtype(dtype).itemsize
    if msg.step < msg.width * item or len(msg.data) < msg.step * msg.height:
        raise ReplayError(f"depth image {msg.width}x{msg.height} step {msg.step} has {len(msg.data)} bytes")
    rows = np.frombuffer(msg.data, np.uint8, count=msg.step * msg.height).reshape(msg.height, msg.step)
    arr = rows[:, : msg.width * item].view(np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<"))
    return arr.astype(dtype, copy=False)


def _stamp(h: Any) -> float:
    return float(h.stamp.sec + h.stamp.nanosec * 1e-9)


def _typestore() -> Any:
    from .bag import _typestore as ts

    return ts()


def open_bag(path: Path) -> Any:
    """A rosbags reader, opened; a file that is no readable ROS 1 bag raises ReplayError naming it."""
    from rosbags.rosbag1 import Reader, ReaderError

    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError) as exc:
        raise ReplayError(f"{path}: not a readable ROS 1 bag ({exc})") from exc
    return reader


def camera_from_info(info: Any) -> _core.Camera:
    """The core's camera model of a CameraInfo message (K: fx, fy, cx, cy)."""
    return _core.Camera(
        int(info.width), int(info.height), float(info.K[0]), float(info.K[4]), float(info.K[2]), float(info.K[5])
    )


def _pick_topics(connections: list[Any], opts: ReplayOptions) -> tuple[str, str]:
    images = sorted({c.topic for c in connections if c.msgtype == "sensor_msgs/msg/Image"})
    infos = {c.topic for c in connections if c.msgtype == "sensor_msgs/msg/CameraInfo"}
    depth = opts.depth_topic
    if depth is None:
        cands = [t for t in images if "depth" in t and not t.endswith("/processed")]
        if len(cands) != 1:
            raise ReplayError(
                f"cannot tell the depth topic among the Image topics {images or '(none)'}: name it with --depth-topic"
            )
        depth = cands[0]
    elif depth not in images:
        raise ReplayError(f"--depth-topic {depth}: not an Image topic of the bag (Image topics: {images or 'none'})")
    info = opts.info_topic or depth.rsplit("/", 1)[0] + "/camera_info"
    if info not in infos:
        raise ReplayError(
            f"camera_info topic {info} not in the bag (CameraInfo topics: {sorted(infos) or 'none'}): "
            "name it with --info-topic"
        )
    return depth, info


def replay(inp: Path, out: Path, opts: ReplayOptions | None = None, show_progress: bool = True) -> ReplayReport:
    """Replays ``inp`` into a new bag ``out`` (never the input; written to a temporary file, then renamed)."""
    from rosbags.rosbag1 import Writer

    opts = opts or ReplayOptions()
    inp, out = Path(inp), Path(out)
    if not inp.exists():
        raise ReplayError(f"{inp}: no such bag")
    if out.exists() and (out.resolve() == inp.resolve() or os.path.samefile(out, inp)):
        raise ReplayError(f"output {out} is the input: the replay never overwrites its input")
    if out.exists():
        raise ReplayError(f"output {out} exists: remove it or choose another name")
    ts = _typestore()
    T = ts.types
    report = ReplayReport()
    tmp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    started = time.monotonic()
    reader = open_bag(inp)
    try:
        depth_topic, info_topic = _pick_topics(list(reader.connections), opts)
        ns = depth_topic.rsplit("/", 2)[0] if depth_topic.count("/") >= 2 else ""
        scan_topic = opts.scan_topic or f"{ns}/scan"
        cleaned_topic = opts.cleaned_topic or f"{depth_topic}/processed"
        report.depth_topic, report.scan_topic = depth_topic, scan_topic
        frames_total = sum(c.msgcount for c in reader.connections if c.topic == depth_topic)
        tf = TfBuffer()
        # tf first (a frame may come before the transform at its stamp): read all of it.
        for conn, _, raw in _messages(
            reader, [c for c in reader.connections if c.topic in ("/tf", "/tf_static")], opts, report
        ):
            tf.add(ts.deserialize_ros1(raw, conn.msgtype), static=conn.topic == "/tf_static")
        config = _core.Config(**opts.config)
        pipe: _core.Pipeline | None = None
        camera: Any = None
        infos: dict[float, Any] = {}
        with Writer(tmp) as w:
            outs: dict[int, Any] = {}
            for c in reader.connections:
                outs[c.id] = w.add_connection(
                    c.topic,
                    c.msgtype,
                    msgdef=c.msgdef.data,
                    md5sum=c.digest,
                    callerid=getattr(c.ext, "callerid", None),
                    latching=getattr(c.ext, "latching", None),
                )
            c_scan = w.add_connection(scan_topic, "sensor_msgs/msg/LaserScan", typestore=ts)
            c_clean = w.add_connection(cleaned_topic, "sensor_msgs/msg/Image", typestore=ts)
            it: Iterator[Any] = _messages(reader, list(reader.connections), opts, report)
            if show_progress:
                from .demo import progress

                it = _progress_frames(it, depth_topic, frames_total, progress)
            for conn, t_ns, raw in it:
                w.write(outs[conn.id], t_ns, raw)
                if conn.topic == info_topic:
                    msg = ts.deserialize_ros1(raw, conn.msgtype)
                    infos[_stamp(msg.header)] = msg
                    continue
                if conn.topic != depth_topic:
                    continue
                report.frames += 1
                img = ts.deserialize_ros1(raw, conn.msgtype)
                stamp = _stamp(img.header)
                info = infos.get(stamp) or (infos[max(infos)] if infos else None)
                if info is None:
                    report.problems.append(f"{depth_topic} at {stamp:.3f} s: no camera_info yet; frame skipped")
                    continue
                cam = camera_from_info(info)
                if pipe is None or repr(cam) != repr(camera):
                    pipe, camera = _core.Pipeline(cam, config), cam
                try:
                    depth = image_to_array(img)
                except ReplayError as exc:
                    report.problems.append(f"{depth_topic} at {stamp:.3f} s: {exc}")
                    continue
                try:
                    q, tr = tf.lookup(opts.base_frame, img.header.frame_id, stamp, opts.tf_tolerance)
                    height, pitch, roll, _ = _core.pose_from_optical_transform((q, tr), opts.base_frame_height)
                    res = pipe.process_pose(depth, height, pitch, roll)
                    report.pose_from_tf += 1
                except LookupError as exc:
                    if opts.pose_fallback == "skip":
                        report.skipped_no_pose += 1
                        report.problems.append(f"{depth_topic} at {stamp:.3f} s: {exc}; frame skipped")
                        continue
                    report.pose_fallback += 1
                    if report.pose_fallback == 1:
                        report.problems.append(f"{depth_topic} at {stamp:.3f} s: {exc}; static pose used (and later)")
                    res = pipe.process(depth)
                report.processed += 1
                _write_outputs(w, ts, T, c_scan, c_clean, t_ns, img, res, opts.scan_frame)
        report.seconds = time.monotonic() - started
        os.replace(tmp, out)
        return report
    finally:
        reader.close()
        if tmp.exists():
            tmp.unlink()


def _progress_frames(it: Iterator[Any], depth_topic: str, total: int, progress: Any) -> Iterator[Any]:
    """Advances the progress bar by depth frames, not by messages."""
    bar = iter(progress(range(total), total, "replay"))
    for item in it:
        if item[0].topic == depth_topic:
            next(bar, None)
        yield item
    for _ in bar:
        pass


def _messages(reader: Any, connections: list[Any], opts: ReplayOptions, report: ReplayReport) -> Iterator[Any]:
    """Messages in time order; a damaged chunk stops with a message naming topic and position, or is skipped."""
    from rosbags.rosbag1 import ReaderError

    if not connections:
        return
    count = 0
    gen = reader.messages(connections=connections)
    while True:
        try:
            conn, t_ns, raw = next(gen)
        except StopIteration:
            return
        except (ReaderError, ValueError, KeyError, IndexError) as exc:
            where = f"after message {count} (bag time {_last_time(report):.3f} s)"
            if not opts.skip_bad:
                raise ReplayError(f"{reader.path}: damaged data {where}: {exc} (use --skip-bad to go on)") from exc
            report.bad_messages += 1
            report.problems.append(f"damaged data {where}: {exc}; the rest of that chunk was skipped")
            return
        count += 1
        report.__dict__["_last_ns"] = t_ns
        yield conn, t_ns, raw


def _last_time(report: ReplayReport) -> float:
    return float(report.__dict__.get("_last_ns", 0)) * 1e-9


def _write_outputs(
    w: Any, ts: Any, T: Any, c_scan: Any, c_clean: Any, t_ns: int, img: Any, res: Any, frame: str
) -> None:
    Header = T["std_msgs/msg/Header"]
    header = Header(seq=img.header.seq, stamp=img.header.stamp, frame_id=frame)
    scan = T["sensor_msgs/msg/LaserScan"](
        header=header,
        angle_min=float(res.angle_min),
        angle_max=float(res.angle_max),
        angle_increment=float(res.angle_increment),
        time_increment=0.0,
        scan_time=0.0,
        range_min=float(res.range_min),
        range_max=float(res.range_max),
        ranges=res.ranges,
        intensities=res.intensities,
    )
    w.write(c_scan, t_ns, ts.serialize_ros1(scan, "sensor_msgs/msg/LaserScan"))
    depth = np.ascontiguousarray(res.depth)
    clean = T["sensor_msgs/msg/Image"](
        header=img.header,
        height=depth.shape[0],
        width=depth.shape[1],
        encoding=img.encoding,
        is_bigendian=0,
        step=depth.strides[0],
        data=depth.view(np.uint8).reshape(-1),
    )
    w.write(c_clean, t_ns, ts.serialize_ros1(clean, "sensor_msgs/msg/Image"))


def format_report(r: ReplayReport) -> str:
    rate = r.processed / r.seconds if r.seconds > 0 else math.nan
    lines = [
        f"{r.processed} of {r.frames} frames of {r.depth_topic} -> {r.scan_topic} in {r.seconds:.1f} s "
        f"({rate:.1f} frames/s); pose from tf {r.pose_from_tf}, fallback {r.pose_fallback}, "
        f"skipped without pose {r.skipped_no_pose}, damaged {r.bad_messages}"
    ]
    lines += [f"  note: {p}" for p in r.problems[:20]]
    return "\n".join(lines)
