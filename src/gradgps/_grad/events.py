"""Fault events: runs of consecutive anomalous fixes of one track, what a person reads first.

An event is a maximal run of usable fixes of one track, in row order, that
the detector flagged (``anomaly=1``); a usable fix judged normal ends it.
Unusable fixes (``invalid_reason`` set) neither start nor end an event: they
are data problems (a repeated timestamp, a missing latitude), counted
separately. Per event: track, first and last row, start and end time,
duration, fixes, the most common bias and time type, the peak offset (the
largest distance between a flagged fix and its repaired position, metres),
the peak score, and whether it raised an alert.

:class:`EventBuilder` takes results chunk by chunk (a run may cross a chunk
boundary) and holds only the flagged rows, so ``detect --events`` stays in
bounded memory on a file of any length.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._tracks.geo import haversine_m

__all__ = ["EVENT_COLUMNS", "EventBuilder", "fault_events"]

EVENT_COLUMNS = (
    "track",
    "start",
    "end",
    "duration_s",
    "fixes",
    "bias_type",
    "time_type",
    "peak_offset_m",
    "peak_score",
    "alert",
    "first_row",
    "last_row",
)


class EventBuilder:
    """Collects fault events from (fixes, result) chunks given in row order."""

    def __init__(self) -> None:
        self._open: dict[str, int] = {}  # track -> id of the event its last usable fix belongs to
        self._next_id = 0
        self._rows = 0
        self._parts: list[pd.DataFrame] = []

    def add(self, fixes: pd.DataFrame, result: pd.DataFrame) -> None:
        """One chunk: canonical fixes and the detector's result, same length, row order."""
        n = len(fixes)
        usable = result["invalid_reason"].to_numpy() == ""
        flagged = usable & (result["anomaly"].to_numpy() == 1)
        rows = np.flatnonzero(usable)
        tracks = fixes["track"].to_numpy(object)
        event = np.full(n, -1, np.int64)
        for i, f in zip(rows.tolist(), flagged[rows].tolist(), strict=True):
            track = tracks[i]
            if not f:
                self._open.pop(track, None)
                continue
            eid = self._open.get(track)
            if eid is None:
                eid = self._next_id
                self._next_id += 1
                self._open[track] = eid
            event[i] = eid
        sel = np.flatnonzero(event >= 0)
        if sel.size:
            lat = fixes["lat"].to_numpy(np.float64)[sel]
            lon = fixes["lon"].to_numpy(np.float64)[sel]
            lat_c = result["lat_clean"].to_numpy(np.float64)[sel]
            lon_c = result["lon_clean"].to_numpy(np.float64)[sel]
            self._parts.append(
                pd.DataFrame(
                    {
                        "event": event[sel],
                        "track": tracks[sel],
                        "t": fixes["t"].to_numpy(np.float64)[sel],
                        "row": sel + self._rows,
                        "bias_type": result["bias_type"].to_numpy(object)[sel],
                        "time_type": result["time_type"].to_numpy(object)[sel],
                        "offset": haversine_m(lat, lon, lat_c, lon_c),
                        "score": result["score"].to_numpy(np.float64)[sel],
                        "alert": result["alert"].to_numpy()[sel].astype(np.int64),
                    }
                )
            )
        self._rows += n

    def events(self) -> pd.DataFrame:
        """The events so far, in order of their first fix; times in seconds as given."""
        if not self._parts:
            return pd.DataFrame({c: pd.Series(dtype=_dtype(c)) for c in EVENT_COLUMNS})
        rows = pd.concat(self._parts, ignore_index=True)
        g = rows.groupby("event", sort=True)

        def mode(s: pd.Series) -> str:
            return str(s.value_counts().index[0])

        out = pd.DataFrame(
            {
                "track": g["track"].first(),
                "start": g["t"].min(),
                "end": g["t"].max(),
                "fixes": g.size(),
                "bias_type": g["bias_type"].agg(mode),
                "time_type": g["time_type"].agg(mode),
                "peak_offset_m": g["offset"].max(),
                "peak_score": g["score"].max(),
                "alert": g["alert"].max().astype(np.int8),
                "first_row": g["row"].min(),
                "last_row": g["row"].max(),
            }
        )
        out["duration_s"] = out["end"] - out["start"]
        return out[list(EVENT_COLUMNS)].reset_index(drop=True)


def _dtype(column: str) -> str:
    if column in ("track", "bias_type", "time_type"):
        return "object"
    if column in ("fixes", "first_row", "last_row"):
        return "int64"
    return "int8" if column == "alert" else "float64"


def fault_events(fixes: pd.DataFrame, result: pd.DataFrame) -> pd.DataFrame:
    """The fault events of one detection result (see the module docstring)."""
    builder = EventBuilder()
    builder.add(fixes, result)
    return builder.events()
