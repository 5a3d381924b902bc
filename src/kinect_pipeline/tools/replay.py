"""Offline replay: run the core over a bag (ROS 1, rosbag2 sqlite3 or mcap; read and written with the PyPI
``rosbags`` library) at the pose the bag's tf gives at each frame's stamp, and write the scan, the cliff scan and the
cleaned image next to the input's messages in a new bag, in the input's format unless told otherwise."""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import _core
from ..bags.messages import IMAGE, LASER_SCAN, depth_array, header, image_message, stamp
from ..bags.reader import ROS1, BagReader, Cameras, image_topic_of, open_bag, pick_topics
from ..bags.ros1 import Bag, BagError, Damage
from ..bags.tf import TfBuffer, read_tf
from ..bags.writer import BagWriter, output_format
from ..intrinsics import Intrinsics
from ..outputs import OutputError, check_outputs

ReplayError = BagError  #: a bag or an option the replay cannot use; the message says which and why

__all__ = [
    "META_TOPIC",
    "ReplayError",
    "ReplayOptions",
    "ReplayReport",
    "TfBuffer",
    "format_report",
    "open_bag",
    "partial_path",
    "read_tf",
    "replay",
]


@dataclass
class ReplayOptions:
    depth_topic: str | None = None  #: default: the only depth topic whose name contains "depth"
    info_topic: str | None = None  #: default: camera_info beside the depth topic
    base_frame: str = "base_footprint"
    base_frame_height: float = 0.0
    scan_topic: str | None = None  #: default: <camera namespace>/scan
    cliff_topic: str | None = None  #: default: <camera namespace>/cliff_scan (written when cliff_scan is on)
    cleaned_topic: str | None = None  #: default: <depth image topic>/processed
    scan_frame: str = "kinect2_scan"
    pose_fallback: str = "static"  #: static | skip
    tf_tolerance: float = 0.1  #: how far beyond the first/last transform a stamp may be [s]
    skip_bad: bool = False  #: skip messages that cannot be read instead of stopping
    format: str | None = None  #: output format (ros1, sqlite3, mcap); default: the input's
    config: dict[str, Any] = field(default_factory=dict)  #: Config fields
    #: fx, fy, cx, cy [px] (and width, height; 0: the images'): the depth camera where the bag has no CameraInfo
    #: (they win over one it has); without them and without a camera_info, config's sensor_model's nominal camera
    intrinsics: list[float] | None = None
    #: the intrinsics' lens (a camera_info YAML's distortion and projection: ``Intrinsics.lens``), or None
    lens: dict[str, Any] | None = None
    #: images rectified by their camera_info's distortion: auto (unless the topic's name holds "rect"), always, never
    rectify: str = "auto"

    def cameras(self, bag: BagReader, info_topic: str | None, on_damage: Any = None) -> Cameras:
        """Where each frame's camera comes from (:class:`kinect_pipeline.bags.Cameras`)."""
        intr = None if self.intrinsics is None else Intrinsics.from_list(self.intrinsics).with_lens(self.lens)
        return Cameras(bag, info_topic, intr, self.config.get("sensor_model"), on_damage, self.rectify)

    def topics(self, bag: BagReader) -> tuple[str, str | None]:
        """The depth topic and its camera_info topic (None where the intrinsics come from elsewhere)."""
        need = self.intrinsics is None and not self.config.get("sensor_model")
        return pick_topics(list(bag.connections), self.depth_topic, self.info_topic, need_info=need)


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
    cliff_topic: str = ""  #: "" when the cliff scan is off
    format: str = ""  #: of the output
    camera: str = ""  #: where the frames' camera came from
    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)  #: results that rest on a guess (the nominal camera)


META_TOPIC = "/kinect_pipeline/replay_info"  #: first message of every replay output: what made it (JSON)
#: after each processed frame's outputs: what the floor refinement decided, and its state (JSON)
FLOOR_TOPIC = "/kinect_pipeline/floor_fit"
STRING = "std_msgs/msg/String"


def partial_path(out: Path) -> Path:
    """Where a replay into ``out`` writes until it is complete (left behind when it was killed)."""
    out = Path(out)
    return out.with_name(f".{out.name}.partial")


