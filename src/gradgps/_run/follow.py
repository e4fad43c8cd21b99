"""Live follow mode: fixes arrive as text lines, a verdict goes out for each line as soon as it is final.

``gradgps detect --follow -`` reads a receiver's output (``cat /dev/ttyACM0``,
``tail -f drive.csv``, ``gpspipe -r``) from standard input and writes one CSV
result line per input line, flushed immediately, so another program can act on
a fix while the car is still at it. The batch reader cannot do this: it reads
the whole file and only then detects.

Input, recognised from the first non-blank line (or named with ``--format``):

* **CSV**: a header line first (column roles auto-detected or named with the
  ``--*-col`` options, as in batch mode), then one fix per line. Output: the
  input fields (padded or cut to the header's width) plus the result columns.
  One :class:`~gradgps.Detector` per track id (the track column's value). A
  speed column whose name says its unit (``speed_kmh``) is read in that unit, as
  the batch reader reads it.
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

**A model whose verdicts settle one fix late** (a confirm head, see
:attr:`gradgps.Detector.settled`): a fix's line goes out when the next fix of
its track has settled its verdict (or at the end of the input, where the
verdict at once is final), so the lines are those of batch ``gradgps detect``
on the same fixes, one fix later. Lines stay in input order: a line waits
for every line before it. With several tracks in one stream a track that
stops sending holds the lines behind its last fix, up to
:data:`HOLD_LINES` lines; past that the oldest goes out with its verdict at
once (counted in ``FollowCounts.unsettled``). One stream per receiver keeps
the delay at one fix.

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

Honest inputs: the checks batch ``gradgps detect`` runs over a whole file
(:class:`gradgps._tracks.input_checks.InputChecks`: a slow rate, repeated
timestamps, a noisy receiver, a reported speed in another unit...) run over the
stream too, over every fix read (usable or not, as batch reads the whole file),
after :data:`CHECK_EVERY` of them, then after twice as many each time, and at
the end of the input;
``warn`` gets each kind of warning once, the first time its evidence is in (a
stream has no end to wait for).

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

import collections
import csv
import datetime as dt
import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import pandas as pd

from .._exceptions import ConfigError, InputError
from .._grad.detector import Detector, MultiTrackDetector, load_grad_model
from .._io.nmea import STALE_DATE_S, Malformed, parse_gga, parse_rmc, split_sentence
from .._io.times import iso_utc_one, time_of_day_utc
from .._result import RESULT_COLUMNS, PointResult
from .._tracks.input_checks import CHECK_EVERY, InputChecks, validated_rates
from .._tracks.track import (
    SPEED_UNITS,
    ColumnMap,
    canonical_heading,
    resolve_columns,
    rolled_over,
    speed_unit_named,
    units_per_degree,
)

__all__ = [
    "CHECK_EVERY",
    "HOLD_LINES",
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
#: Lines that may wait behind a line whose verdict has not settled (a model whose verdicts
#: settle one fix late) before it goes out with its verdict at once.
HOLD_LINES = 10_000


@dataclass
class FollowCounts:
    """What a follow session saw: result lines written, fixes scored, anomalies, unusable lines.

    ``skipped``: banner lines before the first NMEA sentence or CSV header
    (no output line for them: they precede the output's header). ``unsettled``:
    fixes written with their verdict at once although a later fix of their track
    might have settled it (more than :data:`HOLD_LINES` lines waited behind them).
    """

    lines: int = 0
    fixes: int = 0
    anomalies: int = 0
    invalid: int = 0
    skipped: int = 0
    unsettled: int = 0


def _text(value: float | int | str | None) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        # Shortest exact form, as the file outputs write floats: the same numbers in every mode.
        return "" if math.isnan(value) else repr(value)
    return str(value)


class _Verdict:
    """A fix's verdict as it stands; the lines that show it (an NMEA instant's GGA and
    RMC) share one, so settling it changes them all. ``waiting``: a later fix of
    ``track`` may still settle it."""

    __slots__ = ("result", "track", "waiting")

    def __init__(self, result: PointResult, track: str | None = None) -> None:
        self.result = result
        self.track = track
        self.waiting = False


@dataclass
class _Line:
    """An output line before its result columns: the input's fields as shown, the verdict
    they get (``None``: not a fix, ``reason`` says why) and whether the line is the
    one its fix was scored on (an NMEA instant's second sentence repeats the verdict)."""

    shown: list[str]
    verdict: _Verdict | None
    reason: str = ""
    scored: bool = False

    def fields(self) -> list[str]:
        if self.verdict is None:
            return [*self.shown, *_result_fields(None, self.reason)]
        return [*self.shown, *_result_fields(self.verdict.result)]


class _Output:
    """The result lines, written in input order, each once its verdict is final.

    Where the model decides at once every line goes out as it comes. Where its
    verdicts settle one fix late (:attr:`Detector.settled`), a usable fix's verdict
    waits for the next usable fix of its track: that fix's update settles it, or
    begins a new segment, which leaves it as it was (a segment's last fix keeps its
    verdict at once, as in batch). A line goes out when it and every line before it
    are final, or when more than :data:`HOLD_LINES` lines wait behind it.
    """

    def __init__(self, write: Callable[[str], None], counts: FollowCounts, settles: bool) -> None:
        self.write = write
        self.counts = counts
        self.settles = settles
        self.lines: collections.deque[_Line] = collections.deque()
        self.pending: dict[str | None, _Verdict] = {}  # per track, the verdict still waiting

    def verdict(self, track: str | None, det: Detector, result: PointResult) -> _Verdict:
        """The verdict of a fix ``det`` (its track's detector) has just scored; settles the
        track's waiting one."""
        verdict = _Verdict(result, track)
        if not self.settles:
            return verdict
        usable = result.invalid_reason == ""
        before = self.pending.get(track)
        settled = det.settled
        if before is not None and (settled is not None or usable):
            if settled is not None:
                before.result = settled
            before.waiting = False
            del self.pending[track]
        if usable:
            verdict.waiting = True
            self.pending[track] = verdict
        return verdict

    def add(self, line: _Line) -> None:
        self.lines.append(line)
        lines = self.lines
        while lines and (
            lines[0].verdict is None or not lines[0].verdict.waiting or len(lines) > HOLD_LINES
        ):
            self._emit(lines.popleft())

    def finish(self) -> None:
        """The end of the input: the verdicts still waiting are final as they are."""
        for verdict in self.pending.values():
            verdict.waiting = False
        self.pending.clear()
        while self.lines:
            self._emit(self.lines.popleft())

    def _emit(self, line: _Line) -> None:
        verdict, counts = line.verdict, self.counts
        if verdict is not None and verdict.waiting:  # held too long: final as it is
            verdict.waiting = False
            del self.pending[verdict.track]
            counts.unsettled += 1
        self.write(_csv_text(line.fields()))
        counts.lines += 1
        if verdict is None:
            counts.invalid += bool(line.reason)
        elif line.scored and not verdict.result.invalid_reason:
            counts.fixes += 1
            counts.anomalies += verdict.result.anomaly
        else:
            counts.invalid += bool(verdict.result.invalid_reason)


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


class _Watch:
    """The stream's fixes through the input checks, :data:`CHECK_EVERY` of them first and
    twice as many as the last time after that; each kind of warning goes to ``warn``
    once, when the checks first find it."""

    def __init__(
        self,
        warn: Callable[[str], None] | None,
        checks: InputChecks,
        columns: ColumnMap | None = None,
        speed_unit: str = "m/s",
    ) -> None:
        self.warn = warn
        self.checks = checks
        self.columns = columns
        self.speed_unit = speed_unit
        self.rows: list[tuple[str, float, float, float, float, float]] = []
        self.said: set[str] = set()
        self.next_look = CHECK_EVERY

    def fix(
        self,
        track: str,
        t: float,
        lat: float,
        lon: float,
        speed: float | None,
        heading: float | None,
    ) -> None:
        """One fix read, usable or not (speed in m/s, heading in degrees, as the Detector
        took them)."""
        if self.warn is None:
            return
        nan = math.nan
        self.rows.append(
            (
                track,
                t,
                lat,
                lon,
                nan if speed is None else speed,
                nan if heading is None else heading,
            )
        )
        if len(self.rows) >= self.next_look:
            self.next_look *= 2
            self.look()

    def look(self) -> None:
        """Feed the fixes gathered so far to the checks and say what is new."""
        if self.warn is None or not self.rows:
            return
        frame = pd.DataFrame(self.rows, columns=["track", "t", "lat", "lon", "speed", "heading"])
        self.rows = []
        for role in ("speed", "heading"):
            if frame[role].isna().all():
                frame = frame.drop(columns=role)
        if "heading" in frame:
            frame["heading"] = canonical_heading(frame["heading"].to_numpy())
        if self.columns is not None:
            frame.attrs["columns"] = self.columns
        frame.attrs["speed_unit"] = self.speed_unit
        for kind, text in self.checks.add(frame).findings():
            if kind not in self.said:
                self.said.add(kind)
                self.warn(text)


class _CsvFollower:
    """One CSV stream: the header fixes the columns, then one fix per line."""

    def __init__(
        self,
        header: list[str],
        roles: ColumnMap,
        streams: MultiTrackDetector,
        output: _Output,
        watch: _Watch,
        speed_unit: str,
    ) -> None:
        """``roles``: the header's columns as :meth:`_Start.header` resolved them;
        ``speed_unit``: the unit the speed column's name says (:func:`speed_unit_named`)."""
        self.header = header
        self.index = {
            role: (None if name is None else header.index(name))
            for role, name in roles.as_dict().items()
        }
        self.streams = streams
        self.output = output
        # A speed column's name may say its unit (speed_kmh), and a coordinate column's
        # (latitudeE7), as the batch reader reads them.
        self.speed_factor = SPEED_UNITS[speed_unit]
        self.lat_units = units_per_degree(roles.lat)
        self.lon_units = units_per_degree(roles.lon)
        self.watch = watch

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

    def score(self, fields: list[str]) -> _Verdict:
        width = len(self.header)
        if len(fields) != width:
            return _Verdict(
                PointResult.invalid(f"expected {width} fields as in the header, got {len(fields)}")
            )
        role = "time"
        try:
            t = parse_time(self._value(fields, "time") or "nan")
            role = "lat"
            lat = float(self._value(fields, "lat") or "nan") / self.lat_units
            role = "lon"
            lon = float(self._value(fields, "lon") or "nan") / self.lon_units
            role = "speed"
            speed = self._optional(fields, "speed")
            if speed is not None:
                speed *= self.speed_factor
            role = "heading"
            heading = self._optional(fields, "heading")
        except ValueError:
            k = self.index[role] or 0
            what = "a time (seconds or ISO-8601)" if role == "time" else "a number"
            return _Verdict(
                PointResult.invalid(
                    f"column {self.header[k]!r} ({role}) is not {what}: {fields[k]!r}"
                )
            )
        track = self._value(fields, "track") or ""
        det = self.streams.detector(track)
        # The receiver's own fields are hints: an unreadable one is not reported, as in batch.
        result = det.update(
            t,
            lat,
            lon,
            speed,
            heading,
            fix_quality=self._value(fields, "fix_quality"),
            satellites=_satellites(self._value(fields, "satellites")),
        )
        # Every fix read goes to the checks, usable or not, as batch gives them the whole
        # file: a repeated or backward time is what some of them are there to see.
        self.watch.fix(track, t, lat, lon, speed, heading)
        return self.output.verdict(track, det, result)

    def line(self, text: str) -> _Line:
        fields = next(csv.reader([text]))
        verdict = self.score(fields)
        shown = (fields + [""] * len(self.header))[: len(self.header)]
        return _Line(shown, verdict, scored=True)


@dataclass
class _NmeaFollower:
    """One NMEA stream: each GGA/RMC sentence scored as it arrives (see the module docstring)."""

    detector: Detector
    output: _Output
    watch: _Watch
    line_number: int = 0
    day_offset: float = 0.0
    last_tod: float = math.nan
    last_epoch: tuple[float, int, _Verdict] | None = None  # (tod, line, verdict)
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

    def line(self, text: str) -> _Line:
        self.line_number += 1
        n = self.line_number
        blank = ["", "", "", "", "", ""]  # time, lat, lon, speed, heading, epoch_line
        pieces = text.split("$")[1:]
        if not pieces:
            return _Line([str(n), "", *blank], None, "not a fix sentence")
        body = pieces[-1]  # a cut-off sentence followed by a whole one: the whole one counts
        try:
            parsed = split_sentence(body)
            if parsed is None:
                kind = body.split(",", 1)[0][2:5]
                return _Line([str(n), kind, *blank], None, "not a fix sentence")
            kind, values = parsed
            epoch = (parse_gga if kind == "GGA" else parse_rmc)(values, n)
        except Malformed as exc:
            rejected = _Verdict(PointResult.invalid(f"rejected sentence: {exc}"))
            return _Line([str(n), "", *blank], rejected, scored=True)
        tod = epoch.tod
        lat = math.nan if epoch.no_fix else epoch.lat
        lon = math.nan if epoch.no_fix else epoch.lon
        if self.last_epoch is not None and tod == self.last_epoch[0]:
            _, epoch_line, verdict = self.last_epoch
            scored = False
        else:
            if rolled_over(self.last_tod, tod):
                self.day_offset += _DAY  # midnight
            if not math.isnan(tod):
                self.last_tod = tod
            epoch_line = n
            result = self.detector.update(
                tod + self.day_offset,
                lat,
                lon,
                epoch.speed,
                epoch.course,
                fix_quality=0 if epoch.no_fix else epoch.quality,
                satellites=epoch.satellites,
            )
            self.watch.fix("", tod + self.day_offset, lat, lon, epoch.speed, epoch.course)
            verdict = self.output.verdict(None, self.detector, result)
            scored = True
            self.last_epoch = (tod, n, verdict)
        self._date(tod, epoch.midnight)
        shown = [
            self._time_text(tod + self.day_offset),
            *(_text(v) for v in (lat, lon, epoch.speed, epoch.course)),
        ]
        return _Line([str(n), kind, *shown, str(epoch_line)], verdict, scored=scored)


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
    skipped before the first sentence or header (they are counted in
    ``FollowCounts.skipped`` either way), and one per kind of input warning, when
    the checks first find it (see the module docstring). Raises only for a CSV header without
    time/latitude/longitude columns (or no header at all), or an unsupported
    ``fmt``. A model whose verdicts settle one fix late writes each fix's line once
    the next fix of its track has come (see the module docstring).
    """
    if fmt is not None and fmt not in ("csv", "nmea"):
        raise ConfigError(f"follow mode reads CSV or NMEA lines, not {fmt!r}")
    counts = FollowCounts()
    watch: _Watch | None = None
    follower: _CsvFollower | _NmeaFollower | None = None
    output: _Output | None = None
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
                output = _Output(write, counts, streams.settles)
                roles = header[1]
                unit = "m/s" if roles.speed is None else speed_unit_named(roles.speed)
                checks = InputChecks(*validated_rates(load_grad_model(model).config))
                watch = _Watch(warn, checks, roles, unit)
                follower = _CsvFollower(*header, streams, output, watch, unit)
                write(_csv_text(follower.out_header()))
                continue
            single = Detector(model, threshold=threshold)
            output = _Output(write, counts, single.model_.params.settles(single.model_.dims))
            watch = _Watch(warn, InputChecks(*validated_rates(single.model_.config)))
            follower = _NmeaFollower(single, output, watch)
            write(_csv_text(follower.out_header()))
        assert output is not None
        output.add(follower.line(text))
    if output is not None:
        output.finish()
    if watch is not None:
        watch.look()
    if follower is None and start.skipped:
        start.give_up()
    return counts
