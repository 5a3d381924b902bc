"""Bags of every kind opened for reading with one interface (connections, records in time order, ``decode``); ROS 1
bags are read record by record by :mod:`.ros1`, so that damage is named. Also: which topics carry the depth frames and
their camera_info, camera_info paired by stamp, and the depth frames of a bag.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .. import _core
from ..intrinsics import HOW, Intrinsics, IntrinsicsError, nominal_camera
from ..outputs import progress
from .messages import (
    CAMERA_INFO,
    IMAGE,
    TRANSPORTS,
    camera_from_info,
    depth_array,
    distortion_of,
    is_compressed_depth,
    stamp,
    typestore,
)
from .ros1 import Bag, BagError, Damage

ROS1, SQLITE3, MCAP = "ros1", "sqlite3", "mcap"
FORMATS = (ROS1, SQLITE3, MCAP)  #: what a bag can be (rosbag2: sqlite3 or mcap storage)


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
    named = {".mcap": ("an MCAP file", b"\x89MCAP0\r\n"), ".db3": ("a rosbag2 sqlite3 file", b"SQLite format 3")}
    if path.suffix.lower() in named and not head.startswith(b"#ROSBAG"):
        what, magic = named[path.suffix.lower()]
        raise BagError(f"{path}: not {what}: it starts with {head!r}, expected {magic!r} (byte 0)")
    return ROS1  # the ROS 1 reader names what is wrong with anything else


class BagReader:
    """A bag opened for reading: ``connections`` (rosbags ``Connection`` tuples), its records in time order and
    ``decode`` for its serialization. ``damage``: what was found damaged on opening a ROS 1 bag with ``recover``."""

    def __init__(self, path: Path, recover: bool = False) -> None:
        self.path = Path(path)
        self.format = bag_format(self.path)
        self.ros2 = self.format != ROS1
        self.typestore = typestore(self.ros2)
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
        rectify: str = "auto",
    ) -> None:
        self.intrinsics, self.sensor_model = intrinsics, sensor_model
        use_info = info_topic is not None and intrinsics is None
        self.infos = CameraInfos(bag, info_topic, on_damage) if use_info and info_topic else None
        self.warning = ""  #: the nominal camera is a guess: said once
        #: auto | always | never: images rectified by their camera_info's distortion (the node's ~rectify)
        self.rectify, self.rectification = rectify, _core.TopicRectification()
        self.given = (
            f"intrinsics from {intrinsics.source}"
            if intrinsics is not None
            else f"camera_info on {info_topic}"
            if self.infos is not None and self.infos.stamps
            else f"the nominal camera of --sensor-model {sensor_model}"
            if sensor_model
            else "none"
        )

    @property
    def source(self) -> str:
        """Where the cameras come from, and whether the images are rectified (once a frame with a lens has said
        it)."""
        r = self.rectification
        return f"{self.given}; rectified: {r.why}" if r.distorts else self.given

    def for_frame(self, msg: Any, depth: np.ndarray, topic: str = "") -> tuple[Any, np.ndarray, str]:
        """The camera of a depth message on ``topic`` whose image is ``depth``, the image to process (rectified by
        its camera_info's distortion where ``rectify`` says so, as the node does), and a note where its camera_info
        is not of its own stamp (:meth:`CameraInfos.for_stamp`)."""
        height, width = depth.shape[:2]
        try:
            if self.intrinsics is not None:
                intr = self.intrinsics
                cam = intr.camera(width, height)
                depth = self._rectified(intr.distortion_model, list(intr.D), cam, depth, topic)
                if not self.rectification.rectifies:  # a rectified image's camera is P's, as in the node
                    cam = intr.rectified_camera(width, height)
                return cam, depth, ""
            if self.infos is not None and self.infos.stamps:
                info, note = self.infos.for_stamp(stamp(msg))
                cam = camera_from_info(info)
                if (cam.width, cam.height) != (width, height):  # the core would refuse the frame
                    raise BagError(
                        f"the image is {width}x{height} but its camera_info on {self.infos.topic} is "
                        f"{cam.width}x{cam.height} (its roi and binning applied): expected one size"
                    )
                model, coefficients, rotation = distortion_of(info)
                depth = self._rectified(model, coefficients, cam, depth, topic, rotation)
                if not self.rectification.rectifies:  # a rectified image's camera is P's, as in the node
                    cam = camera_from_info(info, rectified=True)
                return cam, depth, note
            if self.sensor_model:
                cam, self.warning = nominal_camera(self.sensor_model, width, height)
                return cam, depth, ""
        except IntrinsicsError as exc:
            raise BagError(str(exc)) from exc
        where = f"no camera_info on {self.infos.topic} in the bag" if self.infos is not None else "no CameraInfo"
        raise BagError(f"{where}: give {HOW}, or --sensor-model NAME for its nominal camera")

    def _rectified(
        self, model: str, coefficients: list[float], cam: Any, depth: np.ndarray, topic: str, rotation: Any = None
    ) -> np.ndarray:
        try:
            return self.rectification.apply(self.rectify, topic, cam, model, coefficients, depth, rotation or None)
        except ValueError as exc:
            raise BagError(
                f"{exc} to rectify the images (--rectify {self.rectify}; never if they are rectified)"
            ) from exc


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
        total = bag.count(depth_topic)
        bar = iter(progress(range(total), total, progress_name))
    noted = False
    for conn, _, raw in bag.messages(conns):
        if bar is not None:
            next(bar, None)
        msg = bag.decode(conn, raw)
        at = stamp(msg)
        try:
            cam, depth, note = cameras.for_frame(msg, depth_array(msg), depth_topic)
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
