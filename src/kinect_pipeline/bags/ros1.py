"""ROS 1 bags read record by record, so that damaged data is found, named (topic and byte offset) and, on request,
skipped.

A healthy bag is opened with the PyPI ``rosbags`` reader (its index gives every message's chunk and offset); each
message record is then read and checked here, so a damaged record names its topic and where it lies instead of
ending the whole read. A bag that ``rosbags`` cannot open (truncated, no index, a damaged chunk or index record) is
walked from the start: the first damage is named, and ``recover=True`` gives every intact message found before,
between and after damaged parts (resynchronising on the next record).
"""

from __future__ import annotations

import bz2
import mmap
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

MAGIC = b"#ROSBAG V2.0\n"
OP_MSG, OP_BAG, OP_INDEX, OP_CHUNK, OP_CHUNK_INFO, OP_CONN = 2, 3, 4, 5, 6, 7
_U32 = struct.Struct("<I")


class BagError(ValueError):
    """A bag that cannot be read, or damaged data in it; the message names the file, the byte offset and the topic."""


@dataclass
class Damage:
    """One damaged place of a bag."""

    offset: int  #: byte offset in the file (of the record, or of its chunk when the chunk is compressed)
    topic: str | None  #: topic of the damaged message(s), when known
    what: str
    lost: int | None = None  #: messages known to be lost there (None: not known)

    def __str__(self) -> str:
        lost = "" if self.lost is None else f" ({self.lost} message{'s' * (self.lost != 1)} lost)"
        return f"byte {self.offset}, topic {self.topic or '(unknown)'}: {self.what}{lost}"


class DamagedRecord(BagError):
    """A damaged message record met while reading; ``damage`` says where."""

    def __init__(self, path: Path, damage: Damage) -> None:
        super().__init__(f"{path}: damaged message record at {damage}")
        self.damage = damage


class Entry(NamedTuple):
    time: int  #: ns
    chunk_pos: int
    offset: int  #: in the chunk's (decompressed) data
    conn: int


@dataclass
class _Chunk:
    pos: int  #: of the chunk record
    datapos: int  #: of its data in the file
    size: int  #: bytes of data present in the file
    compression: str


class _RecordError(Exception):
    def __init__(self, what: str, cut: bool = False, fields: dict[bytes, bytes] | None = None) -> None:
        super().__init__(what)
        self.cut = cut  #: the data ends inside the record (a truncated file)
        self.fields = fields or {}  #: header fields read before the error


def _u32(buf: Any, pos: int) -> int:
    return int(_U32.unpack_from(buf, pos)[0])


def _fields(buf: Any, start: int, end: int) -> dict[bytes, bytes]:
    out: dict[bytes, bytes] = {}
    i = start
    while i < end:
        if i + 4 > end:
            raise _RecordError(f"header field length cut at byte {i}", fields=out)
        n = _u32(buf, i)
        if n == 0 or i + 4 + n > end:
            raise _RecordError(f"header field of length {n} at byte {i} runs past the header's end", fields=out)
        name, eq, value = bytes(buf[i + 4 : i + 4 + n]).partition(b"=")
        if not eq or not name:
            raise _RecordError(f"header field at byte {i} has no 'name=': {bytes(buf[i + 4 : i + 4 + min(n, 16)])!r}")
        out[name] = value
        i += 4 + n
    return out


def _record(buf: Any, pos: int, end: int) -> tuple[int, dict[bytes, bytes], int, int]:
    """(op, header fields, data start, data length) of the record at ``pos``; positions relative to ``buf``."""
    if pos + 4 > end:
        raise _RecordError(f"record header length cut off ({end - pos} of 4 bytes)", cut=True)
    hlen = _u32(buf, pos)
    if hlen < 8:
        raise _RecordError(f"record header length {hlen}: expected at least 8 (an 'op' field)")
    if pos + 4 + hlen > end:
        try:
            partial = _fields(buf, pos + 4, end)
        except _RecordError as exc:
            partial = exc.fields
        raise _RecordError(
            f"record header of {hlen} bytes runs past the end ({end - pos - 4} bytes left)", cut=True, fields=partial
        )
    fields = _fields(buf, pos + 4, pos + 4 + hlen)
    op = fields.get(b"op", b"")
    if len(op) != 1:
        raise _RecordError(f"record header without an 'op' field (fields {sorted(fields)})", fields=fields)
    dpos = pos + 4 + hlen
    if dpos + 4 > end:
        raise _RecordError("record data length cut off", cut=True, fields=fields)
    dlen = _u32(buf, dpos)
    if dpos + 4 + dlen > end:
        raise _RecordError(
            f"record data of {dlen} bytes runs past the end ({end - dpos - 4} bytes left)", cut=True, fields=fields
        )
    return op[0], fields, dpos + 4, dlen


