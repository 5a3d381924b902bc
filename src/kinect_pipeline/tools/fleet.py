"""A fleet's recordings at once: one task per recording on Dask distributed (a LocalCluster, or a running cluster
given by its scheduler's address), the same per-frame machinery as ``replay`` (camera_info by stamp, the tf pose,
the floor refinement running through the recording in order), and per recording and configuration one row of
metrics: frames, time per frame, the floor fit's decisions, the learned correction and its drift, cliff and
phantom proxies, damage. Rows go to ``OUT/fleet.csv`` and ``OUT/fleet.json`` (atomically, after every recording),
so that a rerun skips what is done; ``fleet_html`` draws ``OUT/index.html``."""

from __future__ import annotations

import glob
import hashlib
import json
import math
import os
import time
import traceback
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core
from ..bags.messages import LASER_SCAN, stamp
from ..bags.reader import open_bag, read_side
from ..bags.ros1 import BagError, Damage
from ..bags.tf import read_tf
from ..evaluation.metrics import phantom_beams
from ..intrinsics import Intrinsics, IntrinsicsError
from ..outputs import write_text
from .calibrate import FRAME_SUFFIXES, calibrate, frame_paths, load_depth
from .replay import ReplayOptions, ReplayReport, _Frames, reasons

#: Columns of fleet.csv, in order (fleet.json has these and the learned correction over time).
COLUMNS = (
    "recording",
    "config",
    "status",
    "frames",
    "processed",
    "dropped",
    "damaged",
    "ms_per_frame",
    "core_ms",
    "fit_accepted",
    "fit_reasons",
    "learned_height_m",
    "learned_pitch_deg",
    "learned_roll_deg",
    "drift_height_m",
    "drift_pitch_deg",
    "drift_roll_deg",
    "cliff_beams",
    "phantom_proxy",
    "scan_change",
    "vs_config",
    "beams_moved",
    "fit_changed",
    "pose_fallback",
    "kind",
    "seconds",
    "worker",
    "input_size",
    "input_mtime_ns",
    "input_sha256",
    "config_hash",
    "notes",
)
EVENT_TOPIC = "kinect-pipeline-fleet"  #: progress events of the tasks (Dask worker events)
LIST_SUFFIXES = (".txt", ".lst", ".list")  #: a file of these names lists recordings, one a line
BAG_SUFFIXES = (".bag", ".mcap", ".db3")
#: statuses a rerun takes as final (the input decides them); rows with others ("error", "lost") are done again
FINAL = ("ok", "damaged", "unreadable")


SPAWN_ENV, TRIM = "distributed.nanny.pre-spawn-environ", "MALLOC_TRIM_THRESHOLD_"


class FleetError(ValueError):
    """An input or option the fleet cannot use: the message names it."""


# -- inputs ---------------------------------------------------------------------------------------------------------


def find_recordings(items: list[str]) -> list[Path]:
    """Recordings named by paths, globs (``*``, ``?``, ``[...]``, ``**``) and text files listing them (one a line,
    ``#`` comments; relative to the list's folder), in the order given, each once. A glob that matches nothing or a
    list that cannot be read raises FleetError; a path that does not exist is kept (its row says so)."""
    out: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_file() and p.suffix.lower() in LIST_SUFFIXES:
            out += _listed(p)
        elif any(ch in item for ch in "*?[") and not p.exists():
            found = sorted(glob.glob(item, recursive=True))
            if not found:
                raise FleetError(f"{item}: matches no file or folder")
            out += [Path(f) for f in found]
        else:
            out.append(p)
    seen: set[Path] = set()
    unique = []
    for p in out:
        key = p.absolute()
        if key not in seen:
            seen.add(key)
            unique.append(key)
    return unique


def _listed(path: Path) -> list[Path]:
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise FleetError(f"{path}: cannot read the list of recordings: {exc}") from exc
    found: list[Path] = []
    for line in lines:
        line = line.split("#", 1)[0].strip()
        if line:
            found += find_recordings([str(path.parent / line) if not Path(line).is_absolute() else line])
    if not found:
        raise FleetError(f"{path}: lists no recording: expected a path or glob a line ('#' starts a comment)")
    return found


