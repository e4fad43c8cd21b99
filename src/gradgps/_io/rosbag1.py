"""ROS 1 bags (format 2.0) read in bounded memory, in the order ``rosbags`` gives.

Why not ``rosbags.rosbag1.Reader``: on open it builds a Python object for every
message of the bag (about 150 bytes a message: tracemalloc gave 9.8 MB for a bag
of 64,000), so gradgps reading a 1 GB bag of ``NavSatFix`` messages would have
peaked near 1.5 GB (issue 18; ``docs/reliability.md``). This reader
parses the bag's records itself and keeps per *chunk* state only (a few
integers a chunk: a bag chunk holds hundreds of kilobytes of messages), while
the deserialiser and type store stay ``rosbags``' (same classes, same values).

Order. ``rosbags`` yields the messages of the connections asked for sorted by
(record time, the connection's place in the list asked for, the order its index
entries were read: chunk-info order, then the order of the index records after
each chunk), a stable sort of every connection's index followed by
``heapq.merge`` over the connections, whose ties fall to the earlier list. The
same key is used here without an index of the bag: each chunk's entries are
sorted on their own (NumPy arrays, 16 bytes an entry: time int64, rank int32,
offset uint32) and the chunks merged with a heap, a chunk being opened only
when the merge reaches its earliest message (no message of a chunk not yet
open can come first). So the entries held are those of the chunks whose time
ranges span the merge's time: one or two for a bag recorded in time order
(``rosbag record``), a few for a bag of a few time-ordered runs written one
after the other, and every chunk only for a bag whose chunks all overlap (16
bytes a message then: about 90 MB for the 5.6 million messages of a 1 GB bag
of ``NavSatFix``, computed; and such a bag is slow, its chunks decompressed
again whenever the merge comes back to one the cache has let go). Before the
merge, one pass over the index records finds each chunk's earliest message.

Chunks are decompressed (``none``, ``bz2``, ``lz4`` frames, as ``rosbags``
reads them) into a small LRU cache, bounded in count and bytes.

Hostile input: every length and count is checked against the file size before
anything is read or allocated by it, a record header over 1 MiB (they hold a
few fields; a connection's message definition, the longest, a few kilobytes:
a header of many names would be a large dict) or a chunk over 256 MiB (a
recorder writes 768 KiB chunks) is refused, decompression
stops at the chunk's declared size, and every failure is a
:class:`Ros1BagError` of one line (the caller turns it into an ``InputError``).
"""

from __future__ import annotations

import bz2
import heapq
import os
import re
import struct
from array import array
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Final

import numpy as np

__all__ = ["Connection", "Ros1Bag", "Ros1BagError"]

_MSGDATA: Final = 2
_BAGHEADER: Final = 3
_IDXDATA: Final = 4
_CHUNK: Final = 5
_CHUNK_INFO: Final = 6
_CONNECTION: Final = 7
_OPS: Final = {
    _MSGDATA: "message data",
    _BAGHEADER: "bag header",
    _IDXDATA: "index data",
    _CHUNK: "chunk",
    _CHUNK_INFO: "chunk info",
    _CONNECTION: "connection",
}
_MAX_HEADER: Final = 1 << 20
_MAX_CHUNK: Final = 256 << 20
_CACHE_CHUNKS: Final = 8
_CACHE_BYTES: Final = 64 << 20
_COMPRESSIONS: Final = ("none", "bz2", "lz4")
_NS: Final = 1_000_000_000
_U32: Final = struct.Struct("<L")


class Ros1BagError(Exception):
    """A ROS 1 bag this reader cannot read: damaged, or past its limits (a one-line message)."""


@dataclass(frozen=True)
class Connection:
    """A connection record of the bag's index: topic and type as ``rosbags`` normalises them."""

    id: int
    topic: str
    msgtype: str
    msgdef: str
    digest: str


def _fields(raw: bytes, what: str) -> dict[str, bytes]:
    """A record header's ``name=value`` fields (the last of a repeated name wins, as in rosbags)."""
    fields: dict[str, bytes] = {}
    pos = 0
    while pos < len(raw):
        if pos + 4 > len(raw):
            raise Ros1BagError(f"{what}: a header field's size is cut off")
        (size,) = _U32.unpack_from(raw, pos)
        pos += 4
        if pos + size > len(raw):
            raise Ros1BagError(f"{what}: a header field is longer than its header")
        name, sep, value = raw[pos : pos + size].partition(b"=")
        if not sep:
            raise Ros1BagError(f"{what}: a header field has no '='")
        pos += size
        fields[name.decode("utf-8", "replace")] = value
    return fields


