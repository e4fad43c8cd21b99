"""ROS bags -> a Table of fixes, from ``sensor_msgs/NavSatFix`` (and ``TwistStamped`` speed).

Robots and research cars record GNSS in ROS bags rather than in CSV or NMEA.
The pure-Python ``rosbags`` package (extra ``ros``) reads ROS 2 bags (a
directory with ``metadata.yaml``, or a bare ``.mcap`` or ``.db3`` storage file)
without a ROS installation, and deserialises ROS 1 messages; a ROS 1 ``.bag``'s
records are read by :mod:`gradgps._io.rosbag1` (``rosbags``' own ROS 1 reader
holds an index entry for every message of the bag: issue 18), in the same order.

What is read:

* every ``sensor_msgs/msg/NavSatFix`` topic (or only ``fix_topic``): one row
  per message; ``time`` is the message header stamp (the receiver's time of
  the fix), or the bag's record time when the stamp is zero (drivers that do
  not fill it); ``lat``/``lon``/``alt`` as given; ``status`` the NavSatStatus
  (``-1`` = no fix: the row is kept with NaN position, so it is reported as an
  invalid fix, ``receiver reports no fix``, rather than lost, as the NMEA
  reader does), also as ``fix_quality`` (GGA-style: -1 -> 0, FIX -> 1,
  SBAS/GBAS -> 2); ``topic`` names the
  track when there are several receivers;
* optionally the speed from a ``geometry_msgs/msg/TwistStamped`` topic
  (``twist_topic``, or the only such topic in the bag):
  ``speed = hypot(linear.x, linear.y)`` (horizontal speed, whatever the frame),
  matched to each fix by nearest stamp within ``max_speed_lag_s``. No heading
  is taken from it: the twist frame (ENU, body, odom) is not recorded in the
  message, and a wrong heading is worse than none.
"""

from __future__ import annotations

import math
import os
from array import array
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table
from .rosbag1 import Ros1Bag, Ros1BagError
from .streamed import StreamedChunks

__all__ = [
    "NAVSATFIX",
    "ROSBAG_SUFFIXES",
    "TWIST_STAMPED",
    "BagChunks",
    "is_rosbag",
    "read_rosbag",
    "rosbag_tables",
]

NAVSATFIX: Final = "sensor_msgs/msg/NavSatFix"
TWIST_STAMPED: Final = "geometry_msgs/msg/TwistStamped"
ROSBAG_SUFFIXES: Final = (".bag", ".mcap", ".db3")
_NO_FIX: Final = -1


def is_rosbag(path: str | os.PathLike[str]) -> bool:
    """A ROS 1 ``.bag``, a ROS 2 storage file, or a ROS 2 bag directory (has ``metadata.yaml``)."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in ROSBAG_SUFFIXES


def _stamp(message: Any, record_ns: int) -> float:
    stamp = message.header.stamp
    seconds = float(stamp.sec) + 1e-9 * float(stamp.nanosec)
    return seconds if seconds > 0.0 else record_ns * 1e-9


def _speeds(
    fix_times: np.ndarray,
    twist_times: Sequence[float] | np.ndarray,
    twist_speeds: Sequence[float] | np.ndarray,
    max_lag_s: float,
) -> np.ndarray:
    """Speed of the twist nearest in time to each fix (NaN when none within ``max_lag_s``)."""
    return _Twists(twist_times, twist_speeds).nearest(fix_times, max_lag_s)


class _Twists:
    """A bag's twist speeds by stamp, sorted once, for fixes looked up chunk by chunk."""

    def __init__(
        self, times: Sequence[float] | np.ndarray, speeds: Sequence[float] | np.ndarray
    ) -> None:
        order = np.argsort(np.asarray(times, np.float64), kind="stable")
        self.times = np.asarray(times, np.float64)[order]
        self.speeds = np.asarray(speeds, np.float64)[order]

    def nearest(self, fix_times: np.ndarray, max_lag_s: float) -> np.ndarray:
        out = np.full(fix_times.size, np.nan)
        times = self.times
        if not times.size:
            return out
        after = np.clip(np.searchsorted(times, fix_times), 0, times.size - 1)
        before = np.clip(after - 1, 0, times.size - 1)
        nearest = np.where(
            np.abs(times[before] - fix_times) <= np.abs(times[after] - fix_times), before, after
        )
        close = np.abs(times[nearest] - fix_times) <= max_lag_s
        out[close] = self.speeds[nearest[close]]
        return out