def recording_kind(path: Path) -> str:
    """``bag`` (ROS 1, rosbag2 folder, .mcap/.db3 file) or ``frames`` (a folder of depth frames)."""
    if path.is_dir():
        if (path / "metadata.yaml").exists() or any(path.glob("*.mcap")) or any(path.glob("*.db3")):
            return "bag"
        if any(p.suffix.lower() in FRAME_SUFFIXES for p in path.iterdir()):
            return "frames"
        raise FleetError(f"{path}: a folder that is neither a rosbag2 bag nor a folder of depth frames")
    if path.suffix.lower() in FRAME_SUFFIXES:
        raise FleetError(f"{path}: a single depth frame; give the folder of a recording's frames")
    return "bag"


def input_identity(path: Path, checksum: bool = False) -> dict[str, Any]:
    """What a rerun compares: size and newest mtime of the file (of every file of a folder), and with ``checksum``
    a SHA-256 of the content."""
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    size = sum(f.stat().st_size for f in files)
    mtime = max((f.stat().st_mtime_ns for f in files), default=0)
    digest = ""
    if checksum:
        h = hashlib.sha256()
        for f in files:
            with f.open("rb") as fh:
                while block := fh.read(1 << 20):
                    h.update(block)
        digest = h.hexdigest()
    return {"input_size": size, "input_mtime_ns": mtime, "input_sha256": digest}


# -- configurations -------------------------------------------------------------------------------------------------


def config_hash(config: dict[str, Any], opts: FleetOptions) -> str:
    """Of every Config field as the core reads it (defaults included) and the options that change results."""
    cfg = _core.Config(**config).to_dict()
    cfg.pop("num_threads", None)
    what = {"config": cfg, "options": opts.identity()}
    return hashlib.sha256(json.dumps(what, sort_keys=True, default=str).encode()).hexdigest()[:16]


def load_config(path: Path, base: dict[str, Any]) -> dict[str, Any]:
    """Config fields of a YAML file (``name: value`` lines, as ``rosparam`` loads them; ``curve -o`` writes one)
    over ``base``; an unknown field or a value the core refuses raises FleetError naming the file and field."""
    import yaml

    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:  # one line, though YAML's message has several
        raise FleetError(f"{path}: cannot read a configuration: {' '.join(str(exc).split())}") from exc
    if not isinstance(data, dict):
        raise FleetError(f"{path}: expected a mapping of Config fields (name: value), got {type(data).__name__}")
    return check_config({**base, **data}, str(path))


def check_config(config: dict[str, Any], where: str) -> dict[str, Any]:
    fields = [*_core.Config().to_dict(), "sensor_model"]
    for name in config:
        if name not in fields:
            raise FleetError(f"{where}: no Config field {name!r}; the fields are {', '.join(fields)}")
    try:
        _core.Config(**config)
    except (TypeError, ValueError, RuntimeError) as exc:
        raise FleetError(f"{where}: {exc}") from exc
    return config


def grid_configs(base: dict[str, Any], spec: str) -> list[tuple[str, dict[str, Any]]]:
    """``FIELD=V1,V2,...``: the base configuration with each value of one field (values as JSON, else text)."""
    name, eq, values = spec.partition("=")
    if not eq or not name.strip() or not values.strip():
        raise FleetError(f"--grid {spec!r}: expected FIELD=VALUE1,VALUE2,...")
    out = []
    for text in values.split(","):
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text.strip()
        label = f"{name.strip()}={text.strip()}"
        out.append((label, check_config({**base, name.strip(): value}, f"--grid {label}")))
    return out


@dataclass
class FleetOptions:
    """What every task of a run shares: the bag options (as replay's; ``config`` is per configuration), the
    options of folders of frames, and the core threads per task."""

    replay: ReplayOptions = field(default_factory=ReplayOptions)
    #: fx, fy, cx, cy[, width, height] of folders of frames (else --sensor-model's)
    intrinsics: tuple[float, ...] | None = None
    sensor_model: str | None = None
    depth_scale: float = 0.001  #: of 16-bit frames [m per unit]
    frame_rate: float = 30.0  #: of folders of frames (the floor refinement's learning runs in time) [Hz]
    lidar_topic: str | None = None  #: default: the bag's LaserScan that is not ground truth
    threads: int = 1  #: core threads per task (one task per worker thread)
    checksum: bool = False  #: rerun identity by content, not only size and mtime
    event_every: float = 0.5  #: seconds between a task's progress events

    def identity(self) -> dict[str, Any]:
        r = self.replay
        return {
            "depth_topic": r.depth_topic,
            "info_topic": r.info_topic,
            "base_frame": r.base_frame,
            "base_frame_height": r.base_frame_height,
            "pose_fallback": r.pose_fallback,
            "skip_bad": r.skip_bad,
            "rectify": r.rectify,
            "lens": r.lens,
            "intrinsics": self.intrinsics,
            "sensor_model": self.sensor_model,
            "depth_scale": self.depth_scale,
            "frame_rate": self.frame_rate,
            "lidar_topic": self.lidar_topic,
        }


