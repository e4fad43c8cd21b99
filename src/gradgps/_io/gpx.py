"""GPX 1.0 / 1.1 files -> a Table of track points.

Parsed with the standard library's expat parser, streaming, so that every
problem can name its file line: expat reports the line of malformed XML, and
the reader knows the line of each ``<trkpt>`` when a value inside it is bad.
expat fetches no external entities and (from version 2.4, bundled with every
supported Python) caps entity expansion, so a hostile file cannot make the
reader fetch URLs or exhaust memory.

Each ``<trkseg>`` becomes its own track, with id ``"<track>/<segment>"``:
``<track>`` is the ``<trk>``'s ``<name>`` (or its 0-based index when it has
none, or ``"<name> #<index>"`` when an earlier track has the same name) and
``<segment>`` the 0-based segment index within the track. A segment is a
continuous recording in GPX, so the gap between segments is never bridged.

Columns: ``track``, ``time`` (ISO-8601 UTC text as every mode writes GPX
times, e.g. ``2019-05-23T20:54:11Z``, see :mod:`gradgps._io.times`; empty
where absent; the seconds are kept as ``Table.times``), ``lat``,
``lon``, ``alt`` (from ``<ele>``) and, when any point has them, ``speed``
(m/s), ``course`` (degrees; also read from ``heading``), ``hdop``,
``satellites`` (from ``<sat>``) and ``fix`` (the ``<fix>`` text: ``none``,
``2d``, ``3d``, ``dgps``, ``pps``; ``none`` or 0 satellites makes the point an
invalid fix, ``receiver reports no fix``). Values are looked up among the point's direct children first
and then inside ``<extensions>`` (Garmin ``TrackPointExtension``, OsmAnd and
similar put ``speed``/``course`` there), whatever the namespace.
Waypoints and routes are plans, not recordings, and are ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final
from xml.parsers import expat

import numpy as np
import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table, datetime_seconds
from .files import READ_ERRORS, open_bytes
from .times import iso_utc

__all__ = ["read_gpx"]

# Element local name -> output column, for the optional per-point values.
_VALUE_TAGS: Final = {
    "ele": "alt",
    "speed": "speed",
    "course": "course",
    "heading": "course",
    "hdop": "hdop",
    "sat": "satellites",
}
_OPTIONAL: Final = ("speed", "course", "hdop", "satellites")
#: ``<fix>``: the receiver's fix type (none, 2d, 3d, dgps, pps), kept as text.
_FIX: Final = "fix"


def _local(tag: str) -> str:
    # With namespace_separator=" ", expat names are "uri local" or just "local".
    return tag.rsplit(" ", 1)[-1]


@dataclass
class _Collector:
    """expat callbacks building the point table; knows where in the document it is."""

    source: str
    parser: expat.XMLParserType
    rows: dict[str, list[object]] = field(
        default_factory=lambda: {
            k: [] for k in ("track", "time", "lat", "lon", "alt", *_OPTIONAL, _FIX)
        }
    )
    lines: list[int] = field(default_factory=list)
    stack: list[str] = field(default_factory=list)
    track_index: int = -1
    segment_index: int = -1
    track_name: str | None = None
    names_seen: set[str] = field(default_factory=set)
    track_id: str = ""
    point: dict[str, str] | None = None
    text: list[str] = field(default_factory=list)
    other_points: int = 0

    def start(self, tag: str, attrs: dict[str, str]) -> None:
        name = _local(tag)
        parent = self.stack[-1] if self.stack else ""
        self.stack.append(name)
        self.text = []
        if name == "trk":
            self.track_index += 1
            self.segment_index = -1
            self.track_name = None
        elif name == "trkseg" and parent == "trk":
            self.segment_index += 1
        elif name == "trkpt" and parent == "trkseg":
            self.track_id = f"{self._track_label()}/{self.segment_index}"
            self.point = {"lat": attrs.get("lat", ""), "lon": attrs.get("lon", "")}
            self.lines.append(self.parser.CurrentLineNumber)
        elif name in ("wpt", "rtept"):
            self.other_points += 1

    def _track_label(self) -> str:
        if self.track_name is None or self.track_name == "":
            return str(self.track_index)
        return self.track_name

    def end(self, tag: str) -> None:
        name = _local(tag)
        self.stack.pop()
        parent = self.stack[-1] if self.stack else ""
        text = "".join(self.text).strip()
        self.text = []
        if name == "name" and parent == "trk":
            self.track_name = text if text not in self.names_seen else f"{text} #{self.track_index}"
            self.names_seen.add(self.track_name)
        elif name == "trkpt" and self.point is not None:
            self._add_point(self.point)
            self.point = None
        elif self.point is not None:
            key = name if name in ("time", _FIX) else _VALUE_TAGS.get(name)
            # First occurrence wins: direct children precede <extensions>.
            if key is not None:
                self.point.setdefault(key, text)

    def characters(self, data: str) -> None:
        self.text.append(data)

    def _add_point(self, point: dict[str, str]) -> None:
        line = self.lines[-1]
        self.rows["track"].append(self.track_id)
        self.rows["time"].append(point.get("time", ""))
        for key in ("lat", "lon", "alt", *_OPTIONAL):
            self.rows[key].append(self._number(point.get(key, ""), key, line))
        self.rows[_FIX].append(point.get(_FIX, ""))

    def _number(self, text: str, key: str, line: int) -> float:
        if text == "":
            return math.nan
        try:
            return float(text)
        except ValueError:
            raise InputError(
                f"track point {key} is not a number: {text!r}",
                source=self.source,
                line=line,
                hint="fix the value in the file",
            ) from None


def read_gpx(path: str | Path) -> Table:
    """Read the track points of a GPX file (optionally ``.gz``); see the module docstring."""
    path = Path(path)
    source = str(path)
    parser = expat.ParserCreate(namespace_separator=" ")
    collector = _Collector(source=source, parser=parser)
    parser.StartElementHandler = collector.start
    parser.EndElementHandler = collector.end
    parser.CharacterDataHandler = collector.characters
    with open_bytes(path) as raw:
        try:
            parser.ParseFile(raw)
        except expat.ExpatError as exc:
            raise InputError(
                f"malformed XML: {expat.errors.messages[exc.code]} (column {exc.offset + 1})",
                source=source,
                line=exc.lineno,
                hint="the file is cut off or not GPX; repair it or pass the right format",
            ) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=source) from None
    rows = collector.rows
    n = len(rows["track"])
    if n == 0:
        extra = (
            f" ({collector.other_points} waypoints/route points, which are plans, not recordings)"
            if collector.other_points
            else ""
        )
        raise InputError(
            f"no track points (<trkpt>) in the file{extra}",
            source=source,
            hint="export the recorded track, not a route",
        )
    seconds = datetime_seconds(_times(rows["time"], collector.lines, source))
    frame: dict[str, object] = {
        "track": np.array(rows["track"], dtype=object),
        "time": iso_utc(seconds),
        "lat": np.array(rows["lat"], dtype=np.float64),
        "lon": np.array(rows["lon"], dtype=np.float64),
        "alt": np.array(rows["alt"], dtype=np.float64),
    }
    for key in _OPTIONAL:
        values = np.array(rows[key], dtype=np.float64)
        if np.isfinite(values).any():
            frame[key] = values
    if any(rows[_FIX]):
        frame[_FIX] = np.array(rows[_FIX], dtype=object)
    columns = ColumnMap(
        time="time",
        lat="lat",
        lon="lon",
        track="track",
        alt="alt",
        speed="speed" if "speed" in frame else "",
        heading="course" if "course" in frame else "",
        hdop="hdop" if "hdop" in frame else "",
        fix_quality=_FIX if _FIX in frame else "",
        satellites="satellites" if "satellites" in frame else "",
    )
    return Table(frame=pd.DataFrame(frame), source=source, columns=columns, times=seconds)


def _times(texts: list[object], lines: list[int], source: str) -> pd.Series:
    """ISO-8601 ``<time>`` texts -> UTC datetimes; a bad one is an error naming its line."""
    series = pd.Series(texts, dtype="string")
    blank = (series == "").to_numpy()
    try:
        parsed = pd.to_datetime(
            series.where(~blank, None), utc=True, format="ISO8601", errors="coerce"
        )
    except (ValueError, OverflowError):
        # Some strings make the vectorised parser raise instead of coerce;
        # parse one by one so the culprit can be named.
        parsed = pd.to_datetime(
            pd.Series(
                [None if b else _timestamp(str(t)) for t, b in zip(texts, blank, strict=True)]
            ),
            utc=True,
        )
    bad = parsed.isna().to_numpy() & ~blank
    if bad.any():
        pos = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"track point time is not ISO-8601: {texts[pos]!r}",
            source=source,
            line=lines[pos],
            hint="GPX times look like 2019-05-23T20:54:11Z",
        )
    return parsed


def _timestamp(text: str) -> pd.Timestamp | None:
    try:
        stamp = pd.Timestamp(text)
    except (ValueError, OverflowError):
        return None
    return stamp if stamp.tzinfo is not None else stamp.tz_localize("UTC")
