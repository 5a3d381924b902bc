"""The bags the tools read and write, whatever their kind: ROS 1 (``.bag``), rosbag2 folders with sqlite3 or mcap
storage, and single ``.mcap`` / ``.db3`` files, all through the PyPI ``rosbags`` library.

:func:`open_bag` gives a :class:`BagReader` with the same interface for every kind (connections, records in time
order, ``decode``); ROS 1 bags are read record by record by :mod:`kinect_pipeline.bagfile`, so that damage is named.
The message helpers read ROS 1 and ROS 2 definitions alike (ROS 2 has no ``seq`` and spells CameraInfo's ``K`` as
``k``); the depth image and camera conversions are the C++ core's, the ones the ROS node uses.
"""

from __future__ import annotations

import bisect
import dataclasses
import sys
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from . import _core
from .bagfile import Bag, BagError, Damage
from .intrinsics import HOW, Intrinsics, IntrinsicsError, nominal_camera

ROS1, SQLITE3, MCAP = "ros1", "sqlite3", "mcap"
FORMATS = (ROS1, SQLITE3, MCAP)  #: what a bag can be (rosbag2: sqlite3 or mcap storage)

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
TF_TOPICS = ("/tf", "/tf_static")

Tf = tuple[tuple[float, float, float, float], tuple[float, float, float]]


def _typestore(ros2: bool) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    if ros2:
        return get_typestore(Stores.ROS2_HUMBLE)
    ts = get_typestore(Stores.ROS1_NOETIC)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return ts


