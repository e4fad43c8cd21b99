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
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final
from xml.parsers import expat

import numpy as np
import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table, datetime_seconds
from .files import READ_ERRORS, open_bytes
from .streamed import StreamedChunks
from .times import iso_utc

__all__ = ["gpx_tables", "read_gpx"]

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
#: Longest element text kept (a longer track name, time or value is an error; any other
#: text, a description, is not read beyond it).
MAX_TEXT_CHARS: Final = 1 << 20
#: Most bytes expat may hold unparsed: it keeps a token (a tag with its attributes, a
#: comment, a processing instruction) whole until its end, so without a bound a
#: gigabyte-long tag name would be held whole (issue 18). Element text is not a token: it
#: reaches the handlers as it comes, and :data:`MAX_TEXT_CHARS` bounds what is kept of it.
MAX_MARKUP_BYTES: Final = 1 << 20
#: ``<fix>``: the receiver's fix type (none, 2d, 3d, dgps, pps), kept as text.
_FIX: Final = "fix"


def _local(tag: str) -> str:
    # With namespace_separator=" ", expat names are "uri local" or just "local".
    return tag.rsplit(" ", 1)[-1]


@dataclass
class _Collector:
    """expat callbacks building the point table; knows where in the document it is.

    ``rows``/``lines`` hold the points parsed since the last :meth:`take` (all of
    them when nothing is taken), so a file can be read in chunks of points.
    """

    source: str
    parser: expat.XMLParserType
    rows: dict[str, list[object]] = field(default_factory=lambda: _no_rows())
    lines: list[int] = field(default_factory=list)
    stack: list[str] = field(default_factory=list)
    track_index: int = -1
    segment_index: int = -1
    track_name: str | None = None
    names_seen: set[str] = field(default_factory=set)
    track_id: str = ""
    point: dict[str, str] | None = None
    point_line: int = 0
    text: list[str] = field(default_factory=list)
    text_chars: int = 0  # of the current element's text, kept up to MAX_TEXT_CHARS
    other_points: int = 0
    points: int = 0

    def start(self, tag: str, attrs: dict[str, str]) -> None:
        name = _local(tag)
        parent = self.stack[-1] if self.stack else ""
        self.stack.append(name)
        self.text = []
        self.text_chars = 0
        if name == "trk":
            self.track_index += 1
            self.segment_index = -1
            self.track_name = None
        elif name == "trkseg" and parent == "trk":
            self.segment_index += 1
        elif name == "trkpt" and parent == "trkseg":
            self.track_id = f"{self._track_label()}/{self.segment_index}"
            self.point = {"lat": attrs.get("lat", ""), "lon": attrs.get("lon", "")}
            self.point_line = self.parser.CurrentLineNumber
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
        too_long = self.text_chars > MAX_TEXT_CHARS
        self.text = []
        self.text_chars = 0
        used = (name == "name" and parent == "trk") or (
            self.point is not None and (name in ("time", _FIX) or name in _VALUE_TAGS)
        )
        if too_long and used:
            raise InputError(
                f"<{name}> holds more than {MAX_TEXT_CHARS:,} characters",
                source=self.source,
                line=self.parser.CurrentLineNumber,
                hint="no GPX name, time or value is that long: is this the right file?",
            )
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
        # Kept up to MAX_TEXT_CHARS: a huge text (a description, hostile input) never
        # sits in memory whole; the reader refuses one it would have to use.
        if self.text_chars <= MAX_TEXT_CHARS:
            self.text.append(data[: MAX_TEXT_CHARS + 1 - self.text_chars])
        self.text_chars += len(data)

    def _add_point(self, point: dict[str, str]) -> None:
        line = self.point_line
        self.lines.append(line)
        self.points += 1
        self.rows["track"].append(self.track_id)
        self.rows["time"].append(point.get("time", ""))
        for key in ("lat", "lon", "alt", *_OPTIONAL):
            self.rows[key].append(self._number(point.get(key, ""), key, line))
        self.rows[_FIX].append(point.get(_FIX, ""))

    def take(self, n: int | None = None) -> tuple[dict[str, list[object]], list[int]]:
        """The first ``n`` (``None``: all) points parsed since the last call, and their lines."""
        if n is None or n >= len(self.lines):
            rows, lines = self.rows, self.lines
            self.rows, self.lines = _no_rows(), []
            return rows, lines
        rows = {k: v[:n] for k, v in self.rows.items()}
        lines = self.lines[:n]
        self.rows = {k: v[n:] for k, v in self.rows.items()}
        self.lines = self.lines[n:]
        return rows, lines

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