def _resync(buf: Any, start: int, end: int, ops: tuple[int, ...]) -> int | None:
    """The first position >= ``start`` where a readable record of one of ``ops`` begins."""
    hay = buf if isinstance(buf, (bytes, mmap.mmap)) else bytes(buf)
    found: list[int] = []
    for op in ops:
        needle = b"\x04\x00\x00\x00op=" + bytes([op])
        q = hay.find(needle, start, end)
        while q != -1 and not (found and q - 300 >= min(found)):
            hit = None
            for s in range(max(start, q - 300), q - 3):
                try:
                    got, *_ = _record(hay, s, end)
                except (_RecordError, struct.error):
                    continue
                if got == op:
                    hit = s
                    break
            if hit is not None:
                found.append(hit)
                break
            q = hay.find(needle, q + 1, end)
    return min(found) if found else None


def _chunk_topics(counts: dict[int, int], topics: dict[int, str]) -> str | None:
    names = sorted({topics.get(c, f"connection {c}") for c in counts})
    return ", ".join(names) if names else None


@dataclass
class _Scan:
    """What a walk over a bag has found so far: connections, their topics, the index's message counts per chunk and
    the last intact message (byte offset, topic)."""

    conns: dict[int, dict[bytes, bytes]] = field(default_factory=dict)
    conn_topic: dict[int, str] = field(default_factory=dict)
    chunk_counts: dict[int, dict[int, int]] = field(default_factory=dict)  # from the index's chunk infos
    last: tuple[int, str] | None = None

    def add_conn(self, fields: dict[bytes, bytes], data: dict[bytes, bytes]) -> None:
        from rosbags.rosbag1.reader import normalize

        cid = _u32(fields[b"conn"], 0)
        self.conn_topic[cid] = normalize(fields[b"topic"].decode())
        self.conns.setdefault(cid, data)

    def after(self) -> str:
        """Where the last intact message lies, for a damage's message."""
        return f"; the last intact message before it: {self.last[1]} at byte {self.last[0]}" if self.last else ""


