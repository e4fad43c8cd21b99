"""Live follow mode: fixes arrive as text lines, a verdict goes out for each line at once.

``gradgps detect --follow -`` reads a receiver's output (``cat /dev/ttyACM0``,
``tail -f drive.csv``, ``gpspipe -r``) from standard input and writes one CSV
result line per input line, flushed immediately, so another program can act on
a fix while the car is still at it. The batch reader cannot do this: it reads
the whole file and only then detects.

Input, recognised from the first non-blank line (or named with ``--format``):

* **CSV**: a header line first (column roles auto-detected or named with the
  ``--*-col`` options, as in batch mode), then one fix per line. Output: the
  input fields (padded or cut to the header's width) plus the result columns.
  One :class:`~gradgps.Detector` per track id (the track column's value).
* **NMEA 0183**: GGA and RMC sentences (checksums checked, as in
  :mod:`gradgps._io.nmea`). Output: ``line``, ``sentence``, ``time``, ``lat``,
  ``lon``, ``speed``, ``heading``, ``epoch_line`` plus the result columns.
  A receiver sends GGA and RMC for the same instant: the first sentence of an
  instant is scored, the second gets the same verdict repeated, with
  ``epoch_line`` naming the line that was scored (a stream cannot wait for the
  second sentence without delaying every verdict). ``time`` is written as
  the batch reader writes NMEA times (:mod:`gradgps._io.times`): ISO-8601
  UTC once an RMC sentence has given the date, the time of day alone
  (``10:00:05Z``) before that (a stream cannot wait for a date). The
  detector counts seconds from the first sentence's midnight, continuing
  past 86400 at midnight, so a date (or a stale one, the day that just ended
  on the first RMC after midnight) never moves a fix in time.

Never a crash on bad input: a line that cannot be parsed (wrong field count,
a number that is not one, a damaged sentence) gets its output line with
``anomaly=1`` and ``invalid_reason`` saying what was wrong, exactly as the
Detector reports an unusable fix; NMEA sentences that are not fixes (GSV,
GSA, text) get a line with empty result columns and ``invalid_reason`` ``not a
fix sentence``. Blank lines are skipped (nothing to answer). A fix whose time
is not after the previous fix of its track is invalid, as in any stream; so
is one the receiver reports as no fix (GGA quality 0, RMC status ``V``, a
CSV fix-quality column saying 0/``V``/``none``, 0 satellites), with
``invalid_reason`` ``receiver reports no fix``, as in batch.

Banner lines: loggers often start a file with a line of their own (``#
GPSLogger 3.2 started 2026-11-23``, a count, a title). Until the first NMEA
sentence or CSV header, lines that are neither are skipped, and ``warn`` is
told once how many and why, so a banner does not turn an NMEA log into a
broken CSV. A CSV whose header is really unusable still fails with the
header's own error: as soon as a second line with as many fields follows it
(its data rows), at the end of the input, or after
:data:`MAX_BANNER_LINES` lines without a start.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from .._exceptions import ConfigError, InputError
from .._grad.detector import Detector, MultiTrackDetector, load_grad_model, refuse_settling
from .._io.nmea import STALE_DATE_S, Malformed, parse_gga, parse_rmc, split_sentence
from .._io.times import iso_utc_one, time_of_day_utc
from .._result import RESULT_COLUMNS, PointResult
from .._tracks.track import ColumnMap, resolve_columns, rolled_over

__all__ = [
    "MAX_BANNER_LINES",
    "NMEA_FIELDS",
    "RESULT_FIELDS",
    "FollowCounts",
    "follow_lines",
    "parse_time",
]

RESULT_FIELDS = RESULT_COLUMNS
NMEA_FIELDS = ("line", "sentence", "time", "lat", "lon", "speed", "heading", "epoch_line")
_DAY = 86400.0
#: Banner lines skipped before giving up on finding a start (a live stream must not be eaten silently).
MAX_BANNER_LINES = 100


@dataclass
class FollowCounts:
    """What a follow session saw: result lines written, fixes scored, anomalies, unusable lines.

    ``skipped``: banner lines before the first NMEA sentence or CSV header
    (no output line for them: they precede the output's header).
    """

    lines: int = 0
    fixes: int = 0
    anomalies: int = 0
    invalid: int = 0
    skipped: int = 0


def _text(value: float | int | str | None) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        # Shortest exact form, as the file outputs write floats: the same numbers in every mode.
        return "" if math.isnan(value) else repr(value)
    return str(value)


def _result_fields(result: PointResult | None, reason: str = "") -> list[str]:
    if result is None:  # not a fix at all: nothing to say but why
        return [""] * (len(RESULT_FIELDS) - 1) + [reason]
    return [
        _text(result.anomaly),
        _text(result.score),
        _text(result.bias_type),
        _text(result.time_type),
        _text(result.lat_clean),
        _text(result.lon_clean),
        _text(result.alert),
        result.invalid_reason,
    ]


def parse_time(text: str) -> float:
    """Seconds from a number (unix s, or ms/us epochs by magnitude) or an ISO-8601 time (UTC if naive).

    Per value, unlike the batch reader's per-column rule: a stream cannot look
    ahead. Raises ValueError when it is neither.
    """
    try:
        value = float(text)
    except ValueError:
        stamp = dt.datetime.fromisoformat(text.strip())
        if stamp.tzinfo is None:
            stamp = stamp.replace(tzinfo=dt.UTC)
        return stamp.timestamp()
    if abs(value) > 1e14:
        return value / 1e6
    if abs(value) > 1e11:
        return value / 1e3
    return value


def _satellites(text: str | None) -> float | None:
    """A satellite count as the batch reader reads it: a number, else not reported."""
    if not text:
        return None
    try:
        return float(text)
    except ValueError:
        return None


class _CsvFollower:
    """One CSV stream: the header fixes the columns, then one fix per line."""

    def __init__(self, header: list[str], roles: ColumnMap, streams: MultiTrackDetector) -> None:
        """``roles``: the header's columns as :meth:`_Start.header` resolved them."""
        self.header = header
        self.index = {
            role: (None if name is None else header.index(name))
            for role, name in roles.as_dict().items()
        }
        self.streams = streams

    def out_header(self) -> list[str]:
        return [*self.header, *RESULT_FIELDS]

    def _value(self, fields: list[str], role: str) -> str | None:
        k = self.index[role]
        return None if k is None else fields[k].strip()

    def _optional(self, fields: list[str], role: str) -> float | None:
        text = self._value(fields, role)
        if not text:
            return None
        return float(text)  # ValueError reported by the caller, naming the column

    def score(self, fields: list[str]) -> PointResult:
        width = len(self.header)
        if len(fields) != width:
            return PointResult.invalid(
                f"expected {width} fields as in the header, got {len(fields)}"
            )
        role = "time"
        try:
            t = parse_time(self._value(fields, "time") or "nan")
            role = "lat"
            lat = float(self._value(fields, "lat") or "nan")
            role = "lon"
            lon = float(self._value(fields, "lon") or "nan")
            role = "speed"
            speed = self._optional(fields, "speed")
            role = "heading"
            heading = self._optional(fields, "heading")
        except ValueError:
            k = self.index[role] or 0
            what = "a time (seconds or ISO-8601)" if role == "time" else "a number"
            return PointResult.invalid(
                f"column {self.header[k]!r} ({role}) is not {what}: {fields[k]!r}"
            )
        track = self._value(fields, "track") or ""
        # The receiver's own fields are hints: an unreadable one is not reported, as in batch.
        return self.streams.detector(track).update(
            t,
            lat,
            lon,
            speed,
            heading,
            fix_quality=self._value(fields, "fix_quality"),
            satellites=_satellites(self._value(fields, "satellites")),
        )

    def line(self, text: str) -> tuple[list[str], PointResult | None]:
        fields = next(csv.reader([text]))
        result = self.score(fields)
        shown = (fields + [""] * len(self.header))[: len(self.header)]
        return shown + _result_fields(result), result


@dataclass
class _NmeaFollower:
    """One NMEA stream: each GGA/RMC sentence scored as it arrives (see the module docstring)."""

    detector: Detector
    line_number: int = 0
    day_offset: float = 0.0
    last_tod: float = math.nan
    last_epoch: tuple[float, int, PointResult] | None = None  # (tod, line, verdict)
    #: Unix seconds of the midnight ``day_offset`` counts from, once an RMC gave a date.
    midnight: float = math.nan

    def _date(self, tod: float, midnight: float) -> None:
        """Take the date of an RMC (already counted past midnight by ``day_offset``).

        As the batch reader (:func:`gradgps._io.nmea.epoch_times`): a date one
        day behind the one known, in the first minutes of a day, is stale.
        """
        if math.isnan(midnight) or math.isnan(tod):
            return
        anchor = midnight - self.day_offset
        if anchor == self.midnight - _DAY and tod < STALE_DATE_S:
            return
        self.midnight = anchor

    def _time_text(self, seconds: float) -> str:
        if math.isnan(seconds):
            return ""
        if math.isnan(self.midnight):
            return str(time_of_day_utc([seconds])[0])
        return iso_utc_one(self.midnight + seconds)

    def out_header(self) -> list[str]:
        return [*NMEA_FIELDS, *RESULT_FIELDS]

    def line(self, text: str) -> tuple[list[str], PointResult | None]:
        self.line_number += 1
        n = self.line_number
        blank = ["", "", "", "", "", ""]  # time, lat, lon, speed, heading, epoch_line
        pieces = text.split("$")[1:]
        if not pieces:
            return [str(n), "", *blank, *_result_fields(None, "not a fix sentence")], None
        body = pieces[-1]  # a cut-off sentence followed by a whole one: the whole one counts
        try:
            parsed = split_sentence(body)
            if parsed is None:
                kind = body.split(",", 1)[0][2:5]
                return [str(n), kind, *blank, *_result_fields(None, "not a fix sentence")], None
            kind, values = parsed
            epoch = (parse_gga if kind == "GGA" else parse_rmc)(values, n)
        except Malformed as exc:
            result = PointResult.invalid(f"rejected sentence: {exc}")
            return [str(n), "", *blank, *_result_fields(result)], result
        tod = epoch.tod
        lat = math.nan if epoch.no_fix else epoch.lat
        lon = math.nan if epoch.no_fix else epoch.lon
        scored: PointResult | None
        if self.last_epoch is not None and tod == self.last_epoch[0]:
            _, epoch_line, verdict = self.last_epoch
            scored = None
        else:
            if rolled_over(self.last_tod, tod):
                self.day_offset += _DAY  # midnight
            if not math.isnan(tod):
                self.last_tod = tod
            epoch_line = n
            verdict = scored = self.detector.update(
                tod + self.day_offset,
                lat,
                lon,
                epoch.speed,
                epoch.course,
                fix_quality=0 if epoch.no_fix else epoch.quality,
                satellites=epoch.satellites,
            )
            self.last_epoch = (tod, n, verdict)
        self._date(tod, epoch.midnight)
        shown = [
            self._time_text(tod + self.day_offset),
            *(_text(v) for v in (lat, lon, epoch.speed, epoch.course)),
        ]
        return [str(n), kind, *shown, str(epoch_line), *_result_fields(verdict)], scored


def _csv_text(fields: list[str]) -> str:
    # csv.writer quotes only what needs it; one line, no trailing newline.
    from io import StringIO

    buffer = StringIO()
    csv.writer(buffer, lineterminator="").writerow(fields)
    return buffer.getvalue()


class _Start:
    """Finds where the stream starts: the first NMEA sentence or CSV header, past any banner.

    Lines before it that are neither are counted, not answered; the first
    such line with several fields keeps its header error, raised when the
    lines after it show it was a CSV header after all (see the module
    docstring).
    """

    def __init__(self, fmt: str | None, columns: ColumnMap | None) -> None:
        self.fmt = fmt
        self.columns = columns
        self.skipped: list[str] = []
        self.header_error: InputError | None = None
        self.header_width = 0

    def nmea(self, text: str) -> bool:
        return self.fmt == "nmea" or (self.fmt is None and text.lstrip().startswith(("$", "!")))

    def header(self, text: str) -> tuple[list[str], ColumnMap] | None:
        """The CSV header if ``text`` is one, with its columns' roles; None (and the line
        counted) for a banner line."""
        fields = next(csv.reader([text]))
        try:
            roles = resolve_columns(fields, self.columns, source="<stdin>")
        except InputError as exc:
            if self.header_error is not None and len(fields) == self.header_width:
                raise self.header_error from None  # its data rows follow: a bad header
            if self.header_error is None and len(fields) > 1:
                self.header_error, self.header_width = exc, len(fields)
            self.skipped.append(text)
            if len(self.skipped) > MAX_BANNER_LINES:
                self.give_up()
            return None
        return fields, roles

    def give_up(self) -> None:
        """No start found: the error a header-less input gets (as without banner skipping)."""
        if self.header_error is not None:
            raise self.header_error
        first = self.skipped[0] if self.skipped else ""
        resolve_columns(next(csv.reader([first])), self.columns, source="<stdin>")

    def warning(self, what: str) -> str:
        n = len(self.skipped)
        first = self.skipped[0]
        shown = first if len(first) <= 60 else first[:57] + "..."
        return (
            f"skipped {n} line{'s' if n != 1 else ''} before the first {what}: "
            f"neither NMEA nor a CSV header (first: {shown!r})"
        )


def follow_lines(
    lines: Iterable[str],
    write: Callable[[str], None],
    *,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    columns: ColumnMap | None = None,
    fmt: str | None = None,
    warn: Callable[[str], None] | None = None,
) -> FollowCounts:
    """Score every line of ``lines`` as it comes; ``write`` gets the header, then one line per input line.

    ``write`` is called with one CSV line (no newline) at a time and should
    flush; ``fmt`` is ``"csv"``, ``"nmea"`` or ``None`` (from the first line).
    ``warn`` gets one message (no ``warning:`` prefix) when banner lines were
    skipped before the first sentence or header; they are counted in
    ``FollowCounts.skipped`` either way. Raises only for a CSV header without
    time/latitude/longitude columns (or no header at all), or an unsupported
    ``fmt``.
    """
    if fmt is not None and fmt not in ("csv", "nmea"):
        raise ConfigError(f"follow mode reads CSV or NMEA lines, not {fmt!r}")
    counts = FollowCounts()
    follower: _CsvFollower | _NmeaFollower | None = None
    start = _Start(fmt, columns)
    for raw in lines:
        text = raw.rstrip("\r\n").lstrip("\ufeff")
        if not text.strip():
            continue
        if follower is None:
            is_nmea = start.nmea(text)
            header = None if is_nmea else start.header(text)
            if header is None and not is_nmea:
                continue  # a banner line
            counts.skipped = len(start.skipped)
            if start.skipped and warn is not None:
                warn(start.warning("NMEA sentence" if header is None else "CSV header"))
            if header is not None:
                streams = MultiTrackDetector(model, threshold=threshold)
                refuse_settling(load_grad_model(model), "--follow")
                follower = _CsvFollower(*header, streams)
                write(_csv_text(follower.out_header()))
                continue
            single = Detector(model, threshold=threshold)
            refuse_settling(single.model_, "--follow")
            follower = _NmeaFollower(single)
            write(_csv_text(follower.out_header()))
        fields, result = follower.line(text)
        write(_csv_text(fields))
        counts.lines += 1
        if result is not None:
            if result.invalid_reason:
                counts.invalid += 1
            else:
                counts.fixes += 1
                counts.anomalies += result.anomaly
        elif fields[-1]:
            counts.invalid += 1
    if follower is None and start.skipped:
        start.give_up()
    return counts
