"""Offline replay: run the core over a ROS 1 bag (read and written with the PyPI ``rosbags`` library) at the pose the
bag's tf gives at each frame's stamp, and write the scan and cleaned image next to the input topics in a new bag."""

from __future__ import annotations

import bisect
import math
import os
import time
from collections import defaultdict, deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from .bagfile import Bag, BagError, Damage
from .outputs import OutputError, check_outputs

Tf = tuple[tuple[float, float, float, float], tuple[float, float, float]]

DTYPES = {"8UC1": np.uint8, "mono8": np.uint8, "16UC1": np.uint16, "mono16": np.uint16, "32FC1": np.float32}


ReplayError = BagError  #: a bag or an option the replay cannot use; the message says which and why


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
    reused: int = 0  #: frames taken from the earlier run (--resume)
    warm_up: int = 0  #: frames re-processed to restore the confidence history on resuming
    stopped_early: bool = False  #: stopped at max_frames
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


def open_bag(path: Path, recover: bool = False) -> Bag:
    """A bag opened for reading; a file that is no readable ROS 1 bag, or damaged data in it, raises ReplayError
    naming the file, the byte offset and the topic. ``recover`` reads what is intact of a damaged bag instead."""
    return Bag(path, recover=recover)


def read_tf(bag: Bag, on_damage: Any = None) -> TfBuffer:
    """All of the bag's /tf and /tf_static (a frame may come before the transform at its stamp). A message that
    cannot be decoded is a damaged record: raised as ReplayError, or given to ``on_damage`` and skipped."""
    ts = _typestore()
    tf = TfBuffer()
    conns = [c for c in bag.connections if c.topic in ("/tf", "/tf_static")]
    for conn, _, raw, off in bag.records(conns, on_damage) if conns else ():
        try:
            msg = ts.deserialize_ros1(raw, conn.msgtype)
        except Exception as exc:  # rosbags raises several kinds on garbage
            damage = Damage(off, conn.topic, f"cannot be decoded as {conn.msgtype}: {exc}", lost=1)
            if on_damage is None:
                raise ReplayError(f"{bag.path}: damaged message record at {damage}") from exc
            on_damage(damage)
            continue
        tf.add(msg, static=conn.topic == "/tf_static")
    return tf


def depth_frames(bag: Bag, depth_topic: str, info_topic: str, progress_name: str | None = None) -> Iterator[Any]:
    """(depth Image, its CameraInfo) in time order: the camera_info of the same stamp, else the latest before;
    frames before any camera_info are left out. ``progress_name``: a progress bar (frames/s) with that name."""
    ts = _typestore()
    conns = [c for c in bag.connections if c.topic in (depth_topic, info_topic)]
    total = sum(c.msgcount for c in conns if c.topic == depth_topic)
    bar: Any = None
    if progress_name:
        from .demo import progress

        bar = iter(progress(range(total), total, progress_name))
    infos: dict[float, Any] = {}
    for conn, _, raw in bag.messages(conns):
        msg = ts.deserialize_ros1(raw, conn.msgtype)
        st = _stamp(msg.header)
        if conn.topic == info_topic:
            infos[st] = msg
            continue
        if bar is not None:
            next(bar, None)
        info = infos.get(st) or (infos[max(infos)] if infos else None)
        if info is not None:
            yield msg, info
    for _ in bar or ():
        pass


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


META_TOPIC = "/kinect_pipeline/replay_info"  #: first message of every replay output: what made it (JSON)
#: after each processed frame's scan and cleaned image: what the floor refinement decided, and its state (JSON)
FLOOR_TOPIC = "/kinect_pipeline/floor_fit"


def partial_path(out: Path) -> Path:
    """Where a replay into ``out`` writes until it is complete (left behind when it was killed)."""
    return out.with_name(f".{out.name}.partial")


def _input_identity(path: Path) -> dict[str, Any]:
    import hashlib

    size = path.stat().st_size
    h = hashlib.sha256()
    with path.open("rb") as f:
        h.update(f.read(1 << 20))
        f.seek(max(0, size - (1 << 20)))
        h.update(f.read(1 << 20))
    return {"size": size, "sha256_head_tail": h.hexdigest()}


