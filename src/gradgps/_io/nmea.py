"""NMEA 0183 logs -> a Table of fixes, from GGA and RMC sentences.

Receivers report one *epoch* (one instant) in several sentences. Two of them
carry what detection needs: RMC (date, position, speed in knots, course,
valid/void status) and GGA (position, fix quality, satellites, HDOP,
altitude). Consecutive GGA and RMC sentences with the same time of day are
merged into one fix; any talker is accepted (``GP``, ``GN``, ``GL``,
``GA``, ``BD``...).

The reader is lenient because real logs are damaged (serial noise, cut-off
lines), but it never guesses:

* Every GGA/RMC sentence must end in ``*hh`` and its checksum (XOR of the
  characters between ``$`` and ``*``) must match; otherwise, or when a field is
  malformed (a minute value of 60 or more, a hemisphere that is not N/S/E/W,
  an impossible date), the sentence is *rejected*: counted in
  ``Table.rejected`` with its line in ``Table.notes`` (the first
  :data:`MAX_NOTES`), never fatal.
* Other sentence types (GSV, GSA, VTG, proprietary ``$P...``) and text that is
  not a sentence are skipped and *not* counted: they are not fixes, so their
  health says nothing about the fixes. Bytes that are not ASCII are replaced,
  so a noisy sentence fails its checksum instead of stopping the read.
* An epoch the receiver marks as having no fix (GGA quality 0, RMC status
  ``V`` or mode ``N``) is kept as a row with NaN latitude/longitude and
  ``fix_quality`` 0, so the row count matches the epochs in the log and
  downstream code reports those rows as invalid fixes (``receiver reports
  no fix``) rather than silently losing them.

Times: when an RMC sentence gives the date, the seconds are unix seconds
(UTC); epochs without a date of their own take it from the nearest dated
epoch, and a stale date (the day that just ended, on the first fixes after
midnight) is advanced by a day, so times never jump back 24 h at midnight.
Without any date, they are seconds since midnight UTC of the first day,
growing past 86400 at a midnight rollover (time of day falling by more than
12 hours), so a drive across midnight stays ordered. Those seconds are what
the detector uses (``Table.times``); the ``time`` column holds them as text
in the form every mode writes NMEA times (:mod:`gradgps._io.times`):
ISO-8601 UTC (``2026-11-23T10:00:05.200Z``) when dated, the
time of day alone (``10:00:05Z``) when the log has no date.
"""

from __future__ import annotations

import datetime as dt
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import numpy as np
import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table, day_rollovers, rolled_over
from .files import READ_ERRORS, damaged, open_bytes
from .streamed import StreamedChunks
from .times import iso_utc, time_of_day_utc

__all__ = [
    "KNOT_MS",
    "MAX_NOTES",
    "STALE_DATE_S",
    "Epoch",
    "Malformed",
    "epoch_times",
    "nmea_checksum",
    "nmea_tables",
    "parse_gga",
    "parse_rmc",
    "read_nmea",
    "split_sentence",
]

MAX_NOTES: Final = 20
KNOT_MS: Final = 1852.0 / 3600.0
_DAY: Final = 86400.0
#: An RMC date one day behind, this many seconds or less into the new day, is
#: taken as stale (see :func:`epoch_times`); later in the day it is believed.
#: Receivers update the date within an epoch or two; ten minutes covers any
#: logging rate while a log that really jumps back a day keeps its dates.
STALE_DATE_S: Final = 600.0

_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)")
_TIME = re.compile(r"(\d\d)(\d\d)(\d\d(\.\d+)?)")


class Malformed(Exception):
    """A field that cannot be what the sentence type says it is (internal)."""


#: Bytes of a line read at a time (a longer line is read in pieces, its sentences kept whole).
_PIECE_BYTES = 1 << 20
#: Most characters kept of a sentence spread over pieces (any longer one is rejected as too long).
_OPEN_CHARS = 1 << 20

#: Longest sentence accepted (the standard's limit is 82; some receivers exceed it a little).
MAX_SENTENCE_CHARS = 200


def nmea_checksum(body: str) -> int:
    """XOR of the characters of ``body`` (the text between ``$`` and ``*``)."""
    value = 0
    for char in body:
        value ^= ord(char)
    return value


