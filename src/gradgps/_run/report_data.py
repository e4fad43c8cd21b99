"""What ``--report`` and ``--plots`` draw, collected chunk by chunk in bounded memory.

``gradgps detect`` streams its input (:mod:`gradgps._run.chunked`); the report
must not need the whole result in memory either (issue 18). A
:class:`ReportCollector` takes each chunk's fixes and result in row order:

* up to :data:`EXACT_ROWS` rows it keeps them all, and the report is the one
  drawn from the whole result (the same file as before this module);
* past that it *thins*: it keeps exact counts (everything the summary, the
  legends and the track view's captions say), the first
  :data:`MAX_TABLE_ROWS` anomalous fixes (the anomaly
  table), and per track an evenly spread sample of the usable fixes (every
  k-th, k doubling as the track grows: at most :data:`TRACK_ROWS` per track and
  about :data:`SAMPLE_ROWS` in all) and of its flagged fixes (at most
  :data:`TRACK_DOTS` per track, about :data:`DOT_ROWS` in
  all), each with its row number and its line's run number (a new run where
  usable fixes are more than :data:`gradgps._io.export.LINE_GAP_S` apart, as
  the GeoJSON cuts lines), plus one byte per row (usable, flagged) for the
  channel figures. The figures, the track view and the embedded GeoJSON are
  drawn from that sample, and the page says so. The channel figures need
  every fix of a segment (the REMA bounds are a recursive filter): the input
  is read a second time (:meth:`ReportCollector.channels`) for the first
  :data:`CHANNEL_ROWS` usable fixes of the :data:`CHANNEL_TRACKS` tracks
  with the most flagged fixes, and the busiest segments among those are
  drawn.

Memory is then the sample (a few tens of MB), one byte per input row, a few
counters per track, and the fault events (:class:`gradgps._grad.events.EventBuilder`
keeps one small row per flagged fix).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._io.export import LINE_GAP_S
from .._result import ResultCounts

__all__ = [
    "CHANNEL_ROWS",
    "CHANNEL_TRACKS",
    "DOT_ROWS",
    "EXACT_ROWS",
    "MAX_TABLE_ROWS",
    "SAMPLE_ROWS",
    "TRACK_DOTS",
    "TRACK_ROWS",
    "ReportCollector",
    "ReportTotals",
    "Thinned",
]

#: Rows of the report's anomaly table: the first this many anomalous fixes, kept exactly.
MAX_TABLE_ROWS = 100
#: Rows kept whole: up to this many, the report is drawn from the whole result.
EXACT_ROWS = 250_000
#: Usable fixes sampled for the lines, per track and over all tracks (at least
#: :data:`MIN_TRACK_ROWS` per track, so a run with very many tracks keeps more).
TRACK_ROWS = 4_000
SAMPLE_ROWS = 200_000
MIN_TRACK_ROWS = 64
#: Flagged fixes sampled for the markers, per track (as many as the track view draws,
#: :data:`gradgps._run.explore.MAX_DOTS`) and over all tracks.
TRACK_DOTS = 5_000
DOT_ROWS = 100_000
#: The channel figures of a thinned report: the first this many usable fixes of each of
#: the this many tracks with the most flagged fixes, read again from the input.
CHANNEL_ROWS = 200_000
CHANNEL_TRACKS = 3

#: The result columns a sample keeps (all the report reads).
_RESULT = (
    "anomaly",
    "score",
    "bias_type",
    "time_type",
    "alert",
    "lat_clean",
    "lon_clean",
    "invalid_reason",
)
_USABLE, _FLAGGED = np.uint8(1), np.uint8(2)


def _ordered_counts(counts: dict[Any, int]) -> pd.Series:
    """Counts in first-seen order, sorted as :meth:`pandas.Series.value_counts` sorts them."""
    if not counts:
        return pd.Series([], dtype=np.int64)
    return pd.Series(list(counts.values()), index=list(counts.keys()), dtype=np.int64).sort_values(
        ascending=False
    )


def _add_counts(into: dict[Any, int], values: np.ndarray) -> None:
    for key, n in pd.Series(values, dtype=object).value_counts(sort=False).items():
        into[key] = into.get(key, 0) + int(n)


@dataclass
class ReportTotals:
    """Exact counts of a thinned report's whole run (what the summary, legends and captions say)."""

    counts: ResultCounts = field(default_factory=lambda: ResultCounts(0, 0, 0, 0))
    tracks: set[Any] = field(default_factory=set)
    usable: int = 0  # invalid_reason == ""
    reasons: dict[Any, int] = field(default_factory=dict)
    bias: dict[Any, int] = field(default_factory=dict)  # usable anomalies by bias type
    time: dict[Any, int] = field(default_factory=dict)
    flagged: int = 0  # usable anomalies
    # The track figure: fixes with a position, repaired positions, markers by type.
    drawn: int = 0
    recovered: int = 0
    repaired: int = 0
    markers: dict[tuple[Any, Any], int] = field(default_factory=dict)
    # Per track (the view's captions and the channel tracks): drawn fixes, flagged ones.
    per_track: dict[str, list[int]] = field(default_factory=dict)

    def reason_counts(self) -> pd.Series:
        return _ordered_counts(self.reasons)

    def bias_counts(self) -> pd.Series:
        return _ordered_counts(self.bias)

    def time_counts(self) -> pd.Series:
        return _ordered_counts(self.time)