class _Frames:
    """The per-frame state of a replay: camera_info by stamp, the pipeline (made anew when the camera changes) and
    the frames it processed since then, so that a resumed replay can restore its confidence history exactly."""

    def __init__(self, ts: Any, tf: TfBuffer, opts: ReplayOptions, report: ReplayReport, depth_topic: str) -> None:
        self.ts, self.tf, self.opts, self.report, self.depth_topic = ts, tf, opts, report, depth_topic
        self.config = _core.Config(**opts.config)
        self.window = int(self.config.confidence_window)
        self.infos: dict[float, Any] = {}
        self.pipe: _core.Pipeline | None = None
        self.camera: Any = None
        self.since = 0  # frames processed by this camera's pipeline
        self.recent: deque[Any] = deque(maxlen=2 * self.window)
        # the floor refinement's state after each of the recent frames (None: not known)
        self.states: deque[tuple[Any, ...] | None] = deque(maxlen=2 * self.window)

    def info(self, msg: Any) -> None:
        self.infos[_stamp(msg.header)] = msg

    def _camera(self, img: Any) -> Any:
        stamp = _stamp(img.header)
        info = self.infos.get(stamp) or (self.infos[max(self.infos)] if self.infos else None)
        return None if info is None else camera_from_info(info)

    def _use(self, cam: Any) -> None:
        if self.camera is None or repr(cam) != repr(self.camera):
            self.pipe, self.camera, self.since = None, cam, 0
            self.recent.clear()
            self.states.clear()

    def process(self, img: Any, note: bool = True) -> Any:
        """The core's result for a depth Image at the tf pose of its stamp, or None when the frame is skipped."""
        stamp, report, opts = _stamp(img.header), self.report, self.opts
        cam = self._camera(img)
        if cam is None:
            if note:
                report.problems.append(f"{self.depth_topic} at {stamp:.3f} s: no camera_info yet; frame skipped")
            return None
        self._use(cam)
        if self.pipe is None:
            self.pipe = _core.Pipeline(cam, self.config)
        try:
            depth = image_to_array(img)
        except ReplayError as exc:
            if note:
                report.problems.append(f"{self.depth_topic} at {stamp:.3f} s: {exc}")
            return None
        try:
            q, tr = self.tf.lookup(opts.base_frame, img.header.frame_id, stamp, opts.tf_tolerance)
            height, pitch, roll, _ = _core.pose_from_optical_transform((q, tr), opts.base_frame_height)
            res = self.pipe.process_pose(depth, height, pitch, roll, stamp=stamp)
            report.pose_from_tf += note
        except LookupError as exc:
            if opts.pose_fallback == "skip":
                if note:
                    report.skipped_no_pose += 1
                    report.problems.append(f"{self.depth_topic} at {stamp:.3f} s: {exc}; frame skipped")
                return None
            if note:
                report.pose_fallback += 1
                if report.pose_fallback == 1:
                    report.problems.append(f"{self.depth_topic} at {stamp:.3f} s: {exc}; static pose used (and later)")
            res = self.pipe.process(depth, stamp=stamp)
        self.since += 1
        self.recent.append(img)
        self.states.append(self.pipe.floor_state)
        return res

    def processed_before(self, img: Any, floor_state: tuple[Any, ...] | None) -> None:
        """A frame whose outputs an earlier run wrote: follow the state without processing it."""
        cam = self._camera(img)
        if cam is not None:
            self._use(cam)
            self.since += 1
            self.recent.append(img)
            self.states.append(floor_state)

    def warm_up(self) -> int:
        """Re-processes the last frames before a resume so that the confidence history, and the slot each range
        sits in, is what an uninterrupted run has: those since the last multiple of the window that leaves at
        least a full window. Returns how many."""
        if self.camera is None or self.since == 0:
            return 0
        n, w = self.since, self.window
        start = 0 if n < w else ((n - w) // w) * w
        frames = list(self.recent)[-(n - start) :]
        self.pipe, self.since = _core.Pipeline(self.camera, self.config), start
        saved = list(self.recent)[: len(self.recent) - len(frames)]
        saved_states = list(self.states)[: len(self.states) - len(frames)]
        if start > 0:
            # the floor refinement continues from where the earlier run had it before these frames
            before = saved_states[-1] if saved_states else None
            if before is None:
                raise ReplayError("--resume: the earlier run did not record the floor refinement's state: start anew")
            self.pipe.floor_state = before
        self.recent.clear()
        self.recent.extend(saved)
        self.states.clear()
        self.states.extend(saved_states)
        for img in frames:
            self.process(img, note=False)
        return len(frames)


class _Earlier:
    """The records an earlier, unfinished replay wrote (its partial file, or an output it stopped early), in the
    order they were written, up to its first damaged or missing part."""

    def __init__(self, bag: Bag) -> None:
        self.bag = bag
        limit = min((d.offset for d in bag.damage), default=None)
        entries = [e for e in bag.entries() if limit is None or bag.offset_of(e) < limit]
        self.entries = entries
        self.i = 0

    def peek(self, k: int = 0) -> tuple[str, int] | None:
        if self.i + k >= len(self.entries):
            return None
        e = self.entries[self.i + k]
        return self.bag.topic_of(e), e.time

    def take(self) -> bytes:
        e = self.entries[self.i]
        self.i += 1
        return self.bag.read(e)

    def meta(self) -> dict[str, Any] | None:
        import json

        head = self.peek()
        if head is None or head[0] != META_TOPIC:
            return None
        raw = self.take()
        try:
            text = _typestore().deserialize_ros1(raw, "std_msgs/msg/String").data
            return dict(json.loads(text))
        except (ValueError, TypeError, KeyError):
            return None


def _earlier_run(out: Path, tmp: Path, old: Path, meta: dict[str, Any]) -> tuple[_Earlier | None, list[str]]:
    """The earlier output to resume from: of ``out``, its partial file and the source of an interrupted resume,
    the one made with the same input and options that holds the most records."""
    best: _Earlier | None = None
    why: list[str] = []
    for path in (out, tmp, old):
        if not path.exists():
            continue
        try:
            bag = Bag(path, recover=True)
        except BagError as exc:
            why.append(str(exc))
            continue
        cand = _Earlier(bag)
        got = cand.meta()
        if got != meta:
            diff = (
                "no replay record"
                if got is None
                else ", ".join(sorted(k for k in set(got) | set(meta) if got.get(k) != meta.get(k)))
            )
            why.append(f"{path} is not a replay of this input with these options ({diff})")
            bag.close()
            continue
        if best is None or len(cand.entries) > len(best.entries):
            if best is not None:
                best.bag.close()
            best = cand
        else:
            bag.close()
    return best, why


def replay(
    inp: Path,
    out: Path,
    opts: ReplayOptions | None = None,
    show_progress: bool = True,
    resume: bool = False,
    max_frames: int | None = None,
) -> ReplayReport:
    """Replays ``inp`` into a new bag ``out`` (never the input; written to ``.OUT.partial``, then renamed).

    ``resume`` continues a replay into ``out`` that stopped (killed: its partial file; ``max_frames``: an output
    that ends early): the frames it wrote are taken as they are, the rest computed, with the same result as an
    uninterrupted run. ``max_frames`` stops after that many depth frames (a complete, shorter output)."""
    import json

    from rosbags.rosbag1 import Writer

    opts = opts or ReplayOptions()
    if not isinstance(opts, ReplayOptions):
        raise TypeError(f"opts: {type(opts).__name__}, expected ReplayOptions")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(max_frames, int)):
        raise TypeError(f"max_frames: {type(max_frames).__name__}, expected int")
    if max_frames is not None and max_frames < 1:
        raise ReplayError(f"max_frames = {max_frames}: expected >= 1")
    inp, out = Path(inp), Path(out)
    if not inp.exists():
        raise ReplayError(f"{inp}: no such bag")
    tmp = partial_path(out)
    old = tmp.with_name(tmp.name + ".old")
    try:
        check_outputs([inp], [out, tmp, old])
    except OutputError as exc:
        raise ReplayError(str(exc)) from exc
    if not resume:
        if out.exists():
            raise ReplayError(
                f"output {out} exists: remove it or choose another name (--resume continues a replay into it that "
                "stopped early)"
            )
        for p in (tmp, old):
            if p.exists():
                raise ReplayError(
                    f"{p} is left from a replay into {out} that was interrupted: --resume continues it, or remove it"
                )
    ts = _typestore()
    report = ReplayReport()
    started = time.monotonic()
    try:
        bag = open_bag(inp, recover=opts.skip_bad)
    except BagError as exc:
        if "intact messages" in str(exc):
            raise ReplayError(f"{exc} (--skip-bad replays them)") from exc
        raise
    earlier: _Earlier | None = None
    keep_partial = False
    written = False
    try:
        for d in bag.damage:
            report.bad_messages += d.lost or 0
            report.problems.append(f"damaged: {d}")
        depth_topic, info_topic = _pick_topics(list(bag.connections), opts)
        ns = depth_topic.rsplit("/", 2)[0] if depth_topic.count("/") >= 2 else ""
        scan_topic = opts.scan_topic or f"{ns}/scan"
        cleaned_topic = opts.cleaned_topic or f"{depth_topic}/processed"
        report.depth_topic, report.scan_topic = depth_topic, scan_topic
        meta = {
            "tool": "kinect-pipeline replay",
            "input": _input_identity(inp),
            "depth_topic": depth_topic,
            "info_topic": info_topic,
            "options": {k: v for k, v in vars(opts).items() if k != "skip_bad"},
        }

        def damaged(d: Damage) -> None:
            if not opts.skip_bad:
                raise ReplayError(f"{inp}: damaged message record at {d} (use --skip-bad to go on)")
            report.bad_messages += 1
            report.problems.append(f"damaged, skipped: {d}")

        def decode(conn: Any, raw: bytes, offset: int) -> Any:
            try:
                return ts.deserialize_ros1(raw, conn.msgtype)
            except Exception as exc:  # rosbags raises several kinds on garbage
                damaged(Damage(offset, conn.topic, f"cannot be decoded as {conn.msgtype}: {exc}", lost=1))
                return None

        tf = read_tf(bag, damaged)
        if resume:
            earlier, why = _earlier_run(out, tmp, old, meta)
            if earlier is None:
                raise ReplayError(
                    "--resume: nothing to resume: "
                    + ("; ".join(why) if why else f"neither {out} nor {tmp} exists (start without --resume)")
                )
            if earlier.bag.path == tmp:  # read it while the continuation is written to tmp
                earlier.bag.close()
                os.replace(tmp, old)
                earlier = _Earlier(Bag(old, recover=True))
                earlier.meta()
            elif tmp.exists():
                tmp.unlink()  # a shorter partial than the one resumed from
        frames = _Frames(ts, tf, opts, report, depth_topic)
        frames_total = sum(c.msgcount for c in bag.connections if c.topic == depth_topic)
        if max_frames is not None:
            frames_total = min(frames_total, max_frames)
        with Writer(tmp) as w:
            outs: dict[int, Any] = {}
            for c in bag.connections:
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
            c_meta = w.add_connection(META_TOPIC, "std_msgs/msg/String", typestore=ts)
            c_floor = w.add_connection(FLOOR_TOPIC, "std_msgs/msg/String", typestore=ts)
            entries = bag.entries()
            first_ns = entries[0].time if entries else 0
            meta_msg = ts.types["std_msgs/msg/String"](data=json.dumps(meta, sort_keys=True))
            w.write(c_meta, first_ns, ts.serialize_ros1(meta_msg, "std_msgs/msg/String"))
            written = True
            it: Iterator[Any] = bag.records(on_damage=damaged)
            if show_progress:
                from .demo import progress

                it = _progress_frames(it, depth_topic, frames_total, progress)
            for conn, t_ns, raw, off in it:
                is_depth = conn.topic == depth_topic
                if is_depth and max_frames is not None and report.frames >= max_frames:
                    report.stopped_early = True
                    break
                if earlier is not None:
                    reused = _reuse(earlier, conn, t_ns, raw, is_depth, scan_topic, cleaned_topic)
                    if reused is None:  # the earlier run ends here: compute from this message on
                        report.warm_up = frames.warm_up()
                        earlier.bag.close()
                        earlier = None
                    else:
                        w.write(outs[conn.id], t_ns, raw)
                        if conn.topic == info_topic:
                            msg = decode(conn, raw, off)
                            if msg is not None:
                                frames.info(msg)
                        if is_depth:
                            report.frames += 1
                            report.reused += 1
                            if reused:
                                img = decode(conn, raw, off)
                                if img is not None:
                                    frames.processed_before(img, _floor_state(reused[2]))
                                w.write(c_scan, t_ns, reused[0])
                                w.write(c_clean, t_ns, reused[1])
                                w.write(c_floor, t_ns, reused[2])
                        continue
                w.write(outs[conn.id], t_ns, raw)
                if conn.topic == info_topic:
                    msg = decode(conn, raw, off)
                    if msg is not None:
                        frames.info(msg)
                    continue
                if not is_depth:
                    continue
                report.frames += 1
                img = decode(conn, raw, off)
                if img is None:
                    continue
                res = frames.process(img)
                if res is None:
                    continue
                report.processed += 1
                _write_outputs(w, ts, ts.types, c_scan, c_clean, t_ns, img, res, opts.scan_frame)
                w.write(c_floor, t_ns, _floor_record(ts, res, frames.pipe))
        report.seconds = time.monotonic() - started
        os.replace(tmp, out)
        old.unlink(missing_ok=True)
        return report
    except KeyboardInterrupt:
        keep_partial = written
        raise
    except OSError as exc:
        if exc.filename not in (None, str(tmp), str(old)):
            raise
        raise ReplayError(f"cannot write {out}: {exc.strerror or exc}") from exc
    finally:
        bag.close()
        if earlier is not None:
            earlier.bag.close()
        if tmp.exists() and not keep_partial:
            tmp.unlink()


