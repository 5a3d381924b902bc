"""New bags of every kind (:data:`~.reader.FORMATS`), with messages converted between ROS versions field by field."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from .messages import typestore
from .reader import FORMATS, MCAP, ROS1, SQLITE3, BagReader
from .ros1 import BagError

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
        self.typestore = typestore(self.ros2)
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