def bag_format(path: Path) -> str:
    """What ``path`` is: ``ros1``, ``sqlite3`` or ``mcap``, from its content (a folder from its metadata.yaml);
    anything else raises BagError saying what it is."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: no such bag")
    if path.is_dir():
        meta = path / "metadata.yaml"
        if not meta.exists():
            raise BagError(f"{path}: a folder without metadata.yaml: not a rosbag2 bag")
        text = meta.read_text(errors="replace")
        for fmt in (SQLITE3, MCAP):
            if f"storage_identifier: {fmt}" in text:
                return fmt
        raise BagError(f"{meta}: no storage_identifier sqlite3 or mcap: not a rosbag2 bag the tools read")
    with path.open("rb") as f:
        head = f.read(16)
    if head.startswith(b"\x89MCAP0\r\n"):
        return MCAP
    if head.startswith(b"SQLite format 3"):
        return SQLITE3
    return ROS1  # the ROS 1 reader names what is wrong with anything else


class BagReader:
    """A bag opened for reading: ``connections`` (rosbags ``Connection`` tuples), its records in time order and
    ``decode`` for its serialization. ``damage``: what was found damaged on opening a ROS 1 bag with ``recover``."""

    def __init__(self, path: Path, recover: bool = False) -> None:
        self.path = Path(path)
        self.format = bag_format(self.path)
        self.ros2 = self.format != ROS1
        self.typestore = _typestore(self.ros2)
        self.damage: list[Damage] = []
        self._ros1: Bag | None = None
        self._ros2: Any = None
        if self.ros2:
            from rosbags.rosbag2 import Reader

            try:
                self._ros2 = Reader(self.path)
                self._ros2.open()
            except Exception as exc:  # rosbags raises several kinds on damaged bags
                raise BagError(f"{self.path}: not a readable rosbag2 bag: {exc}") from exc
            self.connections: list[Any] = list(self._ros2.connections)
            self._register_types()
        else:
            self._ros1 = Bag(self.path, recover=recover)
            self.connections = list(self._ros1.connections)
            self.damage = self._ros1.damage

    def _register_types(self) -> None:
        """Message types the bag defines that the ROS 2 typestore lacks (custom messages), where they parse."""
        from rosbags.typesys import get_types_from_idl, get_types_from_msg

        for c in self.connections:
            if c.msgtype in self.typestore.types or not c.msgdef.data:
                continue
            try:
                parse = get_types_from_idl if c.msgdef.data.startswith("=" * 80 + "\nIDL: ") else get_types_from_msg
                self.typestore.register(parse(c.msgdef.data, c.msgtype))
            except Exception:  # a type that does not parse is copied without being decoded
                continue

    @property
    def ros1_bag(self) -> Bag:
        """The ROS 1 bag underneath (its index entries and byte offsets: the replay's resume reads them)."""
        if self._ros1 is None:
            raise BagError(f"{self.path}: a {self.format} bag, not ROS 1")
        return self._ros1

    def count(self, topic: str) -> int:
        return sum(c.msgcount for c in self.connections if c.topic == topic)

    def records(
        self, connections: Any = (), on_damage: Callable[[Damage], None] | None = None
    ) -> Iterator[tuple[Any, int, bytes, int]]:
        """(connection, time [ns], raw message, where) in time order; ``where`` is a byte offset (ROS 1) or the
        message's index (rosbag2). A damaged ROS 1 record raises BagError, or with ``on_damage`` is reported to it
        and skipped."""
        if self._ros1 is not None:
            yield from self._ros1.records(connections, on_damage)
            return
        try:
            for i, (conn, t, raw) in enumerate(self._ros2.messages(connections=list(connections))):
                yield conn, t, bytes(raw), i
        except Exception as exc:  # a damaged storage file
            if isinstance(exc, BagError):
                raise
            raise BagError(f"{self.path}: damaged {self.format} storage: {exc}") from exc

    def messages(self, connections: Any = ()) -> Iterator[tuple[Any, int, bytes]]:
        for conn, t, raw, _ in self.records(connections):
            yield conn, t, raw

    def decode(self, conn: Any, raw: bytes) -> Any:
        """The message of a raw record (ROS 1 or CDR serialization, as the bag has it)."""
        if self.ros2:
            return self.typestore.deserialize_cdr(raw, conn.msgtype)
        return self.typestore.deserialize_ros1(raw, conn.msgtype)

    def where(self, position: int) -> str:
        return f"byte {position}" if not self.ros2 else f"message {position}"

    def close(self) -> None:
        if self._ros1 is not None:
            self._ros1.close()
        if self._ros2 is not None:
            self._ros2.close()
            self._ros2 = None

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_bag(path: Path, recover: bool = False) -> BagReader:
    """A bag of any kind opened for reading; one that cannot be read raises BagError naming it (and for a damaged
    ROS 1 bag the byte offset and topic). ``recover`` reads what is intact of a damaged ROS 1 bag instead."""
    return BagReader(Path(path), recover=recover)


# -- messages of either ROS version -------------------------------------------------------------------------------


def stamp(msg: Any) -> float:
    """The header stamp [s] of a message."""
    s = msg.header.stamp
    return float(s.sec + s.nanosec * 1e-9)


def intrinsics_matrix(info: Any) -> list[float]:
    """K of a CameraInfo (ROS 1 ``K``, ROS 2 ``k``), row-major."""
    k = info.k if hasattr(info, "k") else info.K
    return [float(v) for v in k]


def camera_from_info(info: Any) -> Any:
    """The core's camera of a CameraInfo (the node's checks: K[0] = 0 is an uncalibrated camera)."""
    try:
        return _core.camera_from_intrinsics(
            int(info.width), int(info.height), intrinsics_matrix(info), info.header.frame_id
        )
    except ValueError as exc:
        raise BagError(str(exc)) from exc


#: The transports of a depth image whose topics the tools read: image_transport's ``compressedDepth`` plugin, and
#: its ``compressed`` plugin where it holds a lossless PNG of 16-bit or 8-bit depth (``16UC1; png compressed``).
TRANSPORTS = ("/compressedDepth", "/compressed")

#: What the tools decode of image_transport's ``compressed`` plugin: a lossless PNG of 16-bit depth (as the node).
PNG_DEPTH = ("16UC1", "mono16")

SUPPORTED = (
    "sensor_msgs/Image (8UC1, mono8, 16UC1, mono16, 32FC1), its compressedDepth (16UC1 / 32FC1; compressedDepth png "
    "or rvl) and its compressed PNG of 16-bit depth (16UC1 / mono16; png compressed)"
)


def is_compressed_depth(msgtype: str, topic: str) -> bool:
    """A CompressedImage topic of a transport the tools read (``…/compressedDepth``, ``…/compressed``)."""
    return msgtype == COMPRESSED and topic.rstrip("/").endswith(TRANSPORTS)


def depth_array(msg: Any) -> np.ndarray:
    """The depth image of an Image, a compressedDepth or a PNG ``compressed`` CompressedImage message as a 2-D
    array (uint8, uint16 mm or float32 m), through the core's conversions; a message it cannot read raises
    BagError saying why (and, for a format it does not read, what it reads)."""
    try:
        if hasattr(msg, "encoding"):
            return np.asarray(
                _core.depth_from_buffer(msg.encoding, msg.width, msg.height, msg.step, bool(msg.is_bigendian), msg.data)
            )
        fmt = str(msg.format)
        if "compressedDepth" in fmt:
            decode = getattr(_core, "decode_compressed_depth", None)
            if decode is None:
                raise BagError("compressedDepth images: this build of the core has no decoder")
            return np.asarray(decode(fmt, msg.data))
        return png_depth(fmt, msg.data)
    except (ValueError, TypeError) as exc:
        raise BagError(str(exc)) from exc


def png_depth(fmt: str, data: Any) -> np.ndarray:
    """A depth image of image_transport's ``compressed`` plugin: format ``16UC1; png compressed`` (or mono16), a
    bare lossless 16-bit PNG, which the core's compressedDepth decoder reads as it reads the PNG of a
    compressedDepth message. JPEG, 8-bit, colour and anything else raise BagError naming the format and what is
    read."""
    encoding, _, rest = fmt.partition(";")
    if encoding.strip() not in PNG_DEPTH or "png" not in rest.split():
        raise BagError(
            f"compressed image format {fmt.strip()!r}: not a depth image the tools read; they read {SUPPORTED}"
        )
    decode = getattr(_core, "decode_compressed_depth", None)
    if decode is None:
        raise BagError("compressed PNG depth images: this build of the core has no decoder")
    return np.asarray(decode("16UC1; compressedDepth png", data))


def header(types: Any, stamp_msg: Any, frame_id: str, seq: int = 0) -> Any:
    """A std_msgs/Header of the typestore's definition (ROS 1 with ``seq``, ROS 2 without)."""
    Header = types["std_msgs/msg/Header"]
    fields = {f.name for f in dataclasses.fields(Header)}
    kw: dict[str, Any] = {"stamp": stamp_msg, "frame_id": frame_id}
    if "seq" in fields:
        kw["seq"] = seq
    return Header(**kw)


def image_message(types: Any, header_msg: Any, depth: np.ndarray, encoding: str) -> Any:
    """A sensor_msgs/Image of a 2-D array (host byte order) with this header and encoding."""
    depth = np.ascontiguousarray(depth)
    return types[IMAGE](
        header=header_msg,
        height=depth.shape[0],
        width=depth.shape[1],
        encoding=encoding,
        is_bigendian=int(sys.byteorder == "big"),
        step=depth.strides[0],
        data=depth.view(np.uint8).reshape(-1),
    )


# -- topics ---------------------------------------------------------------------------------------------------


def depth_topics(connections: list[Any]) -> list[str]:
    """Topics that may carry depth frames: Image topics, and compressedDepth / compressed topics (whether a
    message is a depth image the tools read is told per message, by its format)."""
    out = {c.topic for c in connections if c.msgtype == IMAGE}
    out |= {c.topic for c in connections if is_compressed_depth(c.msgtype, c.topic)}
    return sorted(out)


def image_topic_of(depth_topic: str) -> str:
    """The raw image topic of a depth topic (``X/compressedDepth``, ``X/compressed`` -> ``X``)."""
    for suffix in TRANSPORTS:
        if depth_topic.endswith(suffix):
            return depth_topic[: -len(suffix)]
    return depth_topic


def topics_of(connections: list[Any]) -> str:
    """The bag's topics with their types, for messages (``/a [Image], /b [CompressedImage]``)."""
    kinds = sorted({(c.topic, c.msgtype.rsplit("/", 1)[-1]) for c in connections})
    return ", ".join(f"{t} [{k}]" for t, k in kinds) or "none"


def pick_topics(
    connections: list[Any], depth: str | None, info: str | None, need_info: bool = True
) -> tuple[str, str | None]:
    """The depth topic and its camera_info topic: as given, else the only depth topic with "depth" in its name
    (a raw Image before its compressed transports) and ``camera_info`` beside it. Raises BagError naming the
    choices. ``need_info`` False (the intrinsics come from elsewhere): a camera_info topic the bag lacks is None."""
    images = depth_topics(connections)
    infos = sorted({c.topic for c in connections if c.msgtype == CAMERA_INFO})
    if depth is None:
        cands = [t for t in images if "depth" in t and not image_topic_of(t).endswith("/processed")]
        raw = [t for t in cands if image_topic_of(t) == t]
        cands = raw if raw and all(image_topic_of(t) in raw for t in cands) else cands
        if len(cands) != 1:
            raise BagError(
                f"cannot tell the depth topic among the image topics {images or '(none)'}: name it with --depth-topic"
            )
        depth = cands[0]
    elif depth not in images:
        raise BagError(f"--depth-topic {depth}: not a depth image topic of the bag (image topics: {images or 'none'})")
    named = info is not None
    info = info or image_topic_of(depth).rsplit("/", 1)[0] + "/camera_info"
    if info in infos:
        return depth, info
    if named:
        raise BagError(f"--info-topic {info}: not in the bag (its CameraInfo topics: {infos or 'none'})")
    if not need_info:
        return depth, None
    if infos:
        raise BagError(
            f"camera_info topic {info} (beside {depth}) not in the bag; its CameraInfo topics: {', '.join(infos)}: "
            f"name one with --info-topic, or give {HOW}"
        )
    raise BagError(
        f"the bag has no CameraInfo (its topics: {topics_of(connections)}): give the depth camera's intrinsics with "
        f"{HOW}, or --sensor-model NAME for its nominal camera"
    )


# -- tf -------------------------------------------------------------------------------------------------------


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
            r, p = t.transform.rotation, t.transform.translation
            tf: Tf = ((r.x, r.y, r.z, r.w), (p.x, p.y, p.z))
            if static:
                self.static[child] = tf
            else:
                stamps, tfs = self.dynamic[child]
                i = bisect.bisect(stamps, stamp(t))
                stamps.insert(i, stamp(t))
                tfs.insert(i, tf)

    def _edge(self, child: str, at: float, tolerance: float) -> Tf:
        if child in self.static:
            return self.static[child]
        stamps, tfs = self.dynamic.get(child, ([], []))
        if not stamps:
            raise LookupError(f"no transform to '{child}'")
        i = bisect.bisect(stamps, at)
        if i == 0:
            if stamps[0] - at > tolerance:
                raise LookupError(f"'{child}': first transform at {stamps[0]:.3f} s, after the frame ({at:.3f} s)")
            return tfs[0]
        if i == len(stamps):
            if at - stamps[-1] > tolerance:
                raise LookupError(f"'{child}': last transform at {stamps[-1]:.3f} s, before the frame ({at:.3f} s)")
            return tfs[-1]
        a, b = stamps[i - 1], stamps[i]
        return _core.interpolate_transform(tfs[i - 1], tfs[i], (at - a) / (b - a) if b > a else 0.0)

    def lookup(self, target: str, source: str, at: float, tolerance: float) -> Tf:
        """target <- source at ``at`` [s], composing the tree through their common ancestor."""
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

        def to_common(up: list[str]) -> Tf:
            out: Tf = ((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
            for f in up[: up.index(common)]:
                out = _core.compose_transforms(self._edge(f, at, tolerance), out)
            return out

        return _core.compose_transforms(_core.invert_transform(to_common(up_t)), to_common(up_s))


def read_side(
    bag: BagReader, topics: tuple[str, ...], on_damage: Callable[[Damage], None] | None = None
) -> Iterator[tuple[Any, Any]]:
    """(connection, message) of the bag's messages on ``topics``. A message that cannot be decoded is a damaged
    record: raised as BagError, or given to ``on_damage`` and skipped."""
    conns = [c for c in bag.connections if c.topic in topics]
    for conn, _, raw, pos in bag.records(conns, on_damage) if conns else ():
        try:
            msg = bag.decode(conn, raw)
        except Exception as exc:  # rosbags raises several kinds on garbage
            damage = Damage(pos, conn.topic, f"cannot be decoded as {conn.msgtype}: {exc}", lost=1)
            if on_damage is None:
                raise BagError(f"{bag.path}: damaged message record at {damage}") from exc
            on_damage(damage)
            continue
        yield conn, msg


def read_tf(bag: BagReader, on_damage: Callable[[Damage], None] | None = None) -> TfBuffer:
    """All of the bag's /tf and /tf_static (a frame may come before the transform at its stamp)."""
    tf = TfBuffer()
    for conn, msg in read_side(bag, TF_TOPICS, on_damage):
        tf.add(msg, static=conn.topic == "/tf_static")
    return tf


class CameraInfos:
    """The bag's camera_info messages by stamp: an image is paired with the camera_info of its own stamp, wherever
    that lies in the bag (before or after the image), as image_transport's CameraSubscriber pairs them."""

    def __init__(self, bag: BagReader, topic: str, on_damage: Callable[[Damage], None] | None = None) -> None:
        self.topic = topic
        self.by_stamp: dict[float, Any] = {}
        for _, msg in read_side(bag, (topic,), on_damage):
            self.by_stamp.setdefault(round(stamp(msg), 9), msg)
        self.stamps = sorted(self.by_stamp)

    def for_stamp(self, at: float) -> tuple[Any | None, str]:
        """The camera_info of stamp ``at`` [s] and "" ; where the bag has none of that stamp, the nearest one and
        a note saying so; (None, why) in a bag without any."""
        key = round(at, 9)
        if key in self.by_stamp:
            return self.by_stamp[key], ""
        if not self.stamps:
            return None, f"no camera_info on {self.topic} in the bag"
        i = bisect.bisect(self.stamps, key)
        near = min(self.stamps[max(0, i - 1) : i + 1], key=lambda s: abs(s - key))
        return self.by_stamp[near], f"no camera_info of its stamp: the one at {near:.3f} s used"


class Cameras:
    """Where each depth frame's camera comes from: ``intrinsics`` where given (they win over a camera_info), else
    the camera_info of the frame's stamp (:class:`CameraInfos`), else the ``sensor_model`` preset's nominal camera
    scaled to the image (``warning`` then says so). Without any of them a frame raises BagError saying what to give."""

    def __init__(
        self,
        bag: BagReader,
        info_topic: str | None,
        intrinsics: Intrinsics | None = None,
        sensor_model: str | None = None,
        on_damage: Callable[[Damage], None] | None = None,
    ) -> None:
        self.intrinsics, self.sensor_model = intrinsics, sensor_model
        use_info = info_topic is not None and intrinsics is None
        self.infos = CameraInfos(bag, info_topic, on_damage) if use_info and info_topic else None
        self.warning = ""  #: the nominal camera is a guess: said once
        self.source = (
            f"intrinsics from {intrinsics.source}"
            if intrinsics is not None
            else f"camera_info on {info_topic}"
            if self.infos is not None and self.infos.stamps
            else f"the nominal camera of --sensor-model {sensor_model}"
            if sensor_model
            else "none"
        )

    def for_frame(self, msg: Any, depth: np.ndarray) -> tuple[Any, str]:
        """The camera of a depth message whose image is ``depth``, and a note where its camera_info is not of its
        own stamp (:meth:`CameraInfos.for_stamp`)."""
        height, width = depth.shape[:2]
        try:
            if self.intrinsics is not None:
                return self.intrinsics.camera(width, height), ""
            if self.infos is not None and self.infos.stamps:
                info, note = self.infos.for_stamp(stamp(msg))
                return camera_from_info(info), note
            if self.sensor_model:
                cam, self.warning = nominal_camera(self.sensor_model, width, height)
                return cam, ""
        except IntrinsicsError as exc:
            raise BagError(str(exc)) from exc
        where = f"no camera_info on {self.infos.topic} in the bag" if self.infos is not None else "no CameraInfo"
        raise BagError(f"{where}: give {HOW}, or --sensor-model NAME for its nominal camera")


# -- writing --------------------------------------------------------------------------------------------------

_SUFFIX = {".bag": ROS1, ".mcap": MCAP, ".db3": SQLITE3}


def output_format(out: Path, input_format: str, requested: str | None = None) -> str:
    """The format to write ``out`` in: ``requested``, else the input's; a name whose suffix says another format
    (``x.bag`` for a rosbag2 bag, ``x.mcap`` for another) raises BagError."""
    if requested is not None and requested not in FORMATS:
        raise BagError(f"format {requested!r}: expected one of {', '.join(FORMATS)}")
    fmt = requested or input_format
    said = _SUFFIX.get(Path(out).suffix.lower())
    if said is not None and said != fmt:
        raise BagError(f"{out}: a {Path(out).suffix} name for a {fmt} bag: name it otherwise, or give --format {said}")
    return fmt


class BagWriter:
    """A new bag in one of :data:`FORMATS` at ``path`` (which must not exist; callers write to a temporary and
    rename it: ``name`` is the final name, which a rosbag2 bag's storage file takes). A rosbag2 bag is a folder,
    except where ``single_file``: then ``path`` is its one .mcap or .db3 file. Messages of the other ROS version
    are converted field by field (ROS 2 has no ``seq``, spells ``K`` as ``k``)."""

    def __init__(self, path: Path, fmt: str, single_file: bool = False, name: str | None = None) -> None:
        if fmt not in FORMATS:
            raise BagError(f"format {fmt!r}: expected one of {', '.join(FORMATS)}")
        self.path, self.format, self.single_file = Path(path), fmt, single_file and fmt != ROS1
        self.ros2 = fmt != ROS1
        self.typestore = _typestore(self.ros2)
        self.skipped: list[str] = []  #: topics that could not be written in this format, and why
        self._stage = self.path.with_name(self.path.name + ".d")  # rosbag2: the writer's folder is made in here
        if self.ros2:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if fmt == MCAP else StoragePlugin.SQLITE3
            self._stage.mkdir()
            self._folder = self._stage / Path(name or self.path.name).stem
            self._w: Any = Writer(self._folder, version=8, storage_plugin=plugin)
        else:
            from rosbags.rosbag1 import Writer as Writer1

            self._w = Writer1(self.path)
        self._w.open()
        self._convert: dict[int, tuple[Any, str]] = {}  # out connection id -> (source reader, msgtype)

    @property
    def types(self) -> Any:
        return self.typestore.types

    def add(self, topic: str, msgtype: str, latching: bool = False) -> Any:
        """A connection for messages this writer encodes (:meth:`encode`)."""
        if self.ros2:
            return self._w.add_connection(topic, msgtype, typestore=self.typestore)
        return self._w.add_connection(topic, msgtype, typestore=self.typestore, latching=1 if latching else None)

    def copy(self, src: BagReader, conn: Any) -> Any | None:
        """A connection like ``conn`` of ``src`` for copying its messages (:meth:`write_copy`); None (and a note in
        ``skipped``) where its type cannot be written in this format."""
        latching = getattr(conn.ext, "latching", None)
        if src.ros2 == self.ros2:
            if self.ros2 and conn.msgdef.data and conn.digest:
                out = self._w.add_connection(
                    conn.topic,
                    conn.msgtype,
                    msgdef=conn.msgdef.data,
                    rihs01=conn.digest,
                    serialization_format=conn.ext.serialization_format,
                    offered_qos_profiles=conn.ext.offered_qos_profiles,
                )
            elif not self.ros2:
                out = self._w.add_connection(
                    conn.topic,
                    conn.msgtype,
                    msgdef=conn.msgdef.data,
                    md5sum=conn.digest,
                    callerid=getattr(conn.ext, "callerid", None),
                    latching=latching,
                )
            elif conn.msgtype in self.types:
                out = self._w.add_connection(conn.topic, conn.msgtype, typestore=self.typestore)
            else:
                self.skipped.append(f"{conn.topic}: no definition of {conn.msgtype} in the bag")
                return None
            return out
        if conn.msgtype not in self.types:
            self.skipped.append(f"{conn.topic}: {conn.msgtype} has no {self.format} definition here")
            return None
        out = self.add(conn.topic, conn.msgtype, latching=bool(latching))
        self._convert[out.id] = (src, conn.msgtype)
        return out

    def write_copy(self, out: Any, t_ns: int, raw: bytes) -> None:
        """A raw record of the connection ``out`` was copied from (converted where the ROS version differs)."""
        conv = self._convert.get(out.id)
        if conv is not None:
            src, msgtype = conv
            msg = _convert(src.decode(_Conn(msgtype), raw), self.types)
            raw = self.encode(msg, msgtype)
        self._w.write(out, t_ns, raw)

    def write(self, out: Any, t_ns: int, raw: bytes) -> None:
        self._w.write(out, t_ns, raw)

    def encode_ros1(self, msg: Any, msgtype: str) -> bytes:
        """A message built with ROS 1 definitions, encoded for this bag (converted for rosbag2)."""
        return self.encode(_convert(msg, self.types) if self.ros2 else msg, msgtype)

    def encode(self, msg: Any, msgtype: str) -> bytes:
        if self.ros2:
            return bytes(self.typestore.serialize_cdr(msg, msgtype))
        return bytes(self.typestore.serialize_ros1(msg, msgtype))

    def close(self) -> None:
        self._w.close()
        if not self.ros2:
            return
        if self.single_file:
            next(p for p in self._folder.iterdir() if p.suffix in (".mcap", ".db3")).replace(self.path)
        else:
            self._folder.replace(self.path)
        self.remove_stage()

    def remove_stage(self) -> None:
        import shutil

        shutil.rmtree(self._stage, ignore_errors=True)

    def abort(self) -> None:
        """Closes the files; a rosbag2 bag's unfinished folder is removed (a ROS 1 bag is left for --resume)."""
        import contextlib

        with contextlib.suppress(Exception):
            self._w.close()
        if self.ros2:
            self.remove_stage()

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, kind: object, *rest: object) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


@dataclasses.dataclass
class _Conn:
    msgtype: str


def _convert(msg: Any, types: Any) -> Any:
    """A message of one typestore as the same message type of another, field by field: fields are matched by name
    (case-insensitively: ROS 1 ``K`` is ROS 2 ``k``); a field the source lacks (ROS 1 ``seq``) is zero."""
    cls = types[msg.__msgtype__]
    have = {f.name.lower(): f.name for f in dataclasses.fields(msg)}
    kw: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        name = have.get(f.name.lower())
        if name is None:
            kw[f.name] = "" if "str" in str(f.type) else 0
            continue
        v = getattr(msg, name)
        if dataclasses.is_dataclass(v):
            v = _convert(v, types)
        elif isinstance(v, list) and v and dataclasses.is_dataclass(v[0]):
            v = [_convert(x, types) for x in v]
        kw[f.name] = v
    return cls(**kw)


def depth_frames(
    bag: BagReader,
    depth_topic: str,
    cameras: Cameras,
    progress_name: str | None = None,
    problems: list[str] | None = None,
) -> Iterator[tuple[Any, Any, np.ndarray]]:
    """(depth message, its camera, its depth array) of every depth frame of the bag in time order, each with its
    camera from ``cameras`` (:class:`Cameras`: the camera_info of its stamp, or intrinsics given). Frames that
    cannot be used (no camera, an image or a camera_info the core refuses) are left out and said in ``problems``.
    ``progress_name``: a progress bar."""
    conns = [c for c in bag.connections if c.topic == depth_topic]
    bar: Any = None
    if progress_name:
        from .demo import progress

        total = bag.count(depth_topic)
        bar = iter(progress(range(total), total, progress_name))
    noted = False
    for conn, _, raw in bag.messages(conns):
        if bar is not None:
            next(bar, None)
        msg = bag.decode(conn, raw)
        at = stamp(msg)
        try:
            depth = depth_array(msg)
            cam, note = cameras.for_frame(msg, depth)
        except BagError as exc:
            if problems is not None:
                problems.append(f"{depth_topic} at {at:.3f} s: {exc}; frame skipped")
            continue
        if note and problems is not None and not noted:
            problems.append(f"{depth_topic} at {at:.3f} s: {note} (and maybe for later frames)")
            noted = True
        yield msg, cam, depth
    for _ in bar or ():
        pass