@dataclass
class Thinned:
    """A thinned report's data (:class:`ReportCollector` past :data:`EXACT_ROWS` rows)."""

    fixes: pd.DataFrame  # the sample: track, t, lat, lon
    result: pd.DataFrame  # its result rows
    rows: np.ndarray  # input row numbers, increasing
    parts: np.ndarray  # each row's line run within its track
    time_text: np.ndarray | None
    totals: ReportTotals
    channel: tuple[pd.DataFrame, pd.DataFrame] | None = None
    channel_note: str = ""


class _Sampler:
    """Every k-th candidate row per track, k doubling when a track's share is exceeded."""

    def __init__(self, per_track: int, total: int) -> None:
        self.per_track, self.total = per_track, total
        self.seen: dict[Any, int] = {}
        self.stride: dict[Any, int] = {}
        self.frame: pd.DataFrame | None = None

    def add(self, frame: pd.DataFrame) -> None:
        """``frame``: candidate rows of one chunk (column ``track``), in row order."""
        if frame.empty:
            return
        tracks = frame["track"]
        base = tracks.map(self.seen).fillna(0).to_numpy(np.int64)
        ordinal = base + tracks.groupby(tracks, sort=False).cumcount().to_numpy(np.int64)
        stride = tracks.map(self.stride).fillna(1).to_numpy(np.int64)
        for track, n in tracks.value_counts(sort=False).items():
            self.seen[track] = self.seen.get(track, 0) + int(n)
            self.stride.setdefault(track, 1)
        kept = frame.loc[ordinal % stride == 0].assign(ordinal=ordinal[ordinal % stride == 0])
        self.frame = kept if self.frame is None else pd.concat([self.frame, kept])
        self._thin()

    def _thin(self) -> None:
        assert self.frame is not None
        share = max(MIN_TRACK_ROWS, min(self.per_track, self.total // max(1, len(self.seen))))
        sizes = self.frame["track"].value_counts(sort=False)
        over = sizes[sizes > share]
        if over.empty:
            return
        keep = np.ones(len(self.frame), dtype=bool)
        ordinal = self.frame["ordinal"].to_numpy(np.int64)
        positions = self.frame.groupby("track", sort=False).indices
        for track, n in over.items():
            mine = positions[track]
            stride = self.stride[track]
            while n > share:
                stride *= 2
                n = int((ordinal[mine] % stride == 0).sum())
            self.stride[track] = stride
            keep[mine[ordinal[mine] % stride != 0]] = False
        self.frame = self.frame.loc[keep]


class _Thinning:
    """The thinned collection (see the module docstring)."""

    def __init__(self, max_dots: int, first_rows: int) -> None:
        self.totals = ReportTotals()
        self.lines = _Sampler(TRACK_ROWS, SAMPLE_ROWS)
        self.dots = _Sampler(max_dots, DOT_ROWS)
        self.first: list[pd.DataFrame] = []
        self.first_rows = first_rows
        self.first_n = 0
        self.flags: list[np.ndarray] = []
        self.rows = 0
        self.texts = True  # every chunk's times are text
        self.last_t: dict[Any, float] = {}
        self.part: dict[Any, int] = {}

    def add(self, fixes: pd.DataFrame, result: pd.DataFrame, text: Any) -> None:
        n = len(fixes)
        tot = self.totals
        tot.counts = tot.counts + ResultCounts.of(result)
        reason = result["invalid_reason"].to_numpy(object)
        usable = reason == ""
        anomaly = result["anomaly"].to_numpy() == 1
        flagged = usable & anomaly
        tracks = fixes["track"].to_numpy(object)
        lat = fixes["lat"].to_numpy(np.float64)
        lon = fixes["lon"].to_numpy(np.float64)
        lat_c = result["lat_clean"].to_numpy(np.float64)
        lon_c = result["lon_clean"].to_numpy(np.float64)
        bias = result["bias_type"].to_numpy(object)
        time_type = result["time_type"].to_numpy(object)
        tot.tracks.update(pd.unique(tracks).tolist())
        tot.usable += int(usable.sum())
        tot.flagged += int(flagged.sum())
        _add_counts(tot.reasons, reason[~usable])
        _add_counts(tot.bias, bias[flagged])
        _add_counts(tot.time, time_type[flagged])
        drawn = usable & np.isfinite(lat)
        clean = drawn & np.isfinite(lat_c) & np.isfinite(lon_c)
        marked = drawn & anomaly
        tot.drawn += int(drawn.sum())
        tot.recovered += int(clean.sum())
        tot.repaired += int((marked & clean).sum())
        pairs = pd.DataFrame({"b": bias[marked], "t": time_type[marked]}, dtype=object)
        for key, k in pairs.value_counts(sort=False, dropna=False).items():
            pair = (key[0], key[1]) if isinstance(key, tuple) else (key, None)
            tot.markers[pair] = tot.markers.get(pair, 0) + int(k)
        per = pd.DataFrame({"track": tracks[drawn], "flagged": marked[drawn]})
        for track, row in (
            per.groupby("track", sort=False)["flagged"].agg(["size", "sum"]).iterrows()
        ):
            counts = tot.per_track.setdefault(str(track), [0, 0])
            counts[0] += int(row["size"])
            counts[1] += int(row["sum"])
        self.flags.append((usable * _USABLE) | (flagged * _FLAGGED))
        if text is None:
            self.texts = False
        frame = pd.DataFrame(
            {
                "row": np.arange(self.rows, self.rows + n, dtype=np.int64),
                "track": tracks,
                "t": fixes["t"].to_numpy(np.float64),
                "lat": lat,
                "lon": lon,
                "text": text if text is not None else np.full(n, "", dtype=object),
                **{c: result[c].to_numpy() for c in _RESULT},
            }
        )
        frame["part"] = self._parts(frame, drawn)
        self.lines.add(frame.loc[drawn])
        self.dots.add(frame.loc[marked & np.isfinite(lon)])
        if self.first_n < self.first_rows:
            head = frame.loc[flagged].head(self.first_rows - self.first_n)
            self.first.append(head)
            self.first_n += len(head)
        self.rows += n

    def _parts(self, frame: pd.DataFrame, drawn: np.ndarray) -> np.ndarray:
        """Each drawn row's line run within its track (a gap over LINE_GAP_S starts one)."""
        parts = np.zeros(len(frame), dtype=np.int64)
        sub = frame.loc[drawn, ["track", "t"]]
        if sub.empty:
            return parts
        tracks = sub["track"]
        previous = sub.groupby("track", sort=False)["t"].shift()
        carried = tracks.map(self.last_t)
        previous = previous.fillna(carried)
        new_run = (sub["t"] - previous > LINE_GAP_S).to_numpy()
        base = tracks.map(self.part).fillna(0).to_numpy(np.int64)
        runs = base + pd.Series(new_run, index=sub.index).groupby(tracks, sort=False).cumsum()
        parts[drawn] = runs.to_numpy(np.int64)
        ends = pd.DataFrame({"track": tracks, "t": sub["t"], "part": runs}).groupby(
            "track", sort=False
        )
        for track, last in ends.last().iterrows():
            self.last_t[track] = float(last["t"])
            self.part[track] = int(last["part"])
        return parts

    def result(self) -> Thinned:
        frames = [f for f in (self.lines.frame, self.dots.frame, *self.first) if f is not None]
        sample = pd.concat(frames) if frames else None
        if sample is None or sample.empty:
            sample = pd.DataFrame(
                {
                    "row": np.zeros(0, np.int64),
                    "track": np.zeros(0, object),
                    **{c: np.zeros(0) for c in ("t", "lat", "lon", "lat_clean", "lon_clean")},
                    "text": np.zeros(0, object),
                    "part": np.zeros(0, np.int64),
                    **{
                        c: np.zeros(0, object) for c in ("bias_type", "time_type", "invalid_reason")
                    },
                    **{c: np.zeros(0, np.int64) for c in ("anomaly", "alert")},
                    "score": np.zeros(0),
                }
            )
        sample = sample.drop_duplicates("row").sort_values("row", kind="stable")
        sample = sample.reset_index(drop=True)
        fixes = sample[["track", "t", "lat", "lon"]].copy()
        result = sample[list(_RESULT)].copy()
        return Thinned(
            fixes=fixes,
            result=result,
            rows=sample["row"].to_numpy(np.int64),
            parts=sample["part"].to_numpy(np.int64),
            time_text=sample["text"].to_numpy(object) if self.texts else None,
            totals=self.totals,
        )

    def row_flags(self) -> np.ndarray:
        if len(self.flags) > 1:
            self.flags = [np.concatenate(self.flags)]
        return self.flags[0] if self.flags else np.zeros(0, np.uint8)


class ReportCollector:
    """The report's data, fed chunk by chunk (see the module docstring).

    :meth:`add` takes each chunk's canonical fixes, result and time text (the
    output's time column as text, or ``None`` where the input's times are
    numbers), in row order. Then :meth:`whole` gives the kept result of a run of
    at most ``exact_rows`` rows, or ``None`` when the run was thinned and
    :meth:`thinned` gives its data instead.
    """

    def __init__(self, exact_rows: int | None = None) -> None:
        self.exact_rows = EXACT_ROWS if exact_rows is None else exact_rows
        self.rows = 0
        self._kept: list[tuple[pd.DataFrame, pd.DataFrame, Any]] | None = []
        self._thinning = _Thinning(TRACK_DOTS, MAX_TABLE_ROWS)

    def add(self, fixes: pd.DataFrame, result: pd.DataFrame, time_text: Any) -> None:
        self.rows += len(fixes)
        if self._kept is None:
            self._thinning.add(fixes, result, time_text)
            return
        self._kept.append((fixes, result, time_text))
        if self.rows > self.exact_rows:
            for kept in self._kept:
                self._thinning.add(*kept)
            self._kept = None

    def whole(self) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray | None] | None:
        """The whole run's fixes, result and time text; ``None`` once thinned."""
        if self._kept is None:
            return None
        if not self._kept:
            return None
        fixes = pd.concat([f for f, _, _ in self._kept], ignore_index=True)
        result = pd.concat([r for _, r, _ in self._kept], ignore_index=True)
        texts = [t for _, _, t in self._kept]
        text = None if any(t is None for t in texts) else np.concatenate(texts)
        return fixes, result, text

    def thinned(self, reread: Callable[[], Iterable[pd.DataFrame]] | None = None) -> Thinned | None:
        """The thinned run's data; with ``reread`` (the input's canonical fixes again,
        chunk by chunk, in row order), its channel figures' fixes too."""
        if self._kept is not None:
            return None
        out = self._thinning.result()
        if reread is not None:
            out.channel, out.channel_note = self._channels(reread, out.totals)
        return out

    def _channels(
        self, reread: Callable[[], Iterable[pd.DataFrame]], totals: ReportTotals
    ) -> tuple[tuple[pd.DataFrame, pd.DataFrame] | None, str]:
        ranked = sorted(totals.per_track.items(), key=lambda kv: (-kv[1][1], -kv[1][0], kv[0]))
        chosen = {name for name, _ in ranked[:CHANNEL_TRACKS]}
        if not chosen:
            return None, ""
        flags = self._thinning.row_flags()
        taken: dict[str, int] = {}
        parts: list[pd.DataFrame] = []
        flagged: list[np.ndarray] = []
        offset = 0
        for fixes in reread():
            n = len(fixes)
            mine = flags[offset : offset + n]
            offset += n
            names = fixes["track"].astype(str).to_numpy(object)
            rows = np.flatnonzero(((mine & _USABLE) > 0) & np.isin(names, list(chosen)))
            if rows.size:
                rank = pd.Series(names[rows]).groupby(names[rows], sort=False).cumcount().to_numpy()
                base = pd.Series(names[rows]).map(taken).fillna(0).to_numpy(np.int64)
                rows = rows[base + rank < CHANNEL_ROWS]
                for name, k in pd.Series(names[rows]).value_counts(sort=False).items():
                    taken[str(name)] = taken.get(str(name), 0) + int(k)
                parts.append(fixes.iloc[rows])
                flagged.append((mine[rows] & _FLAGGED) > 0)
            if len(taken) == len(chosen) and all(v >= CHANNEL_ROWS for v in taken.values()):
                break
        if not parts:
            return None, ""
        fixes_all = pd.concat(parts, ignore_index=True)
        anomaly = np.concatenate(flagged).astype(np.int8)
        result = pd.DataFrame({"anomaly": anomaly, "invalid_reason": np.full(len(anomaly), "")})
        note = (
            f"Drawn from the first {CHANNEL_ROWS:,} usable fixes (at most) of the "
            f"{len(chosen)} track(s) with the most flagged fixes, read again from the input "
            "(segments numbered within those fixes)."
        )
        return (fixes_all, result), note