def _u32(fields: dict[str, bytes], name: str, what: str) -> int:
    value = fields.get(name)
    if value is None or len(value) < 4:
        raise Ros1BagError(f"{what}: no uint32 field {name!r}")
    return int(_U32.unpack_from(value, 0)[0])


def _u64(fields: dict[str, bytes], name: str, what: str) -> int:
    value = fields.get(name)
    if value is None or len(value) != 8:
        raise Ros1BagError(f"{what}: no uint64 field {name!r}")
    return int.from_bytes(value, "little")


def _op(fields: dict[str, bytes], what: str) -> int:
    value = fields.get("op")
    if value is None or len(value) != 1:
        raise Ros1BagError(f"{what}: no record type ('op' field)")
    return value[0]


def _time(fields: dict[str, bytes], name: str, what: str) -> int:
    """A ``time`` field in nanoseconds, ``sec * 1e9 + nsec`` as rosbags computes it."""
    value = fields.get(name)
    if value is None or len(value) != 8:
        raise Ros1BagError(f"{what}: no time field {name!r}")
    sec, nsec = struct.unpack("<LL", value)
    return int(sec) * _NS + int(nsec)


def _string(fields: dict[str, bytes], name: str, what: str) -> str:
    value = fields.get(name)
    if value is None:
        raise Ros1BagError(f"{what}: no field {name!r}")
    try:
        return value.decode()
    except UnicodeDecodeError:
        raise Ros1BagError(f"{what}: field {name!r} is not UTF-8") from None


def _normalize_topic(name: str) -> str:
    """The topic as ``rosbags.rosbag1`` normalises it (one leading slash kept, no empty parts)."""
    return ("/" if name.startswith("/") else "") + "/".join(x for x in name.split("/") if x)


class _File:
    """The bag file, read at positions only after checking them against its size."""

    def __init__(self, handle: BinaryIO, size: int) -> None:
        self.handle = handle
        self.size = size

    def read(self, pos: int, n: int, what: str) -> bytes:
        if pos < 0 or n < 0 or pos + n > self.size:
            raise Ros1BagError(
                f"{what} at byte {pos} runs past the end of the file "
                f"({n} bytes declared, the file has {self.size})"
            )
        self.handle.seek(pos)
        data = self.handle.read(n)
        if len(data) != n:
            raise Ros1BagError(f"{what} at byte {pos}: the file ended early")
        return data

    def u32(self, pos: int, what: str) -> int:
        return int(_U32.unpack(self.read(pos, 4, what))[0])

    def header(self, pos: int, op: int, what: str) -> tuple[dict[str, bytes], int]:
        """The record header at ``pos`` (of record type ``op``), and where the record's data
        length is."""
        size = self.u32(pos, what)
        if size > _MAX_HEADER:
            raise Ros1BagError(f"{what} at byte {pos}: a header of {size} bytes (over 1 MiB)")
        fields = _fields(self.read(pos + 4, size, what), what)
        have = _op(fields, what)
        if have != op:
            raise Ros1BagError(
                f"{what} at byte {pos}: found a {_OPS.get(have, f'type {have}')} record"
            )
        return fields, pos + 4 + size


@dataclass(frozen=True)
class _ChunkPlace:
    """Where a chunk's data lies in the file and how it is compressed."""

    pos: int
    size: int
    compression: str
    declared: int