@dataclass(slots=True)
class Epoch:
    """One instant, merged from its GGA and/or RMC sentence."""

    line: int
    tod: float  # seconds of day, NaN when the sentence had no time
    midnight: float = math.nan  # unix seconds of the RMC date's midnight
    lat: float = math.nan
    lon: float = math.nan
    alt: float = math.nan
    hdop: float = math.nan
    speed: float = math.nan
    course: float = math.nan
    quality: int | None = None
    satellites: int | None = None
    no_fix: bool = False
    has_gga: bool = False
    has_rmc: bool = False


def _number(text: str, what: str) -> float:
    if text == "":
        return math.nan
    if not _NUMBER.fullmatch(text):
        raise Malformed(f"{what} is not a number: {text!r}")
    return float(text)


def _time_of_day(text: str) -> float:
    if text == "":
        return math.nan
    match = _TIME.fullmatch(text)
    if match is None:
        raise Malformed(f"time is not hhmmss.ss: {text!r}")
    hours, minutes, seconds = int(match[1]), int(match[2]), float(match[3])
    if hours > 23 or minutes > 59 or seconds >= 61.0:
        raise Malformed(f"impossible time of day: {text!r}")
    return round(hours * 3600.0 + minutes * 60.0 + seconds, 6)


def _coordinate(value: str, hemisphere: str, positive: str, negative: str, limit: float) -> float:
    """``dddmm.mmmm`` plus hemisphere -> signed degrees; both empty -> NaN."""
    if value == "" and hemisphere == "":
        return math.nan
    if hemisphere not in (positive, negative):
        raise Malformed(f"hemisphere must be {positive} or {negative}, got {hemisphere!r}")
    if not re.fullmatch(r"\d+(\.\d+)?", value):
        raise Malformed(f"coordinate is not dddmm.mmmm: {value!r}")
    raw = float(value)
    degrees = math.floor(raw / 100.0)
    minutes = raw - 100.0 * degrees
    if minutes >= 60.0:
        raise Malformed(f"coordinate minutes of 60 or more: {value!r}")
    result = degrees + minutes / 60.0
    if result > limit:
        raise Malformed(f"coordinate beyond {limit:g} degrees: {value!r}")
    return -result if hemisphere == negative else result


def _midnight(text: str) -> float:
    """RMC ``ddmmyy`` -> unix seconds of that day's midnight UTC (NaN when empty)."""
    if text == "":
        return math.nan
    if not re.fullmatch(r"\d{6}", text):
        raise Malformed(f"date is not ddmmyy: {text!r}")
    day, month, year = int(text[0:2]), int(text[2:4]), int(text[4:6])
    # NMEA has two-digit years; GPS receivers date from 1980.
    year += 1900 if year >= 80 else 2000
    try:
        date = dt.date(year, month, day)
    except ValueError:
        raise Malformed(f"impossible date: {text!r}") from None
    return float((date - dt.date(1970, 1, 1)).days) * _DAY


def _small_count(text: str, digits: int) -> bool:
    """Whether ``text`` is 1 to ``digits`` ASCII digits (``str.isdigit`` alone takes
    ``'²'``, which ``int`` refuses)."""
    return 0 < len(text) <= digits and text.isascii() and text.isdigit()


def parse_gga(fields: list[str], line: int) -> Epoch:
    if len(fields) < 9:
        raise Malformed(f"GGA has {len(fields)} fields, needs at least 9")
    # Both are small counts (quality one digit 0-8, satellites two digits in NMEA 0183):
    # anything longer than a few ASCII digits is damage, and read as such, since a
    # 20-digit "count" would not even fit the int64 column it is stored in.
    quality_text = fields[5]
    if not _small_count(quality_text, digits=2):
        raise Malformed(f"fix quality is not a one- or two-digit number: {quality_text[:20]!r}")
    quality = int(quality_text)
    satellites = int(fields[6]) if _small_count(fields[6], digits=3) else None
    if fields[6] and satellites is None:
        raise Malformed(f"satellite count is not a number up to 999: {fields[6][:20]!r}")
    epoch = Epoch(
        line=line,
        tod=_time_of_day(fields[0]),
        lat=_coordinate(fields[1], fields[2], "N", "S", 90.0),
        lon=_coordinate(fields[3], fields[4], "E", "W", 180.0),
        hdop=_number(fields[7], "HDOP"),
        alt=_number(fields[8], "altitude"),
        quality=quality,
        satellites=satellites,
        no_fix=quality == 0,
        has_gga=True,
    )
    return epoch