class Bag:
    """A ROS 1 bag opened for reading: ``connections`` (rosbags ``Connection`` tuples) and its messages in time order.

    ``damage`` lists what was found damaged while opening (only with ``recover=True``; otherwise the first damage
    raises :class:`BagError`)."""

    def __init__(self, path: Path | str, recover: bool = False) -> None:
        self.path = Path(path)
        self.recover = recover
        self.damage: list[Damage] = []
        self.indexed = False
        self.connections: list[Any] = []
        self._topics: dict[int, str] = {}
        self._entries: list[Entry] = []
        self._chunks: dict[int, _Chunk] = {}
        self._cache: tuple[int, bytes] = (-1, b"")
        try:
            self._file = self.path.open("rb")
        except OSError as exc:
            raise BagError(f"{self.path}: cannot open ({exc.strerror})") from exc
        self.size = self.path.stat().st_size
        self._mm: Any = b""
        try:
            if self.size == 0:
                raise BagError(f"{self.path}: not a readable ROS 1 bag: empty file (0 bytes)")
            self._mm = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ)
            head = bytes(self._mm[: len(MAGIC)])
            if head != MAGIC:
                raise BagError(
                    f"{self.path}: not a readable ROS 1 bag: it starts with {head!r}, expected {MAGIC!r} (byte 0)"
                )
            try:
                self._open_indexed()
            except BagError:
                raise
            except Exception as exc:  # rosbags raises several kinds on damaged data
                self._open_scanned(f"{type(exc).__name__}: {exc}")
        except BaseException:
            self.close()
            raise

    # -- opening ------------------------------------------------------------------------------------------------
    def _open_indexed(self) -> None:
        from rosbags.rosbag1 import Reader

        reader = Reader(self.path)
        reader.open()
        try:
            self.connections = list(reader.connections)
            for pos in reader.chunks:
                _, fields, dpos, dlen = _record(self._mm, pos, self.size)
                self._chunks[pos] = _Chunk(pos, dpos, dlen, fields.get(b"compression", b"none").decode())
            for c in self.connections:
                self._entries.extend(Entry(e.time, e.chunk_pos, e.offset, c.id) for e in reader.indexes[c.id])
        finally:
            reader.close()
        self._topics = {c.id: c.topic for c in self.connections}
        self._entries.sort()
        self.indexed = True

    def _open_scanned(self, reason: str) -> None:
        """Walks the file record by record (``rosbags`` could not open it: ``reason``)."""
        scan = _Scan()
        pos, index_pos = self._scan_bag_header()
        self._scan_data(scan, pos, index_pos if 0 < index_pos <= self.size else self.size)
        if 0 < index_pos < self.size:
            self._scan_index(scan, index_pos)
        else:
            self._no_index(scan, index_pos)
        for d in self.damage:  # a damaged chunk: its topics and message count from the index, where it was read
            if d.topic is None and d.offset in scan.chunk_counts:
                d.topic = _chunk_topics(scan.chunk_counts[d.offset], scan.conn_topic)
                d.lost = sum(scan.chunk_counts[d.offset].values())
        if not self.damage:
            self.damage.append(Damage(0, None, f"rosbags cannot open it ({reason}), though no record is damaged"))
        if not self.recover:
            first = self.damage[0]
            more = f" (and {len(self.damage) - 1} more damaged place(s))" if len(self.damage) > 1 else ""
            raise BagError(
                f"{self.path}: not a readable ROS 1 bag as it is: damaged at {first}{more}; "
                f"{len(self._entries)} intact messages"
            )
        self._scanned_connections(scan)

    def _scan_bag_header(self) -> tuple[int, int]:
        """Where the first record after the bag header lies, and where the header says the index starts (0:
        unknown). A damaged header is named, and the walk goes on at the next chunk."""
        pos = len(MAGIC)
        try:
            op, fields, dpos, dlen = _record(self._mm, pos, self.size)
            if op != OP_BAG:
                raise _RecordError(f"record op {op}, expected the bag header (op {OP_BAG})")
            return dpos + dlen, int(struct.unpack("<Q", fields[b"index_pos"])[0])
        except (_RecordError, KeyError, struct.error) as exc:
            self.damage.append(Damage(pos, None, f"bag header record damaged: {exc}"))
            nxt = _resync(self._mm, pos + 1, self.size, (OP_CHUNK,))
            return (nxt if nxt is not None else self.size), 0

    def _scan_data(self, scan: _Scan, pos: int, data_end: int) -> None:
        """The chunks and connection records from ``pos`` to the index; damaged records are named and skipped."""
        mm, size = self._mm, self.size
        while pos < data_end:
            try:
                op, fields, dpos, dlen = _record(mm, pos, size)
            except _RecordError as exc:
                if exc.cut and b"op" in exc.fields and exc.fields[b"op"] == bytes([OP_CHUNK]):
                    self._scan_cut_chunk(scan, pos, exc.fields)
                    return
                self.damage.append(Damage(pos, None, f"record unreadable: {exc}{scan.after()}"))
                nxt = None if exc.cut else _resync(mm, pos + 1, data_end, (OP_CHUNK,))
                if nxt is None:
                    return
                self.damage[-1].what += f"; went on at the next chunk, byte {nxt}"
                pos = nxt
                continue
            if op == OP_CHUNK:
                comp = fields.get(b"compression", b"none").decode()
                self._chunks[pos] = _Chunk(pos, dpos, dlen, comp)
                self._scan_chunk(scan, self._chunks[pos])
            elif op == OP_CONN:
                scan.add_conn(fields, _fields(mm, dpos, dpos + dlen))
            elif op not in (OP_INDEX, OP_CHUNK_INFO):
                self.damage.append(Damage(pos, None, f"unexpected record op {op} among the chunks{scan.after()}"))
            pos = dpos + dlen

    def _no_index(self, scan: _Scan, index_pos: int) -> None:
        """Names why there is no index to read: the recording was not closed, or the file was cut."""
        topic, size = scan.last[1] if scan.last else None, self.size
        if index_pos == 0:
            what = (
                "the bag has no index (the bag header's index_pos is 0: the recording was not closed; "
                "`rosbag reindex` repairs it)"
            )
            self.damage.append(Damage(size, topic, what + scan.after()))
        elif index_pos > size:
            if not any("cut off" in d.what or "runs past the end" in d.what for d in self.damage):
                what = f"truncated: the index should start at byte {index_pos}, but the file ends at byte {size}"
                self.damage.append(Damage(size, topic, what + scan.after()))
        else:
            what = f"the index is missing: the file ends at byte {size}, where the bag header says the index starts"
            self.damage.append(Damage(size, topic, what + scan.after()))

    def _scan_index(self, scan: _Scan, index_pos: int) -> None:
        """The index's connection records and chunk infos (which topics each chunk held)."""
        mm, pos = self._mm, index_pos
        while pos < self.size:
            try:
                op, fields, dpos, dlen = _record(mm, pos, self.size)
                if op == OP_CONN:
                    scan.add_conn(fields, _fields(mm, dpos, dpos + dlen))
                elif op == OP_CHUNK_INFO:
                    cpos = int(struct.unpack("<Q", fields[b"chunk_pos"])[0])
                    scan.chunk_counts[cpos] = {
                        _u32(mm, dpos + 8 * i): _u32(mm, dpos + 8 * i + 4) for i in range(dlen // 8)
                    }
            except (_RecordError, KeyError, struct.error) as exc:
                self.damage.append(
                    Damage(pos, None, f"index record unreadable: {exc} (the index starts at byte {index_pos})")
                )
                return
            pos = dpos + dlen

    def _scanned_connections(self, scan: _Scan) -> None:
        """The connections found by the walk, as ``rosbags`` gives them; messages of no known connection go."""
        from rosbags.interfaces import Connection as RConnection
        from rosbags.interfaces import ConnectionExtRosbag1, MessageDefinition, MessageDefinitionFormat
        from rosbags.typesys.msg import normalize_msgtype

        counts: dict[int, int] = {}
        for e in self._entries:
            counts[e.conn] = counts.get(e.conn, 0) + 1
        for cid, data in sorted(scan.conns.items()):
            latching = data.get(b"latching")
            self.connections.append(
                RConnection(
                    cid,
                    scan.conn_topic[cid],
                    normalize_msgtype(data.get(b"type", b"").decode()),
                    MessageDefinition(MessageDefinitionFormat.MSG, data.get(b"message_definition", b"").decode()),
                    data.get(b"md5sum", b"").decode(),
                    counts.get(cid, 0),
                    ConnectionExtRosbag1(
                        data[b"callerid"].decode() if b"callerid" in data else None,
                        int(latching) if latching not in (None, b"") else None,
                    ),
                    self,
                )
            )
        self._entries = sorted(e for e in self._entries if e.conn in scan.conns)
        self._topics = dict(scan.conn_topic)

    def _scan_chunk(self, scan: _Scan, chunk: _Chunk, cut: bool = False) -> None:
        """Records the messages of one chunk; damaged records are named and skipped (resynchronising)."""
        try:
            buf = self._chunk_data(chunk)
        except _RecordError as exc:
            self.damage.append(Damage(chunk.pos, None, str(exc)))
            return
        base = chunk.datapos if chunk.compression == "none" else chunk.pos
        where = "" if chunk.compression == "none" else f" (chunk at byte {chunk.pos}, {chunk.compression})"
        p, end = 0, len(buf)
        while p < end:
            try:
                op, fields, dpos, dlen = _record(buf, p, end)
                if op == OP_CONN:
                    scan.add_conn(fields, _fields(buf, dpos, dpos + dlen))
                elif op == OP_MSG:
                    cid = _u32(fields[b"conn"], 0)
                    sec, nsec = struct.unpack("<II", fields[b"time"])
                    if cid not in scan.conn_topic:
                        raise _RecordError(f"message of connection {cid}, which no connection record defines")
                    self._entries.append(Entry(sec * 1_000_000_000 + nsec, chunk.pos, p, cid))
                    scan.last = (base + p, scan.conn_topic[cid])
                else:
                    raise _RecordError(f"record op {op} inside a chunk (expected messages and connections)")
                p = dpos + dlen
            except (_RecordError, KeyError, struct.error) as exc:
                fields = getattr(exc, "fields", {})
                conn = fields.get(b"conn", b"")
                topic = scan.conn_topic.get(_u32(conn, 0)) if len(conn) == 4 else None
                if getattr(exc, "cut", False) and cut:
                    what = f"truncated: the file ends at byte {self.size}, inside this message record{where} ({exc})"
                    self.damage.append(Damage(base + p, topic, what + scan.after(), lost=1))
                    return
                self.damage.append(Damage(base + p, topic, f"message record unreadable{where}: {exc}{scan.after()}"))
                nxt = _resync(buf, p + 1, end, (OP_MSG, OP_CONN))
                if nxt is None:
                    self.damage[-1].what += "; the rest of the chunk is lost"
                    return
                self.damage[-1].what += f"; went on at byte {base + nxt}"
                p = nxt

    def _scan_cut_chunk(self, scan: _Scan, pos: int, fields: dict[bytes, bytes]) -> None:
        """The last chunk of a truncated file: the messages complete before the cut."""
        hlen = _u32(self._mm, pos)
        dpos = pos + 4 + hlen + 4
        comp = fields.get(b"compression", b"none").decode()
        declared = _u32(self._mm, pos + 4 + hlen) if pos + 8 + hlen <= self.size else -1
        present = max(0, self.size - dpos)
        inside = f"the file ends at byte {self.size}, inside"
        if comp != "none":
            what = f"truncated: {inside} this {comp} chunk ({present} of {declared} bytes): its messages are lost"
            self.damage.append(Damage(pos, None, what))
            return
        n = len(self.damage)
        chunk = _Chunk(pos, dpos, present, comp)
        self._chunks[pos] = chunk
        self._scan_chunk(scan, chunk, cut=True)
        if len(self.damage) == n:  # cut exactly at a record boundary
            topic = scan.last[1] if scan.last else None
            what = f"truncated: {inside} the chunk at byte {pos} ({present} of {declared} bytes)"
            self.damage.append(Damage(self.size, topic, what))

    # -- reading ------------------------------------------------------------------------------------------------
    def _chunk_data(self, chunk: _Chunk) -> Any:
        if chunk.compression == "none":
            return memoryview(self._mm)[chunk.datapos : chunk.datapos + chunk.size]
        if self._cache[0] == chunk.pos:
            return self._cache[1]
        raw = bytes(self._mm[chunk.datapos : chunk.datapos + chunk.size])
        try:
            if chunk.compression == "bz2":
                data = bz2.decompress(raw)
            elif chunk.compression == "lz4":
                from lz4.frame import decompress as lz4_decompress

                data = lz4_decompress(raw)
            else:
                raise _RecordError(f"chunk compression {chunk.compression!r}: expected none, bz2 or lz4")
        except (OSError, ValueError, RuntimeError, EOFError) as exc:
            raise _RecordError(f"{chunk.compression} chunk cannot be decompressed: {exc}") from exc
        self._cache = (chunk.pos, data)
        return data

    def offset_of(self, e: Entry) -> int:
        """Byte offset of a message in the file (of its chunk when the chunk is compressed)."""
        c = self._chunks[e.chunk_pos]
        return c.datapos + e.offset if c.compression == "none" else c.pos

    def topic_of(self, e: Entry) -> str:
        return self._topics.get(e.conn, f"connection {e.conn}")

    def read(self, e: Entry) -> bytes:
        """The serialized message of an index entry; damage raises :class:`BagError` naming offset and topic."""
        chunk = self._chunks[e.chunk_pos]
        where = self.offset_of(e)
        try:
            buf = self._chunk_data(chunk)
            p = e.offset
            while True:
                op, fields, dpos, dlen = _record(buf, p, len(buf))
                if op != OP_CONN:
                    break
                p = dpos + dlen
            if op != OP_MSG:
                raise _RecordError(f"record op {op}: expected message data (op {OP_MSG})")
            cid = _u32(fields[b"conn"], 0)
            sec, nsec = struct.unpack("<II", fields[b"time"])
            if cid != e.conn or sec * 1_000_000_000 + nsec != e.time:
                raise _RecordError(
                    f"record header says connection {cid} at {sec}.{nsec:09d} s, the index connection {e.conn} at "
                    f"{e.time / 1e9:.9f} s"
                )
            return bytes(buf[dpos : dpos + dlen])
        except (_RecordError, KeyError, struct.error) as exc:
            raise DamagedRecord(self.path, Damage(where, self.topic_of(e), str(exc), lost=1)) from exc

    def entries(self, connections: Any = ()) -> list[Entry]:
        """Index entries in time order (ties in file order), of ``connections`` (all if empty)."""
        if not connections:
            return list(self._entries)
        ids = {c.id for c in connections}
        return [e for e in self._entries if e.conn in ids]

    def records(
        self, connections: Any = (), on_damage: Callable[[Damage], None] | None = None
    ) -> Iterator[tuple[Any, int, bytes, int]]:
        """(connection, time [ns], raw message, byte offset) in time order. A damaged record raises
        :class:`BagError`, or with ``on_damage`` is reported to it and skipped."""
        by_id = {c.id: c for c in self.connections}
        for e in self.entries(connections):
            try:
                raw = self.read(e)
            except DamagedRecord as exc:
                if on_damage is None:
                    raise
                on_damage(exc.damage)
                continue
            yield by_id[e.conn], e.time, raw, self.offset_of(e)

    def messages(self, connections: Any = ()) -> Iterator[tuple[Any, int, bytes]]:
        """As ``rosbags``' ``Reader.messages``: (connection, time [ns], raw message)."""
        for conn, t, raw, _ in self.records(connections):
            yield conn, t, raw

    def close(self) -> None:
        self._cache = (-1, b"")
        if isinstance(self._mm, mmap.mmap):
            try:
                self._mm.close()
            except BufferError:  # a memoryview of it is still alive; the file closes with it
                pass
        self._file.close()

    def __enter__(self) -> Bag:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
