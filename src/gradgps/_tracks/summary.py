"""What is in a track file, in numbers: the facts behind ``gradgps info``.

Before detecting anything a user wants to know what they hold: how many
tracks and fixes, at what rate, with which dropouts, where, how fast, and how
much of it is unusable. :func:`summarize` computes that from canonical fixes.

It works on :func:`gradgps.preprocess` points (one segment per track, no
interpolation) of the usable fixes, exactly what the detector uses: invalid
rows are counted with the same reasons the detector gives them, a repeated or
backward timestamp included (each track is read in row order).

Definitions (per track; *steps* are the time differences between
consecutive distinct timestamps of valid fixes):

* rate: 1 / median step, in Hz;
* gap: a step longer than 1.5 x the median step (the threshold above which
  :func:`gradgps.preprocess` fills or splits), by more than a microsecond so
  that float noise in timestamps does not turn an exact 1.5 x step into a gap;
* duration: last minus first valid time;
* speed: the reported ``speed`` column where the track has one, else the
  speed implied by consecutive positions (great-circle distance / step).

The ``total`` pools all tracks: points, invalid rows, gaps and durations are
summed (so overlapping tracks count twice), the median step is taken over all
tracks' steps, the longest gap and the bounding box over all tracks.
"""

from __future__ import annotations

import math
import sys
from collections import Counter
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from .geo import haversine_m
from .input_checks import VALIDATED_DEFAULT, input_warnings
from .preprocess import MIN_STEP_S, preprocess, stream_reasons

__all__ = ["GAP_FACTOR", "SpeedStats", "Summary", "TrackSummary", "summarize"]

GAP_FACTOR = 1.5
_TIME_TOLERANCE_S = 1e-6


@dataclass(frozen=True)
class SpeedStats:
    """Speed distribution in m/s; ``source`` is ``reported``, ``implied`` or ``mixed``."""

    source: str
    mean: float
    median: float
    p95: float
    max: float

    @classmethod
    def of(cls, values: np.ndarray, source: str) -> SpeedStats | None:
        finite = values[np.isfinite(values)]
        if finite.size == 0:
            return None
        return cls(
            source=source,
            mean=float(finite.mean()),
            median=float(np.median(finite)),
            p95=float(np.percentile(finite, 95)),
            max=float(finite.max()),
        )


@dataclass(frozen=True)
class TrackSummary:
    """The numbers for one track (or, with ``track="total"``, for all of them).

    Time-derived fields are ``None`` when fewer than two distinct valid
    timestamps exist; the bounding box is ``None`` without a valid fix.
    """

    track: str
    points: int
    invalid: int
    median_step_s: float | None
    rate_hz: float | None
    duration_s: float | None
    gaps: int
    longest_gap_s: float | None
    lat_min: float | None
    lat_max: float | None
    lon_min: float | None
    lon_max: float | None
    speed: SpeedStats | None
    start_s: float | None = None
    end_s: float | None = None


#: Faster than this (m/s; 324 km/h) is no road vehicle: positions jump or the unit is wrong.
IMPOSSIBLE_SPEED = 90.0
#: Rates outside this band (Hz) are worth a second look.
RATE_BAND = (0.01, 50.0)


def warnings_of(tracks: list[TrackSummary], rows: int) -> list[str]:
    """Plain-language warnings: impossible speeds, odd rates, many unusable rows."""
    out = []
    for s in tracks:
        if s.speed is not None and s.speed.max > IMPOSSIBLE_SPEED:
            what = "reported speed" if s.speed.source == "reported" else "speed between fixes"
            out.append(
                f"track {s.track}: {what} up to {s.speed.max:,.0f} m/s "
                f"(over {IMPOSSIBLE_SPEED:.0f} m/s: position jumps"
                + (", or speed not in m/s" if s.speed.source == "reported" else "")
                + ")"
            )
        if s.rate_hz is not None and not (RATE_BAND[0] <= s.rate_hz <= RATE_BAND[1]):
            out.append(f"track {s.track}: {s.rate_hz:g} Hz is an unusual rate (time unit right?)")
    invalid = sum(s.invalid for s in tracks)
    if rows and invalid > 0.1 * rows:
        out.append(
            f"{invalid:,} of {rows:,} rows ({100 * invalid / rows:.0f} %) are unusable "
            "(see the reasons above)"
        )
    return out