def parse_rmc(fields: list[str], line: int) -> Epoch:
    if len(fields) < 9:
        raise Malformed(f"RMC has {len(fields)} fields, needs at least 9")
    status = fields[1]
    if status not in ("A", "V"):
        raise Malformed(f"status must be A or V, got {status!r}")
    # NMEA 2.3 adds a mode indicator (field 12); N means "data not valid".
    mode_invalid = len(fields) > 11 and fields[11][:1] == "N"
    return Epoch(
        line=line,
        tod=_time_of_day(fields[0]),
        lat=_coordinate(fields[2], fields[3], "N", "S", 90.0),
        lon=_coordinate(fields[4], fields[5], "E", "W", 180.0),
        speed=_number(fields[6], "speed") * KNOT_MS,
        course=_number(fields[7], "course"),
        midnight=_midnight(fields[8]),
        no_fix=status == "V" or mode_invalid,
        has_rmc=True,
    )


def _merge(into: Epoch, other: Epoch) -> None:
    """Fold ``other`` (same instant, the other sentence type) into ``into``."""
    if math.isnan(into.lat):
        into.lat, into.lon = other.lat, other.lon
    for name in ("alt", "hdop", "speed", "course", "midnight"):
        if math.isnan(getattr(into, name)):
            setattr(into, name, getattr(other, name))
    into.quality = into.quality if into.quality is not None else other.quality
    into.satellites = into.satellites if into.satellites is not None else other.satellites
    into.no_fix = into.no_fix or other.no_fix
    into.has_gga = into.has_gga or other.has_gga
    into.has_rmc = into.has_rmc or other.has_rmc


def split_sentence(text: str) -> tuple[str, list[str]] | None:
    """``(type, fields)`` of a GGA/RMC sentence; None for anything else; raises Malformed when damaged.

    ``text`` is what follows a ``$``.
    """
    address = text.split(",", 1)[0].split("*", 1)[0]
    kind = address[2:]
    if len(address) != 5 or address.startswith("P") or kind not in ("GGA", "RMC"):
        return None
    if len(text) > MAX_SENTENCE_CHARS:
        # NMEA 0183 sentences are at most 82 characters; a 400-digit field is damage.
        raise Malformed(f"{kind} sentence of {len(text):,} characters (NMEA allows 82)")
    star = text.rfind("*")
    if star < 0:
        raise Malformed(f"{kind} sentence has no checksum (cut off?)")
    given = text[star + 1 :].strip()
    if not re.fullmatch(r"[0-9A-Fa-f]{2}", given):
        raise Malformed(f"{kind} checksum is not two hex digits: {given!r}")
    body = text[:star]
    computed = nmea_checksum(body)
    if computed != int(given, 16):
        raise Malformed(
            f"{kind} checksum mismatch: sentence says {given.upper()}, content gives {computed:02X}"
        )
    return kind, body.split(",")[1:]


@dataclass
class _LogReader:
    """Turns sentences, in file order, into epochs; counts and notes the rejected ones."""

    epochs: list[Epoch] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    rejected: int = 0

    def add(self, text: str, line: int) -> None:
        """Take one sentence (``text`` follows its ``$``) found on file line ``line``."""
        try:
            parsed = split_sentence(text)
            if parsed is None:
                return
            kind, fields = parsed
            epoch = (parse_gga if kind == "GGA" else parse_rmc)(fields, line)
        except Malformed as exc:
            self.rejected += 1
            if len(self.notes) < MAX_NOTES:
                self.notes.append(f"line {line}: {exc}")
            return
        # Same time of day as the previous epoch and the other sentence type:
        # the same instant. NaN times never match, so they stay rows of their own.
        current = self.epochs[-1] if self.epochs else None
        if (
            current is not None
            and current.tod == epoch.tod
            and not (current.has_gga and epoch.has_gga)
            and not (current.has_rmc and epoch.has_rmc)
        ):
            _merge(current, epoch)
        else:
            self.epochs.append(epoch)