# -- one recording ------------------------------------------------------------------------------------------------


def _sigma(z: np.ndarray, model: str | None) -> np.ndarray:
    z = np.where(np.isfinite(z), z, 0.0)
    return np.asarray(_core.sensor_sigma(model, z) if model else _core.kinect_sigma(z))


def moved(a: np.ndarray, b: np.ndarray, model: str | None = None) -> np.ndarray:
    """Beams that differ by more than the noise: finite in one and not the other, or apart by more than
    1 cm + 4 sigma of the sensor at the nearer range."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    fa, fb = np.isfinite(a), np.isfinite(b)
    both = fa & fb
    near = np.where(both, np.minimum(a, b), 0.0)
    far_apart = np.abs(np.where(both, a - b, 0.0)) > 0.01 + 4.0 * _sigma(near, model)
    return (fa != fb) | (both & far_apart)


class _Track:
    """What one configuration's run through a recording adds up."""

    def __init__(self, name: str, config: dict[str, Any]) -> None:
        self.name, self.config = name, config
        self.model = config.get("sensor_model")
        self.frames = self.processed = 0
        self.seconds = 0.0
        self.core_ms: list[float] = []
        self.reasons: Counter[str] = Counter()
        self.learned: list[tuple[float, float, float, float]] = []  # stamp, height, pitch, roll
        self.cliff = self.beams = self.changed = self.compared = 0
        self.phantom = self.lidar_beams = 0
        self.moved = self.moved_of = self.fit_changed = 0
        self.prev: np.ndarray | None = None
        self.last: Any = None  # the last result (compared with the first configuration's)
        self.report = ReplayReport()

    def add(self, at: float, res: Any, seconds: float, lidar: np.ndarray | None) -> None:
        self.processed += 1
        self.seconds += seconds
        self.core_ms.append(float(res.times["total"]))
        fit = res.floor_fit
        self.reasons[fit.reason] += 1
        lh, lp, lr = (float(v) for v in fit.learned)
        self.learned.append((at, lh, lp, lr))
        r = np.asarray(res.ranges)
        self.beams += len(r)
        self.cliff += int(np.isfinite(res.cliff_ranges).sum()) if len(res.cliff_ranges) else 0
        if self.prev is not None and len(self.prev) == len(r):
            self.changed += int(moved(self.prev, r, self.model).sum())
            self.compared += len(r)
        self.prev = r.copy()
        if lidar is not None:
            has = np.isfinite(lidar)
            self.lidar_beams += int(has.sum())
            self.phantom += int((phantom_beams(r, lidar)[1] & has).sum())

    def compare(self, base: _Track) -> None:
        """This frame's result against the first configuration's on the same frame."""
        if self.last is None or base.last is None:
            return
        a, b = np.asarray(base.last.ranges), np.asarray(self.last.ranges)
        if len(a) == len(b):
            self.moved += int(moved(a, b, self.model).sum())
            self.moved_of += len(a)
        self.fit_changed += int(base.last.floor_fit.reason != self.last.floor_fit.reason)

    def metrics(self) -> dict[str, Any]:
        n = self.processed
        learned = np.array([x[1:] for x in self.learned]) if self.learned else np.zeros((0, 3))
        end = learned[-1] if n else np.full(3, math.nan)
        drift = learned.max(axis=0) - learned.min(axis=0) if n else np.full(3, math.nan)
        rep = self.report
        return {
            "processed": n,
            "dropped": self.frames - n,
            "ms_per_frame": 1000.0 * self.seconds / n if n else math.nan,
            "core_ms": float(np.median(self.core_ms)) if n else math.nan,
            "fit_accepted": self.reasons["accepted"] / n if n else math.nan,
            "fit_reasons": json.dumps(dict(sorted(self.reasons.items())), sort_keys=True),
            "learned_height_m": float(end[0]),
            "learned_pitch_deg": math.degrees(end[1]),
            "learned_roll_deg": math.degrees(end[2]),
            "drift_height_m": float(drift[0]),
            "drift_pitch_deg": math.degrees(drift[1]),
            "drift_roll_deg": math.degrees(drift[2]),
            "cliff_beams": self.cliff / self.beams if self.beams else math.nan,
            "phantom_proxy": self.phantom / self.lidar_beams if self.lidar_beams else math.nan,
            "scan_change": self.changed / self.compared if self.compared else math.nan,
            "beams_moved": self.moved / self.moved_of if self.moved_of else math.nan,
            "fit_changed": self.fit_changed / n if n and self.moved_of else math.nan,
            "pose_fallback": rep.pose_fallback + rep.skipped_no_pose,
            "series": _thin(self.learned),
        }