def _reuse(
    earlier: _Earlier, conn: Any, t_ns: int, raw: bytes, is_depth: bool, scan_topic: str, cleaned_topic: str
) -> tuple[bytes, bytes, bytes] | tuple[()] | None:
    """Takes this input message's records from the earlier run: () for a message without outputs, (scan, cleaned,
    floor fit) for a depth frame it processed, None where the earlier run ends (or ends inside this frame's
    records)."""
    head = earlier.peek()
    if head is None:
        return None
    if head != (conn.topic, t_ns):
        raise ReplayError(
            f"{earlier.bag.path}: record {earlier.i} is {head[0]} at {head[1] / 1e9:.9f} s, where this replay writes "
            f"{conn.topic} at {t_ns / 1e9:.9f} s: it was not made from this input; remove it"
        )
    if not is_depth:
        if earlier.take() != raw:
            raise ReplayError(f"{earlier.bag.path}: {conn.topic} at {t_ns / 1e9:.9f} s differs from the input's")
        return ()
    nxt, nxt2, nxt3 = earlier.peek(1), earlier.peek(2), earlier.peek(3)
    if nxt is None:
        return None  # processed or not: cannot tell
    if nxt == (scan_topic, t_ns):
        if nxt2 != (cleaned_topic, t_ns) or nxt3 != (FLOOR_TOPIC, t_ns):
            return None  # cut between the frame's outputs
        earlier.take()
        return earlier.take(), earlier.take(), earlier.take()
    earlier.take()
    return ()  # skipped by the earlier run (no pose, no camera_info): the next record is the next input message