def _no_rows() -> dict[str, list[object]]:
    return {k: [] for k in ("track", "time", "lat", "lon", "alt", *_OPTIONAL, _FIX)}


#: Bytes handed to expat at a time when a file is read in chunks of points.
_BLOCK_BYTES: Final = 1 << 16


def _point_lists(
    path: Path, chunk_points: int | None
) -> Iterator[tuple[dict[str, list[object]], list[int]]]:
    """The track points of a GPX file as lists (``rows``, ``lines``), ``chunk_points`` at a
    time (``None``: all at once); never an empty chunk. Raises for a file without points."""
    source = str(path)
    parser = expat.ParserCreate(namespace_separator=" ")
    collector = _Collector(source=source, parser=parser)
    parser.StartElementHandler = collector.start
    parser.EndElementHandler = collector.end
    parser.CharacterDataHandler = collector.characters
    with open_bytes(path) as raw:
        try:
            fed = 0
            while block := raw.read(_BLOCK_BYTES):
                parser.Parse(block, False)
                fed += len(block)
                if fed - parser.CurrentByteIndex > MAX_MARKUP_BYTES:
                    raise InputError(
                        f"a tag, attribute, comment or other markup longer than "
                        f"{MAX_MARKUP_BYTES:,} bytes",
                        source=source,
                        line=parser.CurrentLineNumber,
                        hint="the file is damaged or not GPX",
                    )
                while chunk_points is not None and len(collector.lines) >= chunk_points:
                    yield collector.take(chunk_points)
            parser.Parse(b"", True)
        except expat.ExpatError as exc:
            raise InputError(
                f"malformed XML: {expat.errors.messages[exc.code]} (column {exc.offset + 1})",
                source=source,
                line=exc.lineno,
                hint="the file is cut off or not GPX; repair it or pass the right format",
            ) from None
        except READ_ERRORS as exc:
            raise InputError(f"cannot read: {exc}", source=source) from None
    if collector.points == 0:
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
    while collector.lines:
        yield collector.take(chunk_points)


def _needs_nanoseconds(parsed: pd.Series) -> bool:
    """Whether pandas parsed these times in nanoseconds (sub-microsecond digits)."""
    return getattr(parsed.dtype, "unit", "ns") == "ns"


def _used(rows: dict[str, list[object]]) -> set[str]:
    """The optional columns these points give a value to."""
    used = {key for key in _OPTIONAL if np.isfinite(np.array(rows[key], dtype=np.float64)).any()}
    if any(rows[_FIX]):
        used.add(_FIX)
    return used


def _column_map(used: set[str]) -> ColumnMap:
    return ColumnMap(
        time="time",
        lat="lat",
        lon="lon",
        track="track",
        alt="alt",
        speed="speed" if "speed" in used else "",
        heading="course" if "course" in used else "",
        hdop="hdop" if "hdop" in used else "",
        fix_quality=_FIX if _FIX in used else "",
        satellites="satellites" if "satellites" in used else "",
    )


def _column_names(used: set[str]) -> tuple[str, ...]:
    return ("track", "time", "lat", "lon", "alt", *(k for k in (*_OPTIONAL, _FIX) if k in used))