def _thin(series: list[tuple[float, float, float, float]], most: int = 300) -> list[list[float]]:
    """The learned correction over time, at most ``most`` points (for the plots)."""
    if not series:
        return []
    t0 = series[0][0]
    step = max(1, math.ceil(len(series) / most))
    keep = series[::step] + ([series[-1]] if (len(series) - 1) % step else [])
    return [[round(t - t0, 4), h, p, r] for t, h, p, r in keep]


class _Events:
    """Progress events of a task (frames done), sent through the Dask worker's event log at most every
    ``every`` seconds; nothing outside a worker."""

    def __init__(self, recording: str, every: float) -> None:
        from distributed import get_worker

        try:
            self.worker: Any = get_worker()
        except ValueError:
            self.worker = None
        self.recording, self.every, self.sent, self.frames = recording, every, -math.inf, 0

    @property
    def address(self) -> str:
        return str(self.worker.address) if self.worker is not None else ""

    def frame(self, done: bool = False) -> None:
        self.frames += not done
        now = time.monotonic()
        if self.worker is not None and (done or self.frames == 1 or now - self.sent >= self.every):
            self.sent = now
            msg = {"recording": self.recording, "frames": self.frames, "done": done, "worker": self.address}
            self.worker.log_event(EVENT_TOPIC, msg)


class _Damages:
    """Damage met while reading: raised unless ``skip_bad`` (then counted and named)."""

    def __init__(self, path: Path, skip_bad: bool) -> None:
        self.path, self.skip_bad, self.lost = path, skip_bad, 0
        self.notes: list[str] = []

    def __call__(self, d: Damage) -> None:
        if not self.skip_bad:
            raise BagError(f"{self.path}: damaged message record at {d} (--skip-bad goes on past it)")
        self.lost += d.lost or 1
        self.notes.append(f"damaged, skipped: {d}")


class _Lidar:
    """The bag's LiDAR scans (``topic``, default its LaserScan that is not ground truth), found by stamp."""

    def __init__(self, bag: Any, topic: str | None, damages: _Damages) -> None:
        topic = topic or next(
            (c.topic for c in bag.connections if c.msgtype == LASER_SCAN and not c.topic.startswith("/ground_truth")),
            None,
        )
        found = read_side(bag, (topic,), damages) if topic else iter(())
        scans = sorted(((stamp(m), m) for _, m in found), key=lambda x: x[0])
        self.stamps = np.array([s for s, _ in scans])
        self.scans = [m for _, m in scans]

    def nearest(self, at: float) -> Any:
        """The scan nearest in time to ``at`` (None: the bag has none)."""
        if not self.scans:
            return None
        i = int(np.searchsorted(self.stamps, at))
        near = [k for k in (i - 1, i) if 0 <= k < len(self.scans)]
        return self.scans[min(near, key=lambda k: abs(self.stamps[k] - at))]


def _lidar_beams(lidar: _Lidar, tf: Any, opts: ReplayOptions, img: Any, res: Any) -> np.ndarray | None:
    """The LiDAR scan nearest in time, as the range of its return nearest in bearing to each beam of the camera's
    scan, within one LiDAR step (+Inf: none)."""
    msg = lidar.nearest(stamp(img))
    if msg is None:
        return None
    try:
        lq, lt = tf.lookup(opts.base_frame, msg.header.frame_id, stamp(img), opts.tf_tolerance)
        cq, ct = tf.lookup(opts.base_frame, img.header.frame_id, stamp(img), opts.tf_tolerance)
    except LookupError:
        return None
    l_yaw = _core.roll_pitch_yaw(lq)[2]
    c_yaw = _core.pose_from_optical_transform((cq, ct), opts.base_frame_height)[3]
    r = np.asarray(msg.ranges, np.float64)
    a = msg.angle_min + msg.angle_increment * np.arange(len(r)) + l_yaw
    ok = np.isfinite(r) & (r >= msg.range_min) & (r <= msg.range_max)
    # the returns in the camera scan's frame: at the sensor's x, y, turned by its yaw
    x, y = lt[0] + r[ok] * np.cos(a[ok]) - ct[0], lt[1] + r[ok] * np.sin(a[ok]) - ct[1]
    beams = res.angle_min + res.angle_increment * np.arange(len(res.ranges))
    return _nearest_in_bearing(np.arctan2(y, x) - c_yaw, np.hypot(x, y), beams, abs(msg.angle_increment))