def _floor_record(ts: Any, res: Any, pipe: Any) -> bytes:
    """The floor refinement of a frame as JSON: its decision and correction, and the state the next frame starts
    from (floats as repr, so that a resumed replay continues from the same bits)."""
    import json

    f = res.floor_fit
    rec = {
        "reason": f.reason,
        "pixels": f.pixels,
        "correction": list(f.correction),
        "learned": list(f.learned),
        "pose": list(res.pose),
        "state": [repr(v) if v is not None else None for v in pipe.floor_state],
    }
    msg = ts.types["std_msgs/msg/String"](data=json.dumps(rec, sort_keys=True))
    return bytes(ts.serialize_ros1(msg, "std_msgs/msg/String"))


def _floor_state(raw: bytes) -> tuple[Any, ...] | None:
    """The state a _floor_record holds, None if it cannot be read."""
    import json

    try:
        state = json.loads(_typestore().deserialize_ros1(raw, "std_msgs/msg/String").data)["state"]
        return tuple(None if v is None else float(v) for v in state)
    except (ValueError, TypeError, KeyError):
        return None


def _progress_frames(it: Iterator[Any], depth_topic: str, total: int, progress: Any) -> Iterator[Any]:
    """Advances the progress bar (frames/s) by depth frames, not by messages."""
    bar = iter(progress(range(total), total, "replay"))
    for item in it:
        if item[0].topic == depth_topic:
            next(bar, None)
        yield item
    for _ in bar:
        pass


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
    if r.reused:
        lines.append(
            f"  resumed: {r.reused} frames taken from the earlier run, {r.warm_up} re-processed for the confidence "
            f"history, {r.processed} computed"
        )
    if r.stopped_early:
        lines.append(f"  stopped after {r.frames} frames (--max-frames): --resume continues it")
    lines += [f"  note: {p}" for p in r.problems[:20]]
    return "\n".join(lines)