def read_rosbag(
    path: str | os.PathLike[str],
    *,
    fix_topic: str | None = None,
    twist_topic: str | None = None,
    max_speed_lag_s: float = 0.5,
) -> Table:
    """Read the fixes of a ROS 1 or ROS 2 bag into a Table (see the module docstring).

    Columns: ``time`` (unix s), ``lat``, ``lon``, ``alt``, ``status``,
    ``topic``, ``fix_quality``, and ``speed`` (m/s) when a twist topic is found.
    The whole bag as one chunk of :func:`rosbag_tables`.
    """
    bag = rosbag_tables(
        path,
        2**62,
        fix_topic=fix_topic,
        twist_topic=twist_topic,
        max_speed_lag_s=max_speed_lag_s,
    )
    tables = list(bag.chunks)
    if tables:
        return tables[0]
    empty = _frame(_Rows(), bag.header, None, max_speed_lag_s)
    return Table(frame=empty, source=str(path), columns=bag.columns, notes=bag.notes)


@dataclass(frozen=True)
class BagChunks(StreamedChunks):
    """A bag's fixes as chunks (:func:`rosbag_tables`), with the bag's notes."""

    notes: list[str] | None = None


class _Rows:
    """One chunk's rows as they are read (a list per column)."""

    def __init__(self) -> None:
        self.columns: dict[str, list[Any]] = {
            k: [] for k in ("time", "lat", "lon", "alt", "status", "topic")
        }

    def __len__(self) -> int:
        return len(self.columns["time"])


def _frame(
    rows: _Rows, header: tuple[str, ...], twists: _Twists | None, max_lag_s: float
) -> pd.DataFrame:
    frame = pd.DataFrame(rows.columns)
    if "speed" in header:
        frame["speed"] = (
            twists.nearest(frame["time"].to_numpy(np.float64), max_lag_s)
            if twists is not None
            else np.full(len(frame), np.nan)
        )
    # NavSatStatus as a GGA-style fix quality: NO_FIX (-1) -> 0, FIX -> 1, SBAS/GBAS -> 2.
    status = frame["status"].to_numpy(dtype=np.int64) if len(frame) else np.zeros(0, np.int64)
    frame["fix_quality"] = np.where(status == _NO_FIX, 0, np.minimum(status + 1, 2))
    return frame