def _nearest_in_bearing(bearing: np.ndarray, dist: np.ndarray, beams: np.ndarray, within: float) -> np.ndarray:
    out = np.full(len(beams), np.inf)
    if not len(bearing):
        return out
    order = np.argsort(bearing)
    bearing, dist = bearing[order], dist[order]
    hi = np.clip(np.searchsorted(bearing, beams), 0, len(bearing) - 1)
    lo = np.clip(hi - 1, 0, len(bearing) - 1)
    j = np.where(np.abs(bearing[lo] - beams) <= np.abs(bearing[hi] - beams), lo, hi)
    near = np.abs(bearing[j] - beams) <= within
    out[near] = dist[j[near]]
    return out


def _run_bag(path: Path, opts: FleetOptions, tracks: list[_Track], events: _Events) -> tuple[int, list[str]]:
    """Every depth frame of a bag through replay's per-frame machinery, once per configuration. Returns the
    messages lost to damage and the notes."""
    damages = _Damages(path, opts.replay.skip_bad)
    with open_bag(path, recover=opts.replay.skip_bad) as bag:
        for d in bag.damage:
            damages(d)
        depth, info = opts.replay.topics(bag)
        tf = read_tf(bag, damages)
        cameras = opts.replay.cameras(bag, info, damages)
        lidar = _Lidar(bag, opts.lidar_topic, damages)
        frames = []
        for t in tracks:
            t.report.depth_topic = depth
            config = {"num_threads": opts.threads, **t.config}
            frames.append(_Frames(bag, tf, cameras, replace(opts.replay, config=config), t.report))
        conns = [c for c in bag.connections if c.topic == depth]
        for conn, _, raw, where in bag.records(conns, on_damage=damages):
            for t in tracks:
                t.frames += 1
            events.frame()
            try:
                img = bag.decode(conn, raw)
            except Exception as exc:  # rosbags raises several kinds on garbage
                damages(Damage(where, conn.topic, f"cannot be decoded as {conn.msgtype}: {exc}", lost=1))
                continue
            beams = None
            for t, f in zip(tracks, frames, strict=True):
                t0 = time.perf_counter()
                res = f.process(img)
                t.last = res
                if res is not None:
                    beams = _lidar_beams(lidar, tf, opts.replay, img, res) if beams is None else beams
                    t.add(stamp(img), res, time.perf_counter() - t0, beams)
            _compare(tracks)
    notes = damages.notes + [p for t in tracks[:1] for p in t.report.problems]
    return damages.lost, notes


def _compare(tracks: list[_Track]) -> None:
    """Each configuration's result of this frame against the first configuration's."""
    for t in tracks[1:]:
        t.compare(tracks[0])


def _frames_camera(opts: FleetOptions, shape: tuple[int, ...]) -> Any:
    if opts.intrinsics is not None:
        try:
            return Intrinsics.from_list(opts.intrinsics).camera(shape[1], shape[0])
        except IntrinsicsError as exc:
            raise FleetError(str(exc)) from exc
    if not opts.sensor_model:
        raise FleetError("a folder of depth frames needs --intrinsics FX FY CX CY (or --sensor-model NAME)")
    cam = _core.sensor_model(opts.sensor_model)["camera"]
    if (cam.height, cam.width) != tuple(shape[:2]):
        raise FleetError(
            f"--sensor-model {opts.sensor_model}: typical intrinsics for {cam.width}x{cam.height}, the frames are "
            f"{shape[1]}x{shape[0]}: give --intrinsics"
        )
    return cam