def _epoch_lists(path: Path, chunk_epochs: int | None) -> Iterator[tuple[list[Epoch], _LogReader]]:
    """The epochs of a log, in file order, ``chunk_epochs`` at a time (``None``: all at
    once), each with the reader (its rejected count and notes so far). An epoch is
    handed out only once the next one has begun, as a later sentence may still merge
    into it. Raises for a log without epochs."""
    source = str(path)
    log = _LogReader()
    n_lines = 0
    handed = 0
    in_line = False  # the last block read ended inside a line
    open_text: str | None = None  # the line's text after its last "$" so far
    with open_bytes(path) as raw:
        try:
            # A line is read at most _PIECE_BYTES at a time, so a log without line
            # breaks (or a hostile 1 GB line) never sits in memory whole.
            for block in iter(lambda: raw.readline(_PIECE_BYTES), b""):
                if not in_line:
                    n_lines += 1
                    open_text = None
                # Several sentences may share a line (a cut-off one followed
                # by the next); text before the first "$" is a logger's prefix.
                head, *rest = block.decode("ascii", errors="replace").split("$")
                complete: list[str] = []
                if open_text is not None:
                    # Bounded: a "$" and then a gigabyte without one is no sentence.
                    open_text = (open_text + head)[:_OPEN_CHARS]
                if rest:
                    if open_text is not None:
                        complete.append(open_text)
                    complete.extend(rest[:-1])
                    open_text = rest[-1]
                in_line = not block.endswith(b"\n")
                if not in_line and open_text is not None:
                    complete.append(open_text)
                    open_text = None
                for sentence in complete:
                    log.add(sentence, n_lines)
                if chunk_epochs is not None and len(log.epochs) > chunk_epochs:
                    done = log.epochs[:-1]
                    log.epochs = log.epochs[-1:]
                    handed += len(done)
                    yield done, log
        except READ_ERRORS as exc:
            raise damaged(exc, source) from None
    if open_text is not None:  # the last line, without a line break
        log.add(open_text, n_lines)
    if log.rejected > MAX_NOTES:
        log.notes.append(f"... and {log.rejected - MAX_NOTES} more rejected sentences")
    if not handed and not log.epochs:
        if n_lines == 0:
            raise InputError(
                "empty file", source=source, hint="an NMEA log has one $..*hh sentence per line"
            )
        detail = f"; {log.rejected} rejected, first: {log.notes[0]}" if log.rejected else ""
        raise InputError(
            f"no usable GGA or RMC sentences in {n_lines} lines{detail}",
            source=source,
            hint="is this an NMEA 0183 log? otherwise pass the right format",
        )
    if log.epochs:
        yield log.epochs, log


@dataclass(frozen=True)
class _Kinds:
    """Which sentence types and verdicts a log holds: the optional columns it gets."""

    rmc: bool = False
    gga: bool = False
    no_fix: bool = False
    dated: bool = False

    @classmethod
    def of(cls, epochs: list[Epoch]) -> _Kinds:
        return cls(
            rmc=any(e.has_rmc for e in epochs),
            gga=any(e.has_gga for e in epochs),
            no_fix=any(e.no_fix for e in epochs),
            dated=any(not math.isnan(e.midnight) for e in epochs),
        )

    def __or__(self, other: _Kinds) -> _Kinds:
        return _Kinds(
            self.rmc or other.rmc,
            self.gga or other.gga,
            self.no_fix or other.no_fix,
            self.dated or other.dated,
        )

    def columns(self) -> ColumnMap:
        return ColumnMap(
            time="time",
            lat="lat",
            lon="lon",
            track="",
            speed="speed" if self.rmc else "",
            heading="course" if self.rmc else "",
            alt="alt" if self.gga else "",
            hdop="hdop" if self.gga else "",
            fix_quality="fix_quality" if self.gga or self.no_fix else "",
            satellites="satellites" if self.gga else "",
        )

    def names(self) -> tuple[str, ...]:
        """The columns of a table of such a log, in order."""
        return tuple(str(c) for c in _frame([], np.zeros(0), self).columns)


def _notes(log: _LogReader, kinds: _Kinds) -> list[str]:
    notes = list(log.notes)
    if not kinds.dated:
        notes.append("no RMC date in the log: times are times of day (UTC), without a date")
    return notes


def read_nmea(path: str | Path) -> Table:
    """Read an NMEA 0183 log (optionally ``.gz``) into a Table; see the module docstring.

    Columns: ``time``, ``lat``, ``lon`` and, when the log has them, ``speed``
    (m/s), ``course`` (degrees), ``alt`` (m), ``hdop``, ``fix_quality`` (GGA's
    fix quality; 0 for every no-fix epoch, RMC status ``V`` or mode ``N``
    included; empty for an RMC-only epoch with a fix), ``satellites``; plus
    ``line``, the file line of the epoch's first sentence.
    """
    path = Path(path)
    ((epochs, log),) = _epoch_lists(path, None)
    kinds = _Kinds.of(epochs)
    tod = np.array([e.tod for e in epochs])
    midnight = np.array([e.midnight for e in epochs])
    seconds = epoch_times(tod, midnight)
    return Table(
        frame=_frame(epochs, seconds, kinds),
        source=str(path),
        columns=kinds.columns(),
        rejected=log.rejected,
        notes=_notes(log, kinds),
        times=seconds,
    )