def _input_identity(path: Path) -> dict[str, Any]:
    """Size and a hash of the first and last MiB of the input (of each file of a rosbag2 folder)."""
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    size, h = 0, hashlib.sha256()
    for f in files:
        n = f.stat().st_size
        size += n
        with f.open("rb") as fh:
            h.update(fh.read(1 << 20))
            fh.seek(max(0, n - (1 << 20)))
            h.update(fh.read(1 << 20))
    return {"size": size, "sha256_head_tail": h.hexdigest()}


class _Frames:
    """The per-frame state of a replay: camera_info by stamp, the pipeline (made anew when the camera changes) and
    the frames it processed since then, so that a resumed replay can restore its confidence history exactly."""

    def __init__(self, bag: BagReader, tf: TfBuffer, cameras: Cameras, opts: ReplayOptions, report: ReplayReport):
        self.bag, self.tf, self.cameras, self.opts, self.report = bag, tf, cameras, opts, report
        self.depth_topic = report.depth_topic
        self.config = _core.Config(**opts.config)
        self.window = int(self.config.confidence_window)
        self.pipe: _core.Pipeline | None = None
        self.camera: Any = None
        self.since = 0  # frames processed by this camera's pipeline
        self.recent: deque[Any] = deque(maxlen=2 * self.window)
        # the floor refinement's state after each of the recent frames (None: not known)
        self.states: deque[tuple[Any, ...] | None] = deque(maxlen=2 * self.window)
        self.info_notes: set[str] = set()

    def _note(self, at: float, what: str, note: bool) -> None:
        if note:
            self.report.problems.append(f"{self.depth_topic} at {at:.3f} s: {what}")

    def _camera(self, img: Any, note: bool) -> tuple[Any, Any]:
        """The frame's camera and the image to process (rectified where the camera_info says so)."""
        cam, depth, why = self.cameras.for_frame(img, depth_array(img), self.depth_topic)
        if why and note and not self.info_notes:
            self.info_notes.add(why)
            self._note(stamp(img), f"{why} (and maybe for later frames)", note)
        return cam, depth

    def _use(self, cam: Any) -> None:
        if self.camera is None or repr(cam) != repr(self.camera):
            self.pipe, self.camera, self.since = None, cam, 0
            self.recent.clear()
            self.states.clear()

    def process(self, img: Any, note: bool = True) -> Any:
        """The core's result for a depth message at the tf pose of its stamp, or None when the frame is skipped."""
        at = stamp(img)
        try:
            cam, depth = self._camera(img, note)
        except BagError as exc:
            self._note(at, f"{exc}; frame skipped", note)
            return None
        self._use(cam)
        if self.pipe is None:
            self.pipe = _core.Pipeline(cam, self.config)
        try:
            pose, why = self._pose(img, at, note)
        except LookupError:
            return None
        try:
            res = self.pipe.process(depth, stamp=at) if pose is None else self.pipe.process_pose(depth, *pose, stamp=at)
        except ValueError as exc:  # the core refused it (its size against the camera_info's, float millimetres)
            self._note(at, f"refused by the core: {exc}; frame skipped", note)
            return None
        if note:
            self.report.pose_from_tf += pose is not None
            self.report.pose_fallback += pose is None
            if self.report.pose_fallback == 1 and pose is None:
                self._fell_back(at, why)
        self.since += 1
        self.recent.append(img)
        self.states.append(self.pipe.floor_state)
        return res

    def _pose(self, img: Any, at: float, note: bool) -> tuple[tuple[float, float, float] | None, str]:
        """The tf pose (height, pitch, roll) of the frame, or None and why for the static one of the Config; raises
        LookupError where there is none and the frame is to be skipped (--pose-fallback skip)."""
        opts = self.opts
        try:
            q, tr = self.tf.lookup(opts.base_frame, img.header.frame_id, at, opts.tf_tolerance)
            height, pitch, roll, _ = _core.pose_from_optical_transform((q, tr), opts.base_frame_height)
            return (height, pitch, roll), ""
        except LookupError as exc:
            if opts.pose_fallback == "skip":
                if note:
                    self.report.skipped_no_pose += 1
                self._note(at, f"{exc}; frame skipped", note)
                raise
            return None, str(exc)

    def _fell_back(self, at: float, why: str) -> None:
        """The first frame processed at the static pose: said once, with a warning where that pose is a guess."""
        self._note(at, f"{why}; static pose used (and later)", True)
        if not any(k in self.opts.config for k in ("sensor_height", "sensor_pitch", "sensor_roll")):
            self.report.warnings.append(
                f"frames without tf (the first at {at:.3f} s) were processed at the Config's default pose "
                f"(height {self.config.sensor_height:g} m, pitch {self.config.sensor_pitch:g}, roll "
                f"{self.config.sensor_roll:g} rad), not this camera's: give it with --param sensor_height="
                "H --param sensor_pitch=P --param sensor_roll=R (calibrate --bag gives the floor's), or "
                "--pose-fallback skip"
            )

    def processed_before(self, img: Any, floor_state: tuple[Any, ...] | None) -> None:
        """A frame whose outputs an earlier run wrote: follow the state without processing it."""
        try:
            cam, _ = self._camera(img, note=False)
        except BagError:
            return
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
    order they were written, up to its first damaged or missing part (ROS 1 outputs)."""

    def __init__(self, bag: Bag) -> None:
        self.bag = bag
        limit = min((d.offset for d in bag.damage), default=None)
        self.entries = [e for e in bag.entries() if limit is None or bag.offset_of(e) < limit]
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

    def frames(self, depth_topic: str) -> int:
        """The depth frames it holds."""
        return sum(1 for e in self.entries if self.bag.topic_of(e) == depth_topic)

    def meta(self) -> dict[str, Any] | None:
        from ..bags.messages import typestore

        head = self.peek()
        if head is None or head[0] != META_TOPIC:
            return None
        raw = self.take()
        try:
            return dict(json.loads(typestore(False).deserialize_ros1(raw, STRING).data))
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


def _check_call(inp: Path, out: Path, opts: Any, max_frames: Any) -> ReplayOptions:
    opts = opts or ReplayOptions()
    if not isinstance(opts, ReplayOptions):
        raise TypeError(f"opts: {type(opts).__name__}, expected ReplayOptions")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(max_frames, int)):
        raise TypeError(f"max_frames: {type(max_frames).__name__}, expected int")
    if max_frames is not None and max_frames < 1:
        raise ReplayError(f"max_frames = {max_frames}: expected >= 1")
    if not inp.exists():
        raise ReplayError(f"{inp}: no such bag")
    tmp = partial_path(out)
    try:
        check_outputs([inp], [out, tmp, tmp.with_name(tmp.name + ".old")])
    except OutputError as exc:
        raise ReplayError(str(exc)) from exc
    return opts


def replay(
    inp: Path,
    out: Path,
    opts: ReplayOptions | None = None,
    show_progress: bool = True,
    resume: bool = False,
    max_frames: int | None = None,
) -> ReplayReport:
    """Replays ``inp`` into a new bag ``out`` (never the input; written to ``.OUT.partial``, then renamed), in
    ``opts.format`` or the input's format. A bag from which no frame could be processed raises ReplayError saying
    why, and writes nothing.

    ``resume`` continues a replay into a ROS 1 ``out`` that stopped (killed: its partial file; ``max_frames``: an
    output that ends early): the frames it wrote are taken as they are, the rest computed, with the same result as
    an uninterrupted run. ``max_frames`` stops after that many depth frames (a complete, shorter output)."""
    inp, out = Path(inp), Path(out)
    opts = _check_call(inp, out, opts, max_frames)
    tmp = partial_path(out)
    old = tmp.with_name(tmp.name + ".old")
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
    try:
        bag = open_bag(inp, recover=opts.skip_bad)
    except BagError as exc:
        if "intact messages" in str(exc):
            raise ReplayError(f"{exc} (--skip-bad replays them)") from exc
        raise
    run = _Run(bag, inp, out, opts, max_frames)
    try:
        return run.go(resume, show_progress)
    except OSError as exc:
        if exc.filename not in (None, str(tmp), str(old)) and not str(exc.filename).startswith(str(tmp)):
            raise
        raise ReplayError(f"cannot write {out}: {exc.strerror or exc}") from exc
    finally:
        run.close()


class _Run:
    """One replay: the input, the output being written, the earlier run it resumes, and the report."""

    def __init__(self, bag: BagReader, inp: Path, out: Path, opts: ReplayOptions, max_frames: int | None) -> None:
        self.bag, self.inp, self.out, self.opts, self.max_frames = bag, inp, out, opts, max_frames
        self.tmp = partial_path(out)
        self.old = self.tmp.with_name(self.tmp.name + ".old")
        self.report = r = ReplayReport()
        self.earlier: _Earlier | None = None
        self.keep_partial = False
        self.writing = False  # whether this run has begun writing self.tmp
        self.started = time.monotonic()
        for d in bag.damage:
            r.bad_messages += d.lost or 0
            r.problems.append(f"damaged: {d}")
        r.format = output_format(out, bag.format, opts.format)
        depth, self.info_topic = opts.topics(bag)
        image = image_topic_of(depth)
        ns = image.rsplit("/", 2)[0] if image.count("/") >= 2 else ""
        r.depth_topic, r.scan_topic = depth, opts.scan_topic or f"{ns}/scan"
        r.cliff_topic = (opts.cliff_topic or f"{ns}/cliff_scan") if _core.Config(**opts.config).cliff_scan else ""
        self.cleaned_topic = opts.cleaned_topic or f"{image}/processed"
        self.out_topics = [t for t in (r.scan_topic, r.cliff_topic, self.cleaned_topic, FLOOR_TOPIC) if t]
        self.meta = {
            "tool": "kinect-pipeline replay",
            "input": _input_identity(inp),
            "depth_topic": depth,
            "info_topic": self.info_topic,
            "options": {k: v for k, v in vars(opts).items() if k != "skip_bad"},
        }

    def damaged(self, d: Damage) -> None:
        if not self.opts.skip_bad:
            raise ReplayError(f"{self.inp}: damaged message record at {d} (use --skip-bad to go on)")
        self.report.bad_messages += 1
        self.report.problems.append(f"damaged, skipped: {d}")

    def decode(self, conn: Any, raw: bytes, where: int) -> Any:
        try:
            return self.bag.decode(conn, raw)
        except Exception as exc:  # rosbags raises several kinds on garbage
            self.damaged(Damage(where, conn.topic, f"cannot be decoded as {conn.msgtype}: {exc}", lost=1))
            return None

    def _start_resume(self) -> None:
        if self.report.format != ROS1:
            raise ReplayError(f"--resume continues ROS 1 outputs only; {self.out} is a {self.report.format} bag")
        self.earlier, why = _earlier_run(self.out, self.tmp, self.old, self.meta)
        if self.earlier is None:
            raise ReplayError(
                "--resume: nothing to resume: "
                + ("; ".join(why) if why else f"neither {self.out} nor {self.tmp} exists (start without --resume)")
            )
        held = self.earlier.frames(self.report.depth_topic)
        total = self.bag.count(self.report.depth_topic)
        if self.max_frames is None and self.earlier.bag.path == self.out and held >= total:
            raise ReplayError(
                f"--resume: {self.out} holds all {total} frames of the input already: nothing to continue"
            )
        if self.max_frames is not None and self.max_frames <= held:
            raise ReplayError(
                f"--resume with --max-frames {self.max_frames}: {self.earlier.bag.path} holds {held} frames already, "
                f"so there is nothing to continue: expected --max-frames above {held}, or none (a shorter output: "
                "replay into a new name)"
            )
        if self.earlier.bag.path == self.tmp:  # read it while the continuation is written to tmp
            self.earlier.bag.close()
            os.replace(self.tmp, self.old)
            self.earlier = _Earlier(Bag(self.old, recover=True))
            self.earlier.meta()
        elif self.tmp.exists():
            self.tmp.unlink()  # a shorter partial than the one resumed from

    def go(self, resume: bool, show_progress: bool) -> ReplayReport:
        r = self.report
        tf = read_tf(self.bag, self.damaged)
        cameras = self.opts.cameras(self.bag, self.info_topic, self.damaged)
        r.camera = cameras.source
        if resume:
            self._start_resume()
        self.frames = _Frames(self.bag, tf, cameras, self.opts, r)
        try:
            single = self.out.suffix.lower() in (".mcap", ".db3")
            self.writing = True  # from here on, self.tmp is this run's (close() removes it unless kept)
            with BagWriter(self.tmp, r.format, single_file=single, name=self.out.name) as w:
                self._write(w, show_progress)
            r.camera = cameras.source  # now with whether the frames were rectified
        except KeyboardInterrupt:
            self.keep_partial = r.format == ROS1 and self.tmp.exists()
            raise
        if r.processed == 0 and r.reused == 0:
            raise ReplayError(
                f"{self.inp}: no frame of {r.depth_topic} could be processed, of {r.frames}: "
                f"{reasons(r.problems) or 'the bag has none'}; nothing written"
            )
        r.seconds = time.monotonic() - self.started
        if cameras.warning:
            r.warnings.append(cameras.warning)
        os.replace(self.tmp, self.out)
        self.old.unlink(missing_ok=True)
        return r

    def _write(self, w: BagWriter, show_progress: bool) -> None:
        r, ts = self.report, w.typestore
        outs = {c.id: w.copy(self.bag, c) for c in self.bag.connections}
        r.problems += [f"not written: {s}" for s in w.skipped]
        kinds = {self.cleaned_topic: IMAGE, FLOOR_TOPIC: STRING}
        self.c_out = [w.add(t, kinds.get(t, LASER_SCAN)) for t in self.out_topics]
        c_meta = w.add(META_TOPIC, STRING)
        total = self.bag.count(r.depth_topic)
        total = min(total, self.max_frames) if self.max_frames is not None else total
        meta_msg = ts.types[STRING](data=json.dumps(self.meta, sort_keys=True))
        it: Iterator[Any] = self.bag.records(on_damage=self.damaged)
        if show_progress:
            from ..outputs import progress

            it = _progress_frames(it, r.depth_topic, total, progress)
        first = True
        for conn, t_ns, raw, where in it:
            if first:  # the record of what made this bag comes first, at the input's first time
                w.write(c_meta, t_ns, w.encode(meta_msg, STRING))
                first = False
            is_depth = conn.topic == r.depth_topic
            if is_depth and self.max_frames is not None and r.frames >= self.max_frames:
                r.stopped_early = True
                break
            if self.earlier is not None and self._reuse(w, outs, conn, t_ns, raw, where, is_depth):
                continue
            if outs[conn.id] is not None:
                w.write_copy(outs[conn.id], t_ns, raw)
            if not is_depth:
                continue
            r.frames += 1
            img = self.decode(conn, raw, where)
            res = None if img is None else self.frames.process(img)
            if res is not None:
                r.processed += 1
                messages = _outputs(ts.types, img, res, self.opts.scan_frame, r, self.frames.pipe)
                for c, (msg, msgtype) in zip(self.c_out, messages, strict=True):
                    w.write(c, t_ns, w.encode(msg, msgtype))

    def _reuse(
        self, w: BagWriter, outs: dict[int, Any], conn: Any, t_ns: int, raw: bytes, where: int, is_depth: bool
    ) -> bool:
        """Takes this input message's records from the earlier run; False where the earlier run ends (from here
        on, everything is computed)."""
        assert self.earlier is not None
        reused = _reuse(self.earlier, conn, t_ns, raw, is_depth, self.out_topics)
        if reused is None:
            self.report.warm_up = self.frames.warm_up()
            self.earlier.bag.close()
            self.earlier = None
            return False
        if outs[conn.id] is not None:
            w.write_copy(outs[conn.id], t_ns, raw)
        if is_depth:
            self.report.frames += 1
            self.report.reused += 1
            if reused:
                img = self.decode(conn, raw, where)
                if img is not None:
                    self.frames.processed_before(img, _floor_state(reused[-1]))
                for c, rec in zip(self.c_out, reused, strict=True):
                    w.write(c, t_ns, rec)
        return True

    def close(self) -> None:
        self.bag.close()
        if self.earlier is not None:
            self.earlier.bag.close()
        if self.writing and self.tmp.exists() and not self.keep_partial:
            if self.tmp.is_dir():
                import shutil

                shutil.rmtree(self.tmp)
            else:
                self.tmp.unlink()
        folder = self.tmp.with_name(self.tmp.name + ".d")  # a rosbag2 output's stage
        if folder.is_dir():
            import shutil

            shutil.rmtree(folder)


def _reuse(
    earlier: _Earlier, conn: Any, t_ns: int, raw: bytes, is_depth: bool, out_topics: list[str]
) -> tuple[bytes, ...] | None:
    """Takes this input message's records from the earlier run: () for a message without outputs, its output
    records for a depth frame it processed, None where the earlier run ends (or ends inside this frame's records)."""
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
    after = [earlier.peek(1 + k) for k in range(len(out_topics))]
    if after[0] is None:
        return None  # processed or not: cannot tell
    if after[0] == (out_topics[0], t_ns):
        if any(a != (t, t_ns) for a, t in zip(after, out_topics, strict=True)):
            return None  # cut between the frame's outputs
        earlier.take()
        return tuple(earlier.take() for _ in out_topics)
    earlier.take()
    return ()  # skipped by the earlier run (no pose, no camera_info): the next record is the next input message


def _progress_frames(it: Iterator[Any], depth_topic: str, total: int, progress: Any) -> Iterator[Any]:
    """Advances the progress bar (frames/s) by depth frames, not by messages."""
    bar = iter(progress(range(total), total, "replay"))
    for item in it:
        if item[0].topic == depth_topic:
            next(bar, None)
        yield item
    for _ in bar:
        pass


def _outputs(T: Any, img: Any, res: Any, frame: str, r: ReplayReport, pipe: Any) -> list[tuple[Any, str]]:
    """The messages of one processed frame, in the order of the output topics: scan, cliff scan (when on), cleaned
    depth image (the input's encoding; a compressedDepth input's decoded encoding), floor refinement record."""
    import numpy as np

    seq = getattr(img.header, "seq", 0)

    def scan(ranges: Any, intensities: Any) -> tuple[Any, str]:
        msg = T[LASER_SCAN](
            header=header(T, img.header.stamp, frame, seq),
            angle_min=float(res.angle_min),
            angle_max=float(res.angle_max),
            angle_increment=float(res.angle_increment),
            time_increment=0.0,
            scan_time=0.0,
            range_min=float(res.range_min),
            range_max=float(res.range_max),
            ranges=ranges,
            intensities=intensities,
        )
        return msg, LASER_SCAN

    out = [scan(res.ranges, res.intensities)]
    if r.cliff_topic:
        out.append(scan(res.cliff_ranges, np.zeros(0, np.float32)))
    encoding = getattr(img, "encoding", None) or {1: "8UC1", 2: "16UC1", 4: "32FC1"}[res.depth.itemsize]
    clean = image_message(T, header(T, img.header.stamp, img.header.frame_id, seq), res.depth, encoding)
    out.append((clean, IMAGE))
    out.append((T[STRING](data=_floor_record(res, pipe)), STRING))
    return out


def _floor_record(res: Any, pipe: Any) -> str:
    """The floor refinement of a frame as JSON: its decision and correction, and the state the next frame starts
    from (floats as repr, so that a resumed replay continues from the same bits)."""
    f = res.floor_fit
    rec = {
        "reason": f.reason,
        "pixels": f.pixels,
        "correction": list(f.correction),
        "learned": list(f.learned),
        "pose": list(res.pose),
        "state": [repr(v) if v is not None else None for v in pipe.floor_state],
    }
    return json.dumps(rec, sort_keys=True)


def _floor_state(raw: bytes) -> tuple[Any, ...] | None:
    """The state a floor record of a ROS 1 output holds, None if it cannot be read."""
    from ..bags.messages import typestore

    try:
        state = json.loads(typestore(False).deserialize_ros1(raw, STRING).data)["state"]
        return tuple(None if v is None else float(v) for v in state)
    except (ValueError, TypeError, KeyError):
        return None


def reasons(problems: list[str]) -> str:
    """Distinct reasons of per-frame problems ("<topic> at <t> s: why"), with how many frames each."""
    count: dict[str, int] = {}
    for p in problems:
        why = p.split(" s: ", 1)[-1]
        count[why] = count.get(why, 0) + 1
    return "; ".join(f"{why} ({n} frame{'s' * (n != 1)})" for why, n in list(count.items())[:4])


def format_report(r: ReplayReport) -> str:
    rate = r.processed / r.seconds if r.seconds > 0 else math.nan
    topics = r.scan_topic + (f" and {r.cliff_topic}" if r.cliff_topic else "")
    lines = [
        f"{r.processed} of {r.frames} frames of {r.depth_topic} -> {topics} ({r.format}) in {r.seconds:.1f} s "
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
    lines.append(f"  camera: {r.camera}")
    lines += [f"  note: {p}" for p in r.problems[:20]]
    return "\n".join(lines)