def _run_frames(path: Path, opts: FleetOptions, tracks: list[_Track], events: _Events) -> tuple[int, list[str]]:
    """A folder of depth frames in name order, at ``frame_rate``, at the pose of the configuration (or the one
    calibrated from the first frames' floor)."""
    files = frame_paths([path])
    first = load_depth(files[0], opts.depth_scale)
    camera = _frames_camera(opts, first.shape)
    notes: list[str] = []
    pipes = []
    for t in tracks:
        config = {"num_threads": opts.threads, **t.config}
        if not any(k in config for k in ("sensor_height", "sensor_pitch", "sensor_roll")):
            cal = calibrate([(str(f), load_depth(f, opts.depth_scale)) for f in files[:5]], camera)
            if not cal.found:
                raise FleetError(f"{path}: {cal.message}: give the pose with --param sensor_height=H sensor_pitch=P")
            config.update(sensor_height=cal.height, sensor_pitch=cal.pitch, sensor_roll=cal.roll)
            notes.append(f"{t.name}: pose calibrated from the first frames' floor")
        cfg = _core.Config(**config)
        pipes.append((_core.Pipeline(camera, cfg), (cfg.sensor_height, cfg.sensor_pitch, cfg.sensor_roll)))
    for i, f in enumerate(files):
        events.frame()
        metres = first if i == 0 else load_depth(f, opts.depth_scale)
        at = i / opts.frame_rate
        for t, (pipe, pose) in zip(tracks, pipes, strict=True):
            t.frames += 1
            t0 = time.perf_counter()
            t.last = pipe.process_pose(metres, *pose, stamp=at)
            t.add(at, t.last, time.perf_counter() - t0, None)
        _compare(tracks)
    return 0, notes


def measure_recording(path: str, opts: FleetOptions, configs: list[tuple[str, dict[str, Any]]]) -> list[dict[str, Any]]:
    """The task: one recording under each configuration (read once; the configurations side by side, each with its
    own pipeline running through the recording in order). Never raises: a recording that cannot be read, or any
    failure, is a row whose status says why."""
    started = time.monotonic()
    p = Path(path)
    events = _Events(path, opts.event_every)
    tracks = [_Track(name, cfg) for name, cfg in configs]
    status, lost, kind = "ok", 0, ""
    notes: list[str] = []
    try:
        if not p.exists():
            raise FleetError(f"{p}: no such file or folder")
        kind = recording_kind(p)
        runner = _run_frames if kind == "frames" else _run_bag
        lost, notes = runner(p, opts, tracks, events)
        if lost:
            status = f"damaged: {lost} message(s) lost ({notes[0]})"
        if tracks[0].processed == 0:
            why = reasons(tracks[0].report.problems) or "no depth frame in it"
            status = f"unreadable: no frame could be processed of {tracks[0].frames}: {why}"
    except (BagError, FleetError, OSError, ValueError) as exc:
        status = f"{'damaged' if 'damaged' in str(exc) else 'unreadable'}: {exc}"
    except Exception as exc:  # a row says what went wrong, the run goes on
        status = f"error: {type(exc).__name__}: {exc}"
        notes.append(traceback.format_exc(limit=3))
    events.frame(done=True)
    if events.worker is not None and os.environ.get(TRIM):
        notes.append(f"the worker runs with {TRIM}={os.environ[TRIM]} (a Dask nanny's default): frames ~2x slower")
    seconds = time.monotonic() - started
    rows = []
    for i, t in enumerate(tracks):
        row = {
            "recording": path,
            "config": t.name,
            "status": status,
            "frames": t.frames,
            "damaged": lost,
            "vs_config": tracks[0].name if i else "",
            "kind": kind,
            "seconds": round(seconds, 3),
            "worker": events.address,
            "notes": "; ".join(notes[:5]),
            **t.metrics(),
        }
        if not i:
            row["beams_moved"] = row["fit_changed"] = math.nan
        rows.append(row)
    return rows


# -- the table ----------------------------------------------------------------------------------------------------


def _plain(v: Any) -> Any:
    return None if isinstance(v, float) and not math.isfinite(v) else v