def rosbag_tables(
    path: str | os.PathLike[str],
    chunksize: int,
    *,
    fix_topic: str | None = None,
    twist_topic: str | None = None,
    max_speed_lag_s: float = 0.5,
) -> BagChunks:
    """The fixes of a ROS bag (see the module docstring) as Tables of at most ``chunksize``
    rows, in bounded memory, in two passes (issue 18: the bag was read whole). The first
    reads the topics, counts the fixes and keeps each twist's stamp and speed (16 bytes a
    twist: a fix's speed is the twist nearest in time, which may come later in the bag);
    the second deserialises the fixes, a chunk at a time. Rows, values and columns are
    those of :func:`read_rosbag`, which is this with one chunk."""
    source = str(path)
    bag = Path(path)
    if not bag.exists():
        raise InputError("no such file or directory", source=source, hint="check the path")
    with _bag_errors(source), _open_bag(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        fix_topics = (
            [fix_topic] if fix_topic else sorted(t for t, m in types.items() if m == NAVSATFIX)
        )
        for topic in fix_topics:
            if types.get(topic) != NAVSATFIX:
                raise InputError(
                    f"topic {topic!r} is not a {NAVSATFIX} topic",
                    source=source,
                    hint=f"topics in the bag: {_listing(types)}",
                )
        if not fix_topics:
            raise InputError(
                f"no {NAVSATFIX} topic in the bag",
                source=source,
                hint=f"topics in the bag: {_listing(types)}",
            )
        twists = sorted(t for t, m in types.items() if m == TWIST_STAMPED)
        notes: list[str] = []
        if twist_topic is not None and types.get(twist_topic) != TWIST_STAMPED:
            raise InputError(
                f"topic {twist_topic!r} is not a {TWIST_STAMPED} topic",
                source=source,
                hint=f"topics in the bag: {_listing(types)}",
            )
        speed_topic = twist_topic or (twists[0] if len(twists) == 1 else None)
        if speed_topic is None and len(twists) > 1:
            notes.append(
                f"several {TWIST_STAMPED} topics ({', '.join(twists)}): no speed "
                "read; name one to use it"
            )
        wanted = [c for c in reader.connections if c.topic in fix_topics or c.topic == speed_topic]
        n_rows = 0
        twist_times, twist_speeds = array("d"), array("d")
        for connection, record_ns, raw in reader.messages(connections=wanted):
            if connection.msgtype != TWIST_STAMPED:
                n_rows += 1
                continue
            msg: Any = reader.deserialize(raw, connection.msgtype)
            twist_times.append(_stamp(msg, record_ns))
            twist_speeds.append(math.hypot(msg.twist.linear.x, msg.twist.linear.y))
    speeds = _Twists(twist_times, twist_speeds) if speed_topic is not None else None
    del twist_times, twist_speeds
    header: tuple[str, ...] = ("time", "lat", "lon", "alt", "status", "topic")
    header += ("speed", "fix_quality") if speed_topic is not None else ("fix_quality",)
    columns = ColumnMap(
        time="time",
        lat="lat",
        lon="lon",
        track="topic" if len(fix_topics) > 1 else "",
        speed="speed" if speed_topic is not None else "",
        heading="",
        alt="alt",
        hdop="",
        fix_quality="fix_quality",
        satellites="",
    )
    topics = {c.topic for c in wanted if c.msgtype == NAVSATFIX}

    def chunks() -> Iterator[Table]:
        offset = 0
        rows = _Rows()
        with _bag_errors(source), _open_bag(bag) as reader:
            again = [c for c in reader.connections if c.topic in topics or c.topic == speed_topic]
            for connection, record_ns, raw in reader.messages(connections=again):
                if connection.msgtype == TWIST_STAMPED:
                    continue
                msg: Any = reader.deserialize(raw, connection.msgtype)
                no_fix = int(msg.status.status) == _NO_FIX
                rows.columns["time"].append(_stamp(msg, record_ns))
                rows.columns["lat"].append(math.nan if no_fix else float(msg.latitude))
                rows.columns["lon"].append(math.nan if no_fix else float(msg.longitude))
                rows.columns["alt"].append(float(msg.altitude))
                rows.columns["status"].append(int(msg.status.status))
                rows.columns["topic"].append(connection.topic)
                if len(rows) == chunksize:
                    frame = _frame(rows, header, speeds, max_speed_lag_s)
                    yield _table(frame, source, columns, notes, offset)
                    offset += len(frame)
                    rows = _Rows()
        if len(rows):
            yield _table(
                _frame(rows, header, speeds, max_speed_lag_s), source, columns, notes, offset
            )

    return BagChunks(
        n_rows=n_rows, header=header, columns=columns, chunks=chunks(), notes=notes or None
    )


def _table(
    frame: pd.DataFrame, source: str, columns: ColumnMap, notes: list[str], offset: int
) -> Table:
    return Table(
        frame=frame, source=source, columns=columns, notes=notes or None, row_offset=offset
    )


@contextmanager
def _open_bag(bag: Path) -> Iterator[Any]:
    """A ROS 1 ``.bag`` open in :class:`~gradgps._io.rosbag1.Ros1Bag` (bounded memory, the
    messages and values of rosbags' reader: issue 18), anything else in rosbags'
    ``AnyReader`` (a message of the standard types can be read without definitions in the
    bag: ROS 2 bags may not embed them). ``.bag`` exactly, as ``AnyReader`` tells them apart."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(
            "reading ROS bags needs the rosbags package",
            source=str(bag),
            hint="pip install 'gradgps[ros]'",
        ) from None
    if bag.suffix == ".bag":
        with Ros1Bag(bag) as ros1:
            yield ros1
        return
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
        yield reader


@contextmanager
def _bag_errors(source: str) -> Iterator[None]:
    """Any failure of the bag library as one :class:`InputError` naming the bag."""
    try:
        from rosbags.highlevel import AnyReaderError
        from rosbags.rosbag2 import ReaderError as Ros2ReaderError
        from rosbags.serde import SerdeError
    except ImportError:
        raise InputError(
            "reading ROS bags needs the rosbags package",
            source=source,
            hint="pip install 'gradgps[ros]'",
        ) from None
    try:
        yield
    except InputError:
        raise
    except Ros1BagError as exc:
        raise InputError(
            f"cannot read the ROS 1 bag: {_one_line(exc)}",
            source=source,
            hint="a damaged bag may be repaired with rosbag reindex",
        ) from None
    except (
        AnyReaderError,
        Ros2ReaderError,
        SerdeError,
        OSError,
        KeyError,
    ) as exc:
        raise InputError(
            f"cannot read the ROS bag: {_one_line(exc)}",
            source=source,
            hint="is this a ROS 1 .bag, or a ROS 2 bag directory / .mcap / .db3?",
        ) from None
    except Exception as exc:
        # rosbags parses with assertions, str.decode and struct.unpack: a damaged bag
        # surfaces as AssertionError, UnicodeDecodeError, struct.error, IndexError, ...
        raise InputError(
            f"cannot read the ROS bag, it is damaged ({type(exc).__name__}: {_one_line(exc)})",
            source=source,
            hint="re-record or repair it (rosbag reindex for ROS 1)",
        ) from None


def _one_line(exc: BaseException, limit: int = 300) -> str:
    """The bag library's message on one line (YAML errors span several), at most ``limit`` chars."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _listing(types: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(types.items())) or "none"
