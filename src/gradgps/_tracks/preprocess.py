"""Preprocessing (paper section 4.1): order, merge, fill, split, project.

Detection needs evenly spaced, strictly time-ordered fixes in metres. Real
logs have rows out of order, repeated timestamps, dropouts and invalid values,
so :func:`preprocess` turns canonical fixes (see :mod:`gradgps._tracks.track`) into
*points* grouped in *segments*:

1. Invalid fixes (time, latitude or longitude missing, not finite or out of
   range) are set aside with a reason; they never enter a segment.
2. Each track is stably sorted by time.
3. Fixes with the same timestamp (or less than ``min_step_s`` apart) are
   merged into one point (mean position and channels, circular mean heading).
4. Gaps longer than the track's nominal period (median step) but no longer
   than ``max_gap_s`` are filled by linear interpolation at that period; the
   filled points are marked ``interpolated``. Longer gaps start a new segment.
5. Positions are projected to the track's own tangent plane (origin: its
   first valid fix in time) as ``east``/``north`` metres. With
   ``frame_radius_m`` (the detector's choice), a fix farther than that from
   its segment's first point also starts a new segment, and every segment
   gets its own plane at its first point (:attr:`Prepared.segment_frames`):
   a projection is only exact near its origin, and a track that starts at a
   bogus place or drives across a continent must not be measured from it.

Nothing is lost: :attr:`Prepared.row_point` maps every input row to the point
that represents it (``-1`` for an invalid row, whose reason is in
:attr:`Prepared.row_reason`), so results computed per point map back 1:1 to
input rows with :meth:`Prepared.to_rows`.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._exceptions import ConfigError
from .._result import NULL_ISLAND, STEP_TOLERANCE_S, invalid_reasons
from .geo import LocalFrame, radius_splits

__all__ = [
    "MIN_STEP_S",
    "NULL_ISLAND",
    "STEP_TOLERANCE_S",
    "Prepared",
    "invalid_reasons",
    "preprocess",
    "stream_reasons",
    "time_glitch_breaks",
]

_CORE = ("track", "t", "lat", "lon")


@dataclass
class Prepared:
    """Preprocessed points plus the map back to input rows.

    ``points`` columns: ``segment`` (int, global), ``track``, ``t``, ``lat``,
    ``lon``, ``east``, ``north``, every numeric channel of the input
    (``speed``, ``heading``...), ``interpolated`` (bool) and ``n_rows`` (input
    rows merged into the point; 0 for an interpolated one). Points are
    contiguous per segment and strictly increasing in ``t`` within one.
    """

    points: pd.DataFrame
    row_point: np.ndarray
    row_reason: np.ndarray
    frames: dict[str, LocalFrame]
    nominal_period: dict[str, float]
    segment_frames: list[LocalFrame] = field(default_factory=list)
    """The frame ``east``/``north`` of each segment (by global segment id) are in."""

    @property
    def n_rows(self) -> int:
        return int(self.row_point.size)

    def segment_slices(self) -> Iterator[tuple[int, slice]]:
        """``(segment id, slice of points)`` for each segment, in order."""
        seg = self.points["segment"].to_numpy()
        if seg.size == 0:
            return
        starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
        ends = np.r_[starts[1:], seg.size]
        for s, e in zip(starts, ends, strict=True):
            yield int(seg[s]), slice(int(s), int(e))

    def to_rows(self, values: np.ndarray, fill: object = np.nan) -> np.ndarray:
        """Per-point ``values`` -> per-input-row values (``fill`` for invalid rows)."""
        values = np.asarray(values)
        if values.shape[0] != len(self.points):
            raise ConfigError(
                f"expected {len(self.points)} values, one per point, got {values.shape[0]}"
            )
        ok = self.row_point >= 0
        out_dtype = (
            np.result_type(values.dtype, np.min_scalar_type(fill) if np.isscalar(fill) else object)
            if not isinstance(fill, str)
            else object
        )
        out = np.empty((self.n_rows, *values.shape[1:]), dtype=out_dtype)
        out[...] = fill
        out[ok] = values[self.row_point[ok]]
        return out


#: Shortest time step between two usable fixes of a track (1 kHz): closer is one instant.
MIN_STEP_S = 1e-3
#: Reasons :func:`stream_reasons` gives for a fix that is out of time order in its track.
NOT_AFTER = "time not after the previous fix"
TOO_CLOSE = "time less than 1 ms after the previous fix"


def stream_reasons(fixes: pd.DataFrame, *, min_step_s: float = MIN_STEP_S) -> np.ndarray:
    """Per row, why a fix cannot be used when each track is read in row order (``""`` if usable).

    The one rule every detection mode applies (whole file, chunks, follow,
    Python, report): the value checks of :func:`invalid_reasons`, then, per
    track in row order, a fix whose time is not after the previous *usable*
    fix of its track (a repeated or backward timestamp) or less than
    ``min_step_s`` after it is unusable. A repeated timestamp is never
    merged or averaged: no position is invented. Steps are compared with a
    tolerance of :data:`STEP_TOLERANCE_S` (timestamps like 1.7e9 + 0.001 s
    are not exact in float64), the same one :func:`gradgps._result.fix_reason`
    uses, so every mode draws the line at the same place.
    """
    reason = invalid_reasons(fixes)
    ok = np.flatnonzero(reason == "")
    if ok.size < 2:
        return reason
    t = fixes["t"].to_numpy(dtype=np.float64)
    shortest = min_step_s - STEP_TOLERANCE_S if min_step_s > 0 else 0.0
    codes, _ = pd.factorize(pd.Series(fixes["track"].to_numpy(dtype=object)[ok], dtype=object))
    rows = ok[np.argsort(codes, kind="stable")]
    bounds = np.flatnonzero(np.r_[True, np.diff(np.sort(codes, kind="stable")) != 0, True])
    for a, b in itertools.pairwise(bounds.tolist()):
        r = rows[a:b]
        tt = t[r]
        before = np.r_[-np.inf, np.maximum.accumulate(tt)[:-1]]
        late = tt > before
        close = late & (tt - before < shortest)
        if not close.any():
            reason[r[~late]] = NOT_AFTER
            continue
        last = -np.inf  # a close fix is not usable, so the running maximum is not the rule here
        for i, ti in zip(r.tolist(), tt.tolist(), strict=True):
            if ti <= last:
                reason[i] = NOT_AFTER
            elif ti - last < shortest:
                reason[i] = TOO_CLOSE
            else:
                last = ti
    return reason


def time_glitch_breaks(fixes: pd.DataFrame, reason: np.ndarray) -> np.ndarray:
    """Per row, whether a usable fix must begin a new segment because the time column could
    not time the step to it (see :func:`stream_reasons` for ``reason``).

    A fix set aside for its time (:data:`NOT_AFTER`, :data:`TOO_CLOSE`) at a position other
    than the previous usable fix's of its track is a fix the receiver made between that fix
    and the next usable one, in a time column coarser than the fixes come (whole seconds
    from a receiver a little faster than its nominal rate). The step to the next usable fix
    then covers two fixes' motion in one recorded step, which the detector would read as a
    jump and hold; so, as after a gap, nothing is predicted across it: that next usable fix
    begins a new segment. An exact repeat (the same time and position) says nothing of the
    sort and breaks nothing. Every mode applies this rule (batch here, streams in
    :class:`gradgps.Detector` and :class:`gradgps.FleetDetector`)."""
    breaks = np.zeros(len(fixes), dtype=bool)
    timed = np.flatnonzero((reason == NOT_AFTER) | (reason == TOO_CLOSE))
    if timed.size == 0:
        return breaks
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    tracks = fixes["track"].to_numpy(dtype=object)
    # Only the tracks that hold such a fix, each read in row order.
    glitchy = pd.Series(tracks).isin(set(tracks[timed])).to_numpy()
    read = (reason == "") | (reason == NOT_AFTER) | (reason == TOO_CLOSE)
    considered = np.flatnonzero(glitchy & read)
    last: dict[object, tuple[float, float]] = {}
    pending: set[object] = set()
    for i in considered.tolist():
        track = tracks[i]
        if reason[i] == "":
            if track in pending:
                breaks[i] = True
                pending.discard(track)
            last[track] = (lat[i], lon[i])
        elif track in last and last[track] != (lat[i], lon[i]):
            pending.add(track)
    return breaks


def _circular_mean_deg(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    rad = np.radians(values)
    finite = np.isfinite(rad)
    rad = np.where(finite, rad, 0.0)  # sin(inf) warns; non-finite headings are left out anyway
    s = np.add.reduceat(np.where(finite, np.sin(rad), 0.0), starts)
    c = np.add.reduceat(np.where(finite, np.cos(rad), 0.0), starts)
    k = np.add.reduceat(finite.astype(np.int64), starts)
    out = np.mod(np.degrees(np.arctan2(s, c)), 360.0)
    return np.where(k > 0, out, np.nan)


def _group_mean_lon(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """:func:`_group_mean` of longitudes, taken around the group's first one: two fixes
    either side of the antimeridian (179.9, -179.9) average to 180, not to 0."""
    first = values[starts]
    offset = np.repeat(first, np.diff(np.r_[starts, values.size]))
    wrapped = np.mod(values - offset + 180.0, 360.0) - 180.0
    mean = _group_mean(wrapped, starts) + first
    single = np.diff(np.r_[starts, values.size]) == 1
    mean = np.where(mean > 180.0, mean - 360.0, np.where(mean < -180.0, mean + 360.0, mean))
    return np.asarray(np.where(single, first, mean), dtype=np.float64)


def _group_mean(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    finite = np.isfinite(values)
    total = np.add.reduceat(np.where(finite, values, 0.0), starts)
    k = np.add.reduceat(finite.astype(np.int64), starts)
    return np.where(k > 0, total / np.maximum(k, 1), np.nan)


def _interp_heading(t_new: np.ndarray, t: np.ndarray, heading: np.ndarray) -> np.ndarray:
    ok = np.isfinite(heading)
    if ok.sum() < 2:
        return np.asarray(np.interp(t_new, t, heading), dtype=np.float64)
    unwrapped = np.full_like(heading, np.nan)
    unwrapped[ok] = np.degrees(np.unwrap(np.radians(heading[ok])))
    return np.asarray(np.mod(np.interp(t_new, t, unwrapped), 360.0), dtype=np.float64)


def preprocess(
    fixes: pd.DataFrame,
    *,
    max_gap_s: float = 5.0,
    interpolate: bool = True,
    min_step_s: float = 0.0,
    frame_radius_m: float | None = None,
    breaks: np.ndarray | None = None,
) -> Prepared:
    """Order, merge, fill and split canonical fixes; project to metres. See the module docstring.

    ``max_gap_s``: gaps up to this are interpolated (when ``interpolate``),
    longer ones split the track into segments. ``min_step_s``: a fix less
    than this after the previous one (in time order) is merged into its
    point, like a repeated timestamp; the default 0 merges only exact
    repeats. A chain of close fixes merges into one point, at the first time.
    ``frame_radius_m``: see step 5 of the module docstring. ``breaks`` (one per row,
    optional): rows whose point begins a new segment whatever the gap before it
    (:func:`time_glitch_breaks`).
    """
    if not np.isfinite(max_gap_s) or max_gap_s <= 0:
        raise ConfigError(f"max_gap_s must be a positive number of seconds, got {max_gap_s}")
    if not np.isfinite(min_step_s) or min_step_s < 0 or min_step_s >= max_gap_s:
        raise ConfigError(f"min_step_s must be in [0, max_gap_s), got {min_step_s}")
    missing = [c for c in _CORE if c not in fixes.columns]
    if missing:
        raise ConfigError(f"fixes frame lacks columns {missing}; build it with gradgps.to_fixes")
    n = len(fixes)
    channels = [
        c
        for c in fixes.columns
        if c not in _CORE
        and pd.api.types.is_numeric_dtype(fixes[c].dtype)
        and not pd.api.types.is_bool_dtype(fixes[c].dtype)
    ]
    reason = invalid_reasons(fixes)
    valid = reason == ""
    row_point = np.full(n, -1, dtype=np.int64)
    tracks = fixes["track"].to_numpy(dtype=object)
    t_all = fixes["t"].to_numpy(dtype=np.float64)
    lat_all = fixes["lat"].to_numpy(dtype=np.float64)
    lon_all = fixes["lon"].to_numpy(dtype=np.float64)
    chan_all = {c: fixes[c].to_numpy(dtype=np.float64, na_value=np.nan) for c in channels}

    pieces: list[dict[str, np.ndarray]] = []
    frames: dict[str, LocalFrame] = {}
    segment_frames: list[LocalFrame] = []
    periods: dict[str, float] = {}
    offset = 0
    segment_base = 0
    # Group the valid rows by track (in order of first appearance) and by time
    # within a track, with one stable sort: O(n log n) however many tracks.
    valid_rows = np.flatnonzero(valid)
    codes, order_of_tracks = pd.factorize(pd.Series(tracks[valid_rows], dtype=object), sort=False)
    by_track_time = np.lexsort((t_all[valid_rows], codes))
    sorted_rows = valid_rows[by_track_time]
    bounds = np.searchsorted(codes[by_track_time], np.arange(len(order_of_tracks) + 1))
    for k, track in enumerate(order_of_tracks):
        rows = sorted_rows[bounds[k] : bounds[k + 1]]
        t_sorted = t_all[rows]
        steps = np.diff(t_sorted)
        new_point = np.r_[True, steps >= min_step_s if min_step_s > 0 else steps > 0]
        starts = np.flatnonzero(new_point)
        group_of_row = np.cumsum(new_point) - 1
        t_u = t_sorted[starts]
        n_rows_u = np.diff(np.r_[starts, rows.size])
        lat_u = _group_mean(lat_all[rows], starts)
        lon_u = _group_mean_lon(lon_all[rows], starts)
        chan_u = {
            c: (_circular_mean_deg if c == "heading" else _group_mean)(v[rows], starts)
            for c, v in chan_all.items()
        }
        frame = LocalFrame(float(lat_u[0]), float(lon_u[0]))
        frames[str(track)] = frame
        dt = np.diff(t_u)
        period = float(np.median(dt)) if dt.size else 1.0
        periods[str(track)] = period
        split = dt > max_gap_s
        if breaks is not None:
            split |= breaks[rows][starts][1:]
        if frame_radius_m is None:
            east_u, north_u = frame.to_local(lat_u, lon_u)
            seg_frames = [frame] * (int(split.sum()) + 1)
        else:
            split = radius_splits(lat_u, lon_u, split, float(frame_radius_m))
            east_u, north_u = np.empty(t_u.size), np.empty(t_u.size)
            seg_frames = []
            bounds_u = np.r_[0, np.flatnonzero(split) + 1, t_u.size]
            for a, b in itertools.pairwise(bounds_u):
                seg_frame = LocalFrame(float(lat_u[a]), float(lon_u[a]))
                seg_frames.append(seg_frame)
                east_u[a:b], north_u[a:b] = seg_frame.to_local(lat_u[a:b], lon_u[a:b])
        segment_frames.extend(seg_frames)
        fill = np.zeros(dt.size, dtype=np.int64)
        if interpolate and period > 0:
            gap = (~split) & (dt > 1.5 * period)
            fill[gap] = np.maximum(np.rint(dt[gap] / period).astype(np.int64) - 1, 0)
        # New position of each unique point once the fill points are inserted.
        pos_u = np.arange(t_u.size) + np.r_[0, np.cumsum(fill)]
        total = t_u.size + int(fill.sum())
        t_full = np.empty(total)
        t_full[pos_u] = t_u
        is_interp = np.ones(total, dtype=bool)
        is_interp[pos_u] = False
        if total > t_u.size:
            gap_idx = np.repeat(np.arange(dt.size), fill)
            step = np.concatenate([np.arange(1, k + 1) for k in fill[fill > 0]])
            t_full[is_interp] = t_u[gap_idx] + dt[gap_idx] * step / (fill[gap_idx] + 1)
        if total > t_u.size:
            east = np.interp(t_full, t_u, east_u)
            north = np.interp(t_full, t_u, north_u)
            east[pos_u], north[pos_u] = east_u, north_u
            lat, lon = np.empty(total), np.empty(total)
            seg_full = np.empty(total, dtype=np.int64)
            seg_full[pos_u] = np.r_[0, np.cumsum(split)]
            seg_full[is_interp] = np.r_[0, np.cumsum(split)][gap_idx]
            for s_id, seg_frame in enumerate(seg_frames):
                here = seg_full == s_id
                lat[here], lon[here] = seg_frame.to_geodetic(east[here], north[here])
            lat[pos_u], lon[pos_u] = lat_u, lon_u
        else:  # nothing filled: the unique points are the points
            east, north, lat, lon = east_u, north_u, lat_u, lon_u
        seg_u = np.r_[0, np.cumsum(split)]
        segment = np.empty(total, dtype=np.int64)
        segment[pos_u] = seg_u
        if total > t_u.size:
            segment[is_interp] = seg_u[gap_idx]
        piece: dict[str, np.ndarray] = {
            "segment": segment + segment_base,
            "track": np.full(total, track, dtype=object),
            "t": t_full,
            "lat": lat,
            "lon": lon,
            "east": east,
            "north": north,
        }
        for c, v in chan_u.items():
            if total == t_u.size:
                piece[c] = v
                continue
            full = _interp_heading(t_full, t_u, v) if c == "heading" else np.interp(t_full, t_u, v)
            full[pos_u] = v
            piece[c] = full
        n_rows_full = np.zeros(total, dtype=np.int64)
        n_rows_full[pos_u] = n_rows_u
        piece["interpolated"] = is_interp
        piece["n_rows"] = n_rows_full
        pieces.append(piece)
        row_point[rows] = offset + pos_u[group_of_row]
        offset += total
        segment_base += int(seg_u[-1]) + 1

    columns = [
        "segment",
        "track",
        "t",
        "lat",
        "lon",
        "east",
        "north",
        *channels,
        "interpolated",
        "n_rows",
    ]
    if pieces:
        points = pd.DataFrame({c: np.concatenate([p[c] for p in pieces]) for c in columns})
    else:
        points = pd.DataFrame({c: pd.Series(dtype=_empty_dtype(c)) for c in columns})
    return Prepared(
        points=points,
        row_point=row_point,
        row_reason=reason,
        frames=frames,
        nominal_period=periods,
        segment_frames=segment_frames,
    )


def _empty_dtype(column: str) -> str:
    return {"segment": "int64", "track": "object", "interpolated": "bool", "n_rows": "int64"}.get(
        column, "float64"
    )