def nmea_tables(path: str | Path, chunksize: int) -> StreamedChunks:
    """An NMEA log as Tables of at most ``chunksize`` epochs, in two streaming passes, so
    memory is bounded by the chunk, not by the log.

    The first pass parses every sentence and learns what only the whole log
    tells: the sentence types (the optional columns), whether any RMC gives a
    date (the form of the time column), the rejected sentences, and each dated
    epoch's offset from time of day to unix time (:class:`_Offsets`: the stale
    date rule looks one dated epoch ahead, and epochs before the first dated one
    take its date). The second pass yields the Tables: the rows, columns, values
    and times :func:`read_nmea` gives for the whole log, in chunks.
    """
    path = Path(path)
    source = str(path)
    kinds = _Kinds()
    offsets = _Offsets()
    n_rows = 0
    log = _LogReader()
    for epochs, reader in _epoch_lists(path, chunksize):
        log = reader
        kinds = kinds | _Kinds.of(epochs)
        offsets.add(epochs)
        n_rows += len(epochs)
    offsets.finish()
    rejected, notes = log.rejected, _notes(log, kinds)

    def chunks() -> Iterator[Table]:
        clock = _Clock(offsets)
        offset = 0
        for epochs, _ in _epoch_lists(path, chunksize):
            seconds = clock.times(epochs)
            yield Table(
                frame=_frame(epochs, seconds, kinds),
                source=source,
                columns=kinds.columns(),
                rejected=rejected,
                notes=notes,
                times=seconds,
                row_offset=offset,
            )
            offset += len(epochs)

    return StreamedChunks(n_rows, kinds.names(), kinds.columns(), chunks())


class _Days:
    """The running day count of :func:`epoch_times` (:func:`day_rollovers`, one epoch at a
    time): a time of day falling by more than half a day is a midnight rollover
    (:func:`rolled_over`)."""

    def __init__(self) -> None:
        self.days = 0
        self.previous = math.nan

    def step(self, value: float) -> tuple[float, int]:
        """``(continuous seconds, rollovers)`` of one epoch's time of day (NaN: NaN, 0)."""
        if math.isnan(value):
            return math.nan, 0
        if rolled_over(self.previous, value):
            self.days += 1
        self.previous = value
        return value + self.days * _DAY, self.days


class _Offsets:
    """Pass one of :func:`nmea_tables`: the final offset of every dated epoch, as runs.

    The offsets are those of :func:`epoch_times` (the same comparisons, one dated epoch
    of look-ahead), kept as ``(first dated epoch, offset)`` runs: a log's offset changes
    only when its dates disagree with its times of day, so a log holds a handful.
    """

    def __init__(self) -> None:
        self.days = _Days()
        # The dated epoch waiting for the next one: (tod, rollovers, raw offset).
        self.pending: tuple[float, int, float] | None = None
        self.before: tuple[int, float, bool] | None = None  # last final: rollovers, offset, stale
        self.count = 0
        self.starts: list[int] = []
        self.values: list[float] = []

    def add(self, epochs: list[Epoch]) -> None:
        for e in epochs:
            continuous, rollovers = self.days.step(e.tod)
            if math.isnan(e.midnight) or math.isnan(continuous):
                continue
            current = (e.tod, rollovers, e.midnight - rollovers * _DAY)
            if self.pending is not None:
                self._settle(current)
            self.pending = current

    def finish(self) -> None:
        if self.pending is not None:
            self._settle(None)

    def _settle(self, following: tuple[float, int, float] | None) -> None:
        assert self.pending is not None
        tod, rollovers, offset = self.pending
        stale = False
        if tod < STALE_DATE_S:
            before = self.before
            rolled = before is not None and (before[0] < rollovers or before[2])
            if (rolled and before is not None and offset == before[1] - _DAY) or (
                following is not None
                and following[0] < STALE_DATE_S
                and following[1] == rollovers
                and offset == following[2] - _DAY
            ):
                offset += _DAY
                stale = True
        self.before = (rollovers, offset, stale)
        if not self.values or self.values[-1] != offset:
            self.starts.append(self.count)
            self.values.append(offset)
        self.count += 1
        self.pending = None


