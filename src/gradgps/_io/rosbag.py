"""ROS bags -> a Table of fixes, from ``sensor_msgs/NavSatFix`` (and ``TwistStamped`` speed).

Robots and research cars record GNSS in ROS bags rather than in CSV or NMEA.
The pure-Python ``rosbags`` package (extra ``ros``) reads ROS 1 ``.bag``
files and ROS 2 bags (a directory with ``metadata.yaml``, or a bare ``.mcap``
or ``.db3`` storage file) without a ROS installation.

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
from pathlib import Path
from typing import Any, Final

import numpy as np
import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table

__all__ = ["NAVSATFIX", "ROSBAG_SUFFIXES", "TWIST_STAMPED", "is_rosbag", "read_rosbag"]

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
    fix_times: np.ndarray, twist_times: list[float], twist_speeds: list[float], max_lag_s: float
) -> np.ndarray:
    """Speed of the twist nearest in time to each fix (NaN when none within ``max_lag_s``)."""
    out = np.full(fix_times.size, np.nan)
    if not twist_times:
        return out
    order = np.argsort(twist_times, kind="stable")
    times = np.asarray(twist_times, np.float64)[order]
    speeds = np.asarray(twist_speeds, np.float64)[order]
    after = np.clip(np.searchsorted(times, fix_times), 0, times.size - 1)
    before = np.clip(after - 1, 0, times.size - 1)
    nearest = np.where(
        np.abs(times[before] - fix_times) <= np.abs(times[after] - fix_times), before, after
    )
    close = np.abs(times[nearest] - fix_times) <= max_lag_s
    out[close] = speeds[nearest[close]]
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
    """
    try:
        from rosbags.highlevel import AnyReader, AnyReaderError
        from rosbags.rosbag1 import ReaderError as Ros1ReaderError
        from rosbags.rosbag2 import ReaderError as Ros2ReaderError
        from rosbags.serde import SerdeError
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(
            "reading ROS bags needs the rosbags package",
            source=str(path),
            hint="pip install 'gradgps[ros]'",
        ) from None
    source = str(path)
    bag = Path(path)
    if not bag.exists():
        raise InputError("no such file or directory", source=source, hint="check the path")
    # ROS 2 bags may not embed their message definitions; these are standard messages.
    store = get_typestore(Stores.ROS2_HUMBLE)
    try:
        with AnyReader([bag], default_typestore=store) as reader:
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
            wanted = [
                c for c in reader.connections if c.topic in fix_topics or c.topic == speed_topic
            ]
            rows: dict[str, list[Any]] = {
                k: [] for k in ("time", "lat", "lon", "alt", "status", "topic")
            }
            twist_times: list[float] = []
            twist_speeds: list[float] = []
            for connection, record_ns, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, connection.msgtype)
                t = _stamp(msg, record_ns)
                if connection.msgtype == TWIST_STAMPED:
                    twist_times.append(t)
                    twist_speeds.append(math.hypot(msg.twist.linear.x, msg.twist.linear.y))
                    continue
                no_fix = int(msg.status.status) == _NO_FIX
                rows["time"].append(t)
                rows["lat"].append(math.nan if no_fix else float(msg.latitude))
                rows["lon"].append(math.nan if no_fix else float(msg.longitude))
                rows["alt"].append(float(msg.altitude))
                rows["status"].append(int(msg.status.status))
                rows["topic"].append(connection.topic)
    except InputError:
        raise
    except (AnyReaderError, Ros1ReaderError, Ros2ReaderError, SerdeError, OSError, KeyError) as exc:
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
    frame = pd.DataFrame(rows)
    if speed_topic is not None:
        frame["speed"] = _speeds(
            frame["time"].to_numpy(np.float64), twist_times, twist_speeds, max_speed_lag_s
        )
    # NavSatStatus as a GGA-style fix quality: NO_FIX (-1) -> 0, FIX -> 1, SBAS/GBAS -> 2.
    status = frame["status"].to_numpy(dtype=np.int64) if len(frame) else np.zeros(0, np.int64)
    frame["fix_quality"] = np.where(status == _NO_FIX, 0, np.minimum(status + 1, 2))
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
    return Table(frame=frame, source=source, columns=columns, notes=notes or None)


def _one_line(exc: BaseException, limit: int = 300) -> str:
    """The bag library's message on one line (YAML errors span several), at most ``limit`` chars."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _listing(types: dict[str, str]) -> str:
    return ", ".join(f"{t} ({m})" for t, m in sorted(types.items())) or "none"