class Ros1Bag:
    """An open ROS 1 bag (format 2.0): ``connections``, :meth:`messages`, :meth:`deserialize`,
    the part of ``rosbags.highlevel.AnyReader`` that gradgps uses, with the same values."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.connections: list[Connection] = []
        self._chunk_pos = array("q")
        self._index_counts = array("q")
        self._cache: OrderedDict[int, bytes] = OrderedDict()
        self._cache_bytes = 0
        handle = path.open("rb")
        try:
            self._file = _File(handle, os.fstat(handle.fileno()).st_size)
            self._read_index()
            self.typestore = _typestore(self.connections)
        except BaseException:
            handle.close()
            raise

    def __enter__(self) -> Ros1Bag:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        self._cache.clear()
        self._file.handle.close()

    def _read_index(self) -> None:
        """The bag header, then the connection and chunk-info records at its ``index_pos``."""
        file = self._file
        magic = file.handle.read(64)
        if not magic:
            raise Ros1BagError("the file is empty")
        found = re.match(rb"#ROSBAG V(\d+)\.(\d+)\n", magic)
        if not found:
            raise Ros1BagError("not a ROS 1 bag (no '#ROSBAG V2.0' line)")
        version = int(found[1]) * 100 + int(found[2])
        if version != 200:
            raise Ros1BagError(f"bag version {version} is not supported (only 2.0)")
        header, _ = file.header(found.end(), _BAGHEADER, "bag header")
        index_pos = _u64(header, "index_pos", "bag header")
        conn_count = _u32(header, "conn_count", "bag header")
        chunk_count = _u32(header, "chunk_count", "bag header")
        if header.get("encryptor"):
            raise Ros1BagError("encrypted bags are not supported")
        if index_pos == 0:
            raise Ros1BagError("the bag is not indexed (reindex it: rosbag reindex)")
        if chunk_count == 0:
            return  # rosbags reads no connections then: an empty bag
        if index_pos >= file.size:
            raise Ros1BagError(f"the bag's index at byte {index_pos} is past the end of the file")
        # Every record takes at least 8 bytes: counts beyond that are damage, not a loop.
        if (conn_count + chunk_count) * 8 > file.size - index_pos:
            raise Ros1BagError(
                f"the bag header's counts ({conn_count} connections, {chunk_count} chunks) "
                "do not fit in the file"
            )
        pos = index_pos
        for _ in range(conn_count):
            connection, pos = self._connection(pos)
            self.connections.append(connection)
        for _ in range(chunk_count):
            pos = self._chunk_info(pos)

    def _connection(self, pos: int) -> tuple[Connection, int]:
        what = "connection record"
        fields, pos = self._file.header(pos, _CONNECTION, what)
        conn = _u32(fields, "conn", what)
        topic = _string(fields, "topic", what)
        size = self._file.u32(pos, what)
        if size > _MAX_HEADER:
            raise Ros1BagError(f"{what} at byte {pos}: {size} bytes of data (over 1 MiB)")
        data = _fields(self._file.read(pos + 4, size, what), what)
        from rosbags.typesys.msg import normalize_msgtype

        if not topic:
            raise Ros1BagError(f"{what}: an empty topic name")
        connection = Connection(
            id=conn,
            topic=_normalize_topic(topic),
            msgtype=normalize_msgtype(_string(data, "type", what)),
            msgdef=_string(data, "message_definition", what),
            digest=_string(data, "md5sum", what),
        )
        return connection, pos + 4 + size

    def _chunk_info(self, pos: int) -> int:
        what = "chunk info record"
        fields, pos = self._file.header(pos, _CHUNK_INFO, what)
        version = _u32(fields, "ver", what)
        if version != 1:
            raise Ros1BagError(f"chunk info version {version} is not supported")
        chunk_pos = _u64(fields, "chunk_pos", what)
        if chunk_pos >= self._file.size:
            raise Ros1BagError(f"{what}: a chunk at byte {chunk_pos}, past the end of the file")
        count = _u32(fields, "count", what)
        if count:
            _time(fields, "start_time", what)
            _time(fields, "end_time", what)
        pairs = np.frombuffer(self._file.read(pos + 4, 8 * count, what), "<u4")
        # rosbags reads one index record after the chunk per distinct connection listed here.
        self._chunk_pos.append(chunk_pos)
        self._index_counts.append(int(np.unique(pairs[0::2]).size))
        return pos + 4 + 8 * count

    def _place(self, i: int) -> tuple[_ChunkPlace, int]:
        """Chunk ``i``'s data (checked against the file, not read) and where its index records
        start."""
        what = "chunk record"
        fields, pos = self._file.header(self._chunk_pos[i], _CHUNK, what)
        compression = _string(fields, "compression", what)
        if compression not in _COMPRESSIONS:
            raise Ros1BagError(f"chunk compression {compression!r} is not supported")
        declared = _u32(fields, "size", what) if "size" in fields else _MAX_CHUNK
        size = self._file.u32(pos, what)
        if size > _MAX_CHUNK or (compression != "none" and declared > _MAX_CHUNK):
            raise Ros1BagError(f"{what} at byte {pos}: a chunk over 256 MiB")
        if pos + 4 + size > self._file.size:
            raise Ros1BagError(f"{what} at byte {pos}: {size} bytes run past the end of the file")
        return _ChunkPlace(pos + 4, size, compression, declared), pos + 4 + size

    def _index(self, i: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Chunk ``i``'s index entries in the order rosbags reads them: connection ids,
        times (ns, int64), offsets in the decompressed chunk."""
        _, pos = self._place(i)
        what = "index data record"
        conns, times, offsets = [], [], []
        for _ in range(self._index_counts[i]):
            fields, pos = self._file.header(pos, _IDXDATA, what)
            version = _u32(fields, "ver", what)
            if version != 1:
                raise Ros1BagError(f"index data version {version} is not supported")
            conn = _u32(fields, "conn", what)
            count = _u32(fields, "count", what)
            size = self._file.u32(pos, what)
            if size != 12 * count:
                raise Ros1BagError(f"{what}: {size} bytes for {count} entries")
            table = np.frombuffer(self._file.read(pos + 4, size, what), "<u4").reshape(count, 3)
            pos += 4 + size
            times.append(table[:, 0].astype(np.int64) * _NS + table[:, 1])
            offsets.append(table[:, 2])
            conns.append(np.full(count, conn, np.int64))
        if not conns:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.uint32)
        return np.concatenate(conns), np.concatenate(times), np.concatenate(offsets)

    def messages(
        self, connections: Sequence[Connection] = ()
    ) -> Iterator[tuple[Connection, int, bytes]]:
        """``(connection, record time ns, raw message)`` of ``connections`` (all when empty) in
        rosbags' order: a merge of the chunks, each sorted on its own, opened when the merge
        reaches its earliest message (see the module docstring)."""
        asked = list(connections) or self.connections
        rank: dict[int, int] = {}
        for k, connection in enumerate(asked):
            rank.setdefault(connection.id, k)
        ids = np.array(sorted(rank), np.int64)
        ranks = np.array([rank[i] for i in sorted(rank)], np.int32)
        by_id = {c.id: c for c in self.connections}
        starts, chunks = self._starts(ids)
        heap: list[tuple[int, int, int, int]] = []  # (time, rank, chunk, place in its order)
        opened: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        waiting = 0
        while True:
            # Every chunk that may hold the next message is open: the rest start later.
            while waiting < len(chunks) and (not heap or starts[waiting] <= heap[0][0]):
                i = chunks[waiting]
                waiting += 1
                time, order, offset = opened[i] = self._sorted(i, ids, ranks)
                heapq.heappush(heap, (int(time[0]), int(order[0]), i, 0))
            if not heap:
                return
            ns, _, i, k = heap[0]
            time, order, offset = opened[i]
            yield self._message(i, int(offset[k]), ns, by_id)
            if k + 1 < time.size:
                heapq.heapreplace(heap, (int(time[k + 1]), int(order[k + 1]), i, k + 1))
            else:
                heapq.heappop(heap)
                del opened[i]

    def _starts(self, ids: np.ndarray) -> tuple[list[int], list[int]]:
        """The earliest wanted message time of each chunk holding any, and those chunks, sorted
        by that time (then chunk-info order)."""
        starts, chunks = array("q"), array("q")
        for i in range(len(self._chunk_pos)):
            conns, times, _ = self._index(i)
            times = times[np.isin(conns, ids)]
            if times.size:
                starts.append(int(times.min()))
                chunks.append(i)
        first = np.frombuffer(starts, np.int64)
        order = np.argsort(first, kind="stable")
        return first[order].tolist(), np.frombuffer(chunks, np.int64)[order].tolist()

    def _sorted(
        self, i: int, ids: np.ndarray, ranks: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Chunk ``i``'s wanted entries sorted by (time, rank), ties in index order: times,
        ranks, offsets (16 bytes an entry)."""
        conns, times, offsets = self._index(i)
        keep = np.isin(conns, ids)
        time, offset = times[keep], offsets[keep]
        rank = ranks[np.searchsorted(ids, conns[keep])]
        order = np.lexsort((rank, time))  # stable
        return time[order], rank[order], offset[order]

    def _message(
        self, i: int, offset: int, time: int, by_id: dict[int, Connection]
    ) -> tuple[Connection, int, bytes]:
        """The message record at ``offset`` of chunk ``i`` (connection records before it
        skipped, as rosbags does)."""
        data = self._chunk(i)
        what = f"message in the chunk at byte {self._chunk_pos[i]}"
        pos = offset
        while True:
            fields, pos = _header_in(data, pos, what)
            op = _op(fields, what)
            if op != _CONNECTION:
                break
            pos += 4 + _u32_in(data, pos, what)
        if op != _MSGDATA:
            raise Ros1BagError(f"{what}: expected message data, found a {_OPS.get(op, op)} record")
        size = _u32_in(data, pos, what)
        if pos + 4 + size > len(data):
            raise Ros1BagError(f"{what}: the message runs past the end of its chunk")
        conn = _u32(fields, "conn", what)
        connection = by_id.get(conn)
        if connection is None:
            raise Ros1BagError(f"{what}: connection {conn} is not in the bag's index")
        if _time(fields, "time", what) != time:
            raise Ros1BagError(f"{what}: its time is not the index's")
        return connection, time, data[pos + 4 : pos + 4 + size]

    def _chunk(self, i: int) -> bytes:
        """Chunk ``i`` decompressed, from a small LRU cache (a few chunks, at most 64 MiB held
        besides the chunk in use)."""
        cached = self._cache.get(i)
        if cached is not None:
            self._cache.move_to_end(i)
            return cached
        place, _ = self._place(i)
        raw = self._file.read(place.pos, place.size, "chunk data")
        data = _decompress(raw, place.compression, place.declared)
        self._cache[i] = data
        self._cache_bytes += len(data)
        while len(self._cache) > 1 and (
            len(self._cache) > _CACHE_CHUNKS or self._cache_bytes > _CACHE_BYTES
        ):
            _, dropped = self._cache.popitem(last=False)
            self._cache_bytes -= len(dropped)
        return data

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        """The message as rosbags' ROS 1 deserialiser gives it, with the bag's own types."""
        return self.typestore.deserialize_ros1(raw, msgtype)


def _header_in(data: bytes, pos: int, what: str) -> tuple[dict[str, bytes], int]:
    size = _u32_in(data, pos, what)
    if size > _MAX_HEADER:
        raise Ros1BagError(f"{what}: a header of {size} bytes (over 1 MiB)")
    if pos + 4 + size > len(data):
        raise Ros1BagError(f"{what}: a record header runs past the end of its chunk")
    return _fields(data[pos + 4 : pos + 4 + size], what), pos + 4 + size


def _u32_in(data: bytes, pos: int, what: str) -> int:
    if pos < 0 or pos + 4 > len(data):
        raise Ros1BagError(f"{what}: offset {pos} is outside its chunk of {len(data)} bytes")
    return int(_U32.unpack_from(data, pos)[0])


def _decompress(raw: bytes, compression: str, declared: int) -> bytes:
    """A chunk's bytes, at most ``declared`` of them (``none`` as is: rosbags ignores the size).
    A stream that does not end, or ends past the declared size, is damage."""
    if compression == "none":
        return raw
    decompressor: Any
    if compression == "bz2":
        decompressor = bz2.BZ2Decompressor()
    else:
        import lz4.frame  # type: ignore[import-untyped]  # a rosbags dependency

        decompressor = lz4.frame.LZ4FrameDecompressor()
    try:
        data = bytes(decompressor.decompress(raw, max_length=declared + 1))
    except (OSError, RuntimeError, ValueError, EOFError) as exc:
        raise Ros1BagError(f"a {compression} chunk does not decompress ({exc})") from None
    if len(data) > declared:
        raise Ros1BagError(f"a {compression} chunk holds more than its declared {declared} bytes")
    if not decompressor.eof:
        raise Ros1BagError(f"a {compression} chunk is cut off")
    return data


def _typestore(connections: list[Connection]) -> Any:
    """The types of the bag's message definitions, checked against their MD5 sums, as
    ``rosbags.highlevel.AnyReader`` builds them for a ROS 1 bag."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    types: dict[str, Any] = {}
    digests: dict[str, str] = {}
    for connection in connections:
        types.update(get_types_from_msg(connection.msgdef, connection.msgtype))
        if connection.digest:
            digests[connection.msgtype] = connection.digest
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    for msgtype, digest in digests.items():
        have = store.generate_msgdef(msgtype)[1]
        if have != digest:
            raise Ros1BagError(f"message type {msgtype!r} hash mismatch {have} != {digest}")
    return store