def _table(
    rows: dict[str, list[object]],
    times: pd.Series,
    used: set[str],
    source: str,
    row_offset: int = 0,
) -> Table:
    """The Table of these points with the optional columns in ``used``."""
    seconds = datetime_seconds(times)
    frame: dict[str, object] = {
        "track": np.array(rows["track"], dtype=object),
        "time": iso_utc(seconds),
        "lat": np.array(rows["lat"], dtype=np.float64),
        "lon": np.array(rows["lon"], dtype=np.float64),
        "alt": np.array(rows["alt"], dtype=np.float64),
    }
    for key in _OPTIONAL:
        if key in used:
            frame[key] = np.array(rows[key], dtype=np.float64)
    if _FIX in used:
        frame[_FIX] = np.array(rows[_FIX], dtype=object)
    return Table(
        frame=pd.DataFrame(frame),
        source=source,
        columns=_column_map(used),
        times=seconds,
        row_offset=row_offset,
    )


def read_gpx(path: str | Path) -> Table:
    """Read the track points of a GPX file (optionally ``.gz``); see the module docstring."""
    path = Path(path)
    source = str(path)
    ((rows, lines),) = _point_lists(path, None)
    return _table(rows, _times(rows["time"], lines, source), _used(rows), source)


def gpx_tables(path: str | Path, chunksize: int) -> StreamedChunks:
    """The track points of a GPX file as Tables of at most ``chunksize`` points, in two
    streaming passes, so memory is bounded by the chunk, not by the file.

    The first pass parses and checks every point (a bad value fails before any
    output) and learns what only the whole file tells: which optional columns
    any point fills, and whether any time needs nanoseconds (then pandas parses
    the whole file's times in nanoseconds, and a time out of their range is an
    error). The second pass yields the Tables: the rows, columns, values and
    times :func:`read_gpx` gives for the whole file, in chunks.
    """
    path = Path(path)
    source = str(path)
    used: set[str] = set()
    nanoseconds = False
    n_rows = 0
    for rows, lines in _point_lists(path, chunksize):
        nanoseconds = nanoseconds or _needs_nanoseconds(_times(rows["time"], lines, source))
        used |= _used(rows)
        n_rows += len(lines)

    def chunks() -> Iterator[Table]:
        offset = 0
        for rows, lines in _point_lists(path, chunksize):
            times = _times(rows["time"], lines, source, nanoseconds)
            yield _table(rows, times, used, source, offset)
            offset += len(lines)

    return StreamedChunks(n_rows, _column_names(used), _column_map(used), chunks())


def _times(
    texts: list[object], lines: list[int], source: str, nanoseconds: bool = False
) -> pd.Series:
    """ISO-8601 ``<time>`` texts -> UTC datetimes; a bad one is an error naming its line.

    ``nanoseconds``: the times of the whole file need nanoseconds (a chunk of it is
    being read): they are converted to that unit as pandas converts them when it parses
    the whole file, a time outside its range (year 1, 3000) becoming an error.
    """
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
    if nanoseconds and not _needs_nanoseconds(parsed):
        parsed = _in_nanoseconds(parsed)
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


def _in_nanoseconds(parsed: pd.Series) -> pd.Series:
    """UTC datetimes in nanoseconds; NaT where a time does not fit them."""
    unit = getattr(parsed.dtype, "unit", "ns")
    ticks = parsed.dt.tz_localize(None).to_numpy().astype(np.int64)
    per = {"s": 10**9, "ms": 10**6, "us": 10**3}[unit]
    missing = parsed.isna().to_numpy()
    limit = np.iinfo(np.int64).max // per
    fits = ~missing & (np.abs(ticks) <= limit)
    ns = np.where(fits, ticks * np.where(fits, per, 1), np.iinfo(np.int64).min)
    out = pd.Series(ns.view("datetime64[ns]"), index=parsed.index).dt.tz_localize("UTC")
    return out


def _timestamp(text: str) -> pd.Timestamp | None:
    try:
        stamp = pd.Timestamp(text)
    except (ValueError, OverflowError):
        return None
    return stamp if stamp.tzinfo is not None else stamp.tz_localize("UTC")