class _Clock:
    """Pass two of :func:`nmea_tables`: each epoch's seconds, as :func:`epoch_times`."""

    def __init__(self, offsets: _Offsets) -> None:
        self.days = _Days()
        self.starts, self.values = offsets.starts, offsets.values
        self.dated = -1  # dated epochs seen, minus one
        self.run = 0

    def times(self, epochs: list[Epoch]) -> np.ndarray:
        out = np.full(len(epochs), np.nan)
        if not self.values:  # no date anywhere: seconds of day, rollovers added
            for i, e in enumerate(epochs):
                out[i] = self.days.step(e.tod)[0]
            return out
        for i, e in enumerate(epochs):
            continuous, _ = self.days.step(e.tod)
            if not math.isnan(e.midnight) and not math.isnan(continuous):
                self.dated += 1
                while self.run + 1 < len(self.starts) and self.starts[self.run + 1] <= self.dated:
                    self.run += 1
            out[i] = continuous + self.values[self.run]
        return out


def epoch_times(tod: np.ndarray, midnight: np.ndarray) -> np.ndarray:
    """Seconds for each epoch from its time of day and (maybe missing) date; see the module docstring.

    A date one day behind its neighbours on an epoch in the first
    :data:`STALE_DATE_S` seconds of a day is *stale*: receivers stamp the
    first RMC after midnight with the day that just ended, and taken at its
    word that fix (and the undated ones carried from it) would land 24 h
    early, so time would run backwards by a day. Such a date is advanced by
    one day when the time of day has wrapped since the previous dated epoch
    (the day rolled over and the date did not follow), or when the next
    dated epoch, also just after midnight, names the following day.
    """
    rollovers = day_rollovers(tod)
    continuous = tod + rollovers * _DAY
    dated = np.flatnonzero(np.isfinite(midnight) & np.isfinite(continuous))
    if not dated.size:
        return continuous
    # Offset from "continuous seconds of day" to unix time at each dated
    # epoch: a whole number of days, so exact comparisons are safe.
    offsets = midnight[dated] - rollovers[dated] * _DAY
    stale = np.zeros(dated.size, dtype=bool)
    for k, at in enumerate(dated):
        if tod[at] >= STALE_DATE_S:
            continue
        # A wrap since the previous dated epoch, or that epoch's date was stale too.
        rolled = k > 0 and (rollovers[dated[k - 1]] < rollovers[at] or stale[k - 1])
        if rolled and offsets[k] == offsets[k - 1] - _DAY:
            offsets[k] += _DAY
            stale[k] = True
            continue
        following = dated[k + 1] if k + 1 < dated.size else -1
        if (
            following >= 0
            and tod[following] < STALE_DATE_S
            and rollovers[following] == rollovers[at]
            and offsets[k] == offsets[k + 1] - _DAY
        ):
            offsets[k] += _DAY
            stale[k] = True
    # Carried from the dated epochs to their undated neighbours.
    spread = np.full(tod.size, np.nan)
    spread[dated] = offsets
    offset = pd.Series(spread).ffill().bfill()
    return np.asarray(continuous + offset.to_numpy(), dtype=np.float64)


def _frame(epochs: list[Epoch], time: np.ndarray, kinds: _Kinds) -> pd.DataFrame:
    """The rows of ``epochs`` (times ``time``) with the columns a log of ``kinds`` has."""
    no_fix = np.array([e.no_fix for e in epochs], dtype=bool)
    columns: dict[str, object] = {
        "time": iso_utc(time) if kinds.dated else time_of_day_utc(time),
        "lat": np.where(no_fix, np.nan, np.array([e.lat for e in epochs], dtype=np.float64)),
        "lon": np.where(no_fix, np.nan, np.array([e.lon for e in epochs], dtype=np.float64)),
    }
    if kinds.rmc:
        columns["speed"] = np.array([e.speed for e in epochs], dtype=np.float64)
        columns["course"] = np.array([e.course for e in epochs], dtype=np.float64)
    if kinds.gga:
        columns["alt"] = np.array([e.alt for e in epochs], dtype=np.float64)
        columns["hdop"] = np.array([e.hdop for e in epochs], dtype=np.float64)
    if kinds.gga or kinds.no_fix:
        # The receiver's own verdict: GGA's quality, 0 for any epoch it calls no fix
        # (RMC status V or mode N too), so every mode reads one column for it.
        columns["fix_quality"] = pd.array(
            [0 if e.no_fix else e.quality for e in epochs], dtype="Int64"
        )
    if kinds.gga:
        columns["satellites"] = pd.array([e.satellites for e in epochs], dtype="Int64")
    columns["line"] = np.array([e.line for e in epochs], dtype=np.int64)
    return pd.DataFrame(columns)