class Table:
    """``OUT/fleet.json`` (every row, with the learned correction over time) and ``OUT/fleet.csv`` (the columns
    of :data:`COLUMNS`): rows keyed by recording and configuration hash, both files written atomically."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.rows: dict[tuple[str, str], dict[str, Any]] = {}  # by recording and configuration name
        path = out / "fleet.json"
        if path.exists():
            try:
                rows = json.loads(path.read_text())["rows"]
                self.put(rows)
            except (ValueError, KeyError, TypeError) as exc:
                raise FleetError(f"{path}: not a fleet table ({exc}): remove it or choose another OUT") from exc

    def put(self, rows: list[dict[str, Any]]) -> None:
        for r in rows:
            self.rows[(r["recording"], r["config"])] = r

    def done(self, recording: str, config: str, chash: str, identity: dict[str, Any], checksum: bool) -> bool:
        """Whether the row of this recording and configuration is for the same input and configuration fields, with
        a final status (ok, damaged, unreadable)."""
        r = self.rows.get((recording, config))
        keys = ("input_size", "input_sha256" if checksum else "input_mtime_ns")
        return (
            r is not None
            and r.get("config_hash") == chash
            and str(r["status"]).split(":")[0] in FINAL
            and all(r.get(k) == identity[k] for k in keys)
        )

    def save(self) -> None:
        import csv
        import io

        rows = sorted(self.rows.values(), key=lambda r: (r["recording"], r["config"]))
        doc = {"tool": "kinect-pipeline fleet", "columns": list(COLUMNS), "rows": rows}
        text = io.StringIO()
        w = csv.DictWriter(text, fieldnames=list(COLUMNS), extrasaction="ignore", lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: "" if _plain(r.get(k)) is None else r.get(k) for k in COLUMNS})
        write_text(self.out / "fleet.json", json.dumps(_json_safe(doc), indent=1, sort_keys=True) + "\n")
        write_text(self.out / "fleet.csv", text.getvalue())


def _json_safe(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json_safe(x) for x in v]
    return _plain(v)


# -- the run ------------------------------------------------------------------------------------------------------


@dataclass
class Job:
    recording: Path
    configs: list[tuple[str, dict[str, Any], str]]  #: name, fields, hash: those still to do
    identity: dict[str, Any]


@dataclass
class FleetResult:
    recordings: int = 0
    skipped: int = 0  #: up to date in the table
    computed: int = 0
    frames: int = 0
    seconds: float = 0.0
    failed: list[tuple[str, str, str]] = field(default_factory=list)  #: recording, config, status
    dashboard: str = ""


def plan(
    recordings: list[Path], configs: list[tuple[str, dict[str, Any]]], opts: FleetOptions, table: Table, redo: bool
) -> tuple[list[Job], int]:
    """What is left to do: per recording the configurations without an up-to-date row; and how many recordings
    are up to date."""
    hashes = [(name, cfg, config_hash(cfg, opts)) for name, cfg in configs]
    jobs, skipped = [], 0
    for rec in recordings:
        try:
            ident = input_identity(rec, opts.checksum)
        except OSError:
            ident = {"input_size": None, "input_mtime_ns": None, "input_sha256": ""}
        todo = [c for c in hashes if redo or not table.done(str(rec), c[0], c[2], ident, opts.checksum)]
        if todo:
            jobs.append(Job(rec, todo, ident))
        else:
            skipped += 1
    return jobs, skipped


class _Progress:
    """Recordings and frames done, printed at most every ``every`` seconds (from the task's events)."""

    def __init__(self, total: int, quiet: bool, every: float = 2.0) -> None:
        self.total, self.quiet, self.every = total, quiet, every
        self.frames: dict[str, int] = {}
        self.done = 0
        self.started = self.shown = time.monotonic()

    def event(self, event: tuple[float, dict[str, Any]]) -> None:
        msg = event[1]
        self.frames[msg["recording"]] = int(msg["frames"])
        self.show()

    def finished(self, rows: list[dict[str, Any]]) -> None:
        self.done += 1
        if rows:
            self.frames[rows[0]["recording"]] = int(rows[0]["frames"] or 0)
        self.show(force=True)

    def show(self, force: bool = False) -> None:
        now = time.monotonic()
        if self.quiet or (not force and now - self.shown < self.every):
            return
        self.shown = now
        n = sum(self.frames.values())
        rate = n / (now - self.started) if now > self.started else 0.0
        import sys

        print(f"fleet: {self.done}/{self.total} recordings, {n} frames ({rate:.1f} frames/s)", file=sys.stderr)


def _client(workers: int | None, scheduler: str | None) -> tuple[Any, Any]:
    """A Dask client: of the running cluster at ``scheduler`` (waiting for ``workers`` workers when given), or of
    a LocalCluster on this machine with ``workers`` processes (default: one per core), one thread each."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError, ValueError) as exc:  # ValueError: not an address at all
            raise FleetError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there: {exc}") from exc
        if workers:
            try:
                client.wait_for_workers(workers, timeout=120)
            except TimeoutError as exc:
                have = len(client.scheduler_info()["workers"])
                client.close()
                raise FleetError(f"--workers {workers}: {have} worker(s) joined {scheduler} within 120 s") from exc
        return client, None
    import dask

    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    n = workers or cpus
    if n > cpus:
        import sys

        print(
            f"kinect-pipeline fleet: warning: --workers {n} is more than the {cpus} CPU(s) this process may use: the "
            "workers share them (no faster, each with its own memory); a LocalCluster takes one per CPU by default",
            file=sys.stderr,
        )
    _core_first_on_path()
    try:
        # Dask's nannies start workers with MALLOC_TRIM_THRESHOLD_=65536, which turns off glibc's adaptive mmap
        # threshold: every frame's buffers are then fresh pages, and a frame took twice as long (measured, see
        # docs/performance.md#fleet). Unset for our workers.
        with dask.config.set({f"{SPAWN_ENV}.{TRIM}": None}):
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0"
            )
    except RuntimeError as exc:
        raise FleetError(f"could not start a LocalCluster of {n} worker(s): {exc} (see the log above)") from exc
    return Client(cluster), cluster


def _core_first_on_path() -> None:
    """Worker processes are spawned with this process's sys.path. In a catkin devel space the package is the
    devel folder (with the binding) extended by the source folder, which the devel shim puts first on sys.path: a
    new process would import the sources alone, without the binding. The binding's folder goes first."""
    import sys

    here = str(Path(_core.__file__).resolve().parent.parent)
    if sys.path[:1] != [here]:
        sys.path[:] = [here, *(p for p in sys.path if p != here)]


def _lost_rows(job: Job, status: str) -> list[dict[str, Any]]:
    return [
        {"recording": str(job.recording), "config": name, "status": status, "frames": 0, "notes": ""}
        for name, _, _ in job.configs
    ]


def run_fleet(
    recordings: list[Path],
    out: Path,
    opts: FleetOptions,
    configs: list[tuple[str, dict[str, Any]]],
    workers: int | None = None,
    scheduler: str | None = None,
    redo: bool = False,
    quiet: bool = False,
) -> FleetResult:
    """Measures every recording under every configuration that has no up-to-date row in ``out``'s table, one Dask
    task per recording; rows are saved after each recording. Returns what was done and what failed."""
    from distributed import as_completed

    table = Table(out)
    jobs, skipped = plan(recordings, configs, opts, table, redo)
    result = FleetResult(recordings=len(recordings), skipped=skipped)
    started = time.monotonic()
    if jobs:
        client, cluster = _client(workers, scheduler)
        try:
            result.dashboard = str(client.dashboard_link or "")
            if not quiet:
                import sys

                print(
                    f"fleet: {len(jobs)} recording(s) to do on {scheduler or 'a LocalCluster'}; dashboard "
                    f"{result.dashboard or 'none'}",
                    file=sys.stderr,
                )
            _run_jobs(client, jobs, opts, table, result, _Progress(len(jobs), quiet), as_completed)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    table.save()
    result.seconds = time.monotonic() - started
    wanted = {(str(r), name) for r in recordings for name, _ in configs}
    for key, row in sorted(table.rows.items()):
        if key in wanted and row["status"] != "ok":
            result.failed.append((key[0], key[1], row["status"]))
    return result


def _run_jobs(
    client: Any, jobs: list[Job], opts: FleetOptions, table: Table, result: FleetResult, prog: _Progress, ac: Any
) -> None:
    import uuid

    token = uuid.uuid4().hex[:8]
    client.subscribe_topic(EVENT_TOPIC, prog.event)
    futures = {}
    for i, job in enumerate(jobs):
        configs = [(name, cfg) for name, cfg, _ in job.configs]
        key = f"fleet-{token}-{i}-{job.recording.name}"
        fut = client.submit(measure_recording, str(job.recording), opts, configs, key=key, pure=False)
        futures[fut.key] = (fut, job)
    saved = time.monotonic()
    for fut in ac([f for f, _ in futures.values()]):
        job = futures[fut.key][1]
        try:
            rows = fut.result()
        except Exception as exc:  # KilledWorker (its workers died again and again), a lost scheduler
            rows = _lost_rows(job, f"lost: {type(exc).__name__}: {exc}")
        fut.release()
        for row, (_, _, chash) in zip(rows, job.configs, strict=True):
            row.update(job.identity, config_hash=chash)
        table.put(rows)
        result.computed += 1
        result.frames += int(rows[0].get("frames") or 0)
        prog.finished(rows)
        if time.monotonic() - saved > 1.0 or len(futures) < 50:
            table.save()
            saved = time.monotonic()
    client.unsubscribe_topic(EVENT_TOPIC)