@dataclass(frozen=True)
class Summary:
    """Per-track summaries, their total, and what the reader had to reject."""

    source: str
    tracks: list[TrackSummary]
    total: TrackSummary
    invalid_reasons: dict[str, int]
    rejected: int = 0
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able data (NaN never appears: missing values are ``None``)."""
        return {
            "source": self.source,
            "n_tracks": len(self.tracks),
            "n_points": self.total.points,
            "total": asdict(self.total),
            "tracks": [asdict(t) for t in self.tracks],
            "invalid_reasons": dict(self.invalid_reasons),
            "rejected": self.rejected,
            "notes": list(self.notes),
            "warnings": list(self.warnings),
        }


@dataclass
class _TrackFacts:
    """What the total needs from each track, besides its summary."""

    steps: np.ndarray
    speeds: np.ndarray
    speed_source: str | None


def _track_facts(points: pd.DataFrame, has_speed: bool) -> _TrackFacts:
    t = points["t"].to_numpy(dtype=np.float64)
    steps = np.diff(t)
    speeds = np.empty(0)
    source: str | None = None
    if has_speed:
        reported = points["speed"].to_numpy(dtype=np.float64)
        if np.isfinite(reported).any():
            speeds, source = reported, "reported"
    if source is None and steps.size:
        lat = points["lat"].to_numpy(dtype=np.float64)
        lon = points["lon"].to_numpy(dtype=np.float64)
        speeds = haversine_m(lat[:-1], lon[:-1], lat[1:], lon[1:]) / steps
        source = "implied"
    return _TrackFacts(steps=steps, speeds=speeds, speed_source=source)


def _summary_of(
    name: str,
    points: int,
    invalid: int,
    duration: float | None,
    steps: list[np.ndarray],
    box: tuple[float, float, float, float] | None,
    speed: SpeedStats | None,
    span: tuple[float, float] | None = None,
) -> TrackSummary:
    """One summary from facts that may come from one track or many (``steps`` per track)."""
    all_steps = np.concatenate(steps) if steps else np.empty(0)
    median = float(np.median(all_steps)) if all_steps.size else None
    gaps = 0
    longest: float | None = None
    for track_steps in steps:
        if track_steps.size == 0:
            continue
        is_gap = track_steps > GAP_FACTOR * float(np.median(track_steps)) + _TIME_TOLERANCE_S
        gaps += int(is_gap.sum())
        if is_gap.any():
            longest = max(longest or 0.0, float(track_steps[is_gap].max()))
    return TrackSummary(
        track=name,
        points=points,
        invalid=invalid,
        median_step_s=median,
        rate_hz=1.0 / median if median else None,
        duration_s=duration,
        gaps=gaps,
        longest_gap_s=longest,
        lat_min=box[0] if box else None,
        lat_max=box[1] if box else None,
        lon_min=box[2] if box else None,
        lon_max=box[3] if box else None,
        speed=speed,
        start_s=span[0] if span else None,
        end_s=span[1] if span else None,
    )


def summarize(
    fixes: pd.DataFrame,
    *,
    rejected: int = 0,
    notes: list[str] | None = None,
    min_rate_hz: float = VALIDATED_DEFAULT["min_rate_hz"],
    max_rate_hz: float = VALIDATED_DEFAULT["max_rate_hz"],
) -> Summary:
    """Summarise canonical fixes (see the module docstring for every definition).

    ``rejected``/``notes`` pass on what a lenient reader skipped (NMEA
    sentences), from :attr:`gradgps.Table.rejected` and ``Table.notes``.
    """
    # One segment per track (no gap is too long) and no filling: the summary
    # measures the fixes as recorded and finds gaps itself.
    # Invalid rows by the rule every detection mode applies (rows in order per
    # track; a repeated or backward timestamp is unusable), so info and detect agree.
    row_reason = stream_reasons(fixes, min_step_s=MIN_STEP_S)
    invalid_rows = row_reason != ""
    prepared = preprocess(
        fixes.iloc[np.flatnonzero(~invalid_rows)], max_gap_s=sys.float_info.max, interpolate=False
    )
    points = prepared.points
    has_speed = "speed" in points.columns
    row_tracks = fixes["track"].astype(str).to_numpy(dtype=object)
    track_of_point = points["track"].astype(str).to_numpy(dtype=object)

    summaries: list[TrackSummary] = []
    step_lists: list[np.ndarray] = []
    speed_parts: list[np.ndarray] = []
    speed_sources: set[str] = set()
    for name in pd.unique(pd.Series(row_tracks, dtype=object)):
        in_track = row_tracks == name
        track_points = points[track_of_point == name]
        facts = _track_facts(track_points, has_speed)
        t = track_points["t"].to_numpy(dtype=np.float64)
        box = _box(track_points)
        speed = SpeedStats.of(facts.speeds, facts.speed_source) if facts.speed_source else None
        summaries.append(
            _summary_of(
                str(name),
                int(in_track.sum()),
                int((in_track & invalid_rows).sum()),
                float(t[-1] - t[0]) if facts.steps.size else None,
                [facts.steps],
                box,
                speed,
                (float(t[0]), float(t[-1])) if t.size else None,
            )
        )
        step_lists.append(facts.steps)
        if facts.speed_source:
            speed_parts.append(facts.speeds)
            speed_sources.add(facts.speed_source)

    total_speed = None
    if speed_parts:
        source = speed_sources.pop() if len(speed_sources) == 1 else "mixed"
        total_speed = SpeedStats.of(np.concatenate(speed_parts), source)
    durations = [s.duration_s for s in summaries if s.duration_s is not None]
    starts = [s.start_s for s in summaries if s.start_s is not None]
    ends = [s.end_s for s in summaries if s.end_s is not None]
    total = _summary_of(
        "total",
        len(fixes),
        int(invalid_rows.sum()),
        math.fsum(durations) if durations else None,
        step_lists,
        _box(points),
        total_speed,
        (min(starts), max(ends)) if starts else None,
    )
    reasons = Counter(str(r) for r in row_reason if r != "")
    return Summary(
        source=str(fixes.attrs.get("source", "<data>")),
        tracks=summaries,
        total=total,
        invalid_reasons=dict(reasons.most_common()),
        rejected=rejected,
        notes=list(notes or []),
        warnings=warnings_of(summaries, len(fixes))
        + input_warnings(fixes, min_rate_hz=min_rate_hz, max_rate_hz=max_rate_hz),
    )


def _box(points: pd.DataFrame) -> tuple[float, float, float, float] | None:
    if len(points) == 0:
        return None
    lat = points["lat"].to_numpy(dtype=np.float64)
    lon = points["lon"].to_numpy(dtype=np.float64)
    return float(lat.min()), float(lat.max()), float(lon.min()), float(lon.max())
