"""How output times are written: in the input's own form, the same in every mode.

The rule (README, "Output times"): the output's time column is the input's
time column as the input wrote it. Readers of text formats keep their time
column as written (CSV, GeoJSON: text stays that text, with its own offset or
``Z``; epoch numbers stay the same numbers), Parquet keeps its column type
(a timestamp column written to CSV becomes ISO-8601 text). The formats whose
times are fields to be assembled, not text to keep, are written by
:func:`iso_utc`, the one formatter every mode uses (batch, chunked, follow,
report):

* **GPX**: ISO-8601 UTC with ``Z`` (``2026-11-23T10:00:05Z``; GPX times are
  UTC by the standard).
* **NMEA 0183**: ISO-8601 UTC (``2026-11-23T10:00:05.200Z``) when the date is
  known: from an RMC sentence (batch carries it to the epochs around it;
  ``--follow`` cannot look ahead, so sentences before the first dated RMC of
  a stream have no date yet). Without a date, the time of day alone, in the
  ISO-8601 form ``10:00:05.200Z`` (:func:`time_of_day_utc`).

Fractional seconds are written as milliseconds, and only when not zero.
The seconds the detector uses are kept beside the text
(:attr:`gradgps._tracks.track.Table.times`), so no precision or day count is
lost to the formatting.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from .._tracks.track import datetime_seconds

__all__ = [
    "csv_ready",
    "datetimes_as_text",
    "iso_utc",
    "iso_utc_one",
    "output_time_text",
    "time_of_day_utc",
]

_DAY = 86400.0


def _milliseconds(seconds: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(seconds, dtype=np.float64)
    ok = np.isfinite(t)
    ms = np.zeros(t.shape, dtype=np.int64)
    ms[ok] = np.round(t[ok] * 1000.0).astype(np.int64)
    return ms, ok


def _trim(text: np.ndarray, ms: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Drop ``.000`` from whole seconds; empty text where the time is missing."""
    out = np.asarray(text, dtype=object)
    whole = ok & (ms % 1000 == 0)
    out[whole] = [s.replace(".000Z", "Z") for s in out[whole]]
    out[~ok] = ""
    return out


def iso_utc(seconds: ArrayLike) -> np.ndarray:
    """Unix seconds as ISO-8601 UTC text (``2026-11-23T10:00:05Z``, ``...05.200Z``); ``""`` for NaN."""
    ms, ok = _milliseconds(seconds)
    stamps = ms.astype("datetime64[ms]")
    text = np.datetime_as_string(stamps, unit="ms", timezone="UTC")
    return _trim(text, ms, ok)


def iso_utc_one(seconds: float) -> str:
    """:func:`iso_utc` of one time."""
    return str(iso_utc(np.array([seconds]))[0])


def time_of_day_utc(seconds: ArrayLike) -> np.ndarray:
    """Seconds since a UTC midnight as the time of day alone (``10:00:05.200Z``); ``""`` for NaN.

    For NMEA without a date: past 86400 (a drive across midnight) it wraps to the next day's time.
    """
    t = np.asarray(seconds, dtype=np.float64)
    return np.asarray([text[11:] for text in iso_utc(np.mod(t, _DAY))], dtype=object)


def datetimes_as_text(series: pd.Series) -> pd.Series:
    """A datetime column as ISO-8601 text for a CSV: ``Z`` for UTC, its own offset otherwise.

    Naive datetimes stay without an offset; missing ones become empty text.
    """
    tz = getattr(series.dt, "tz", None)
    missing = series.isna()
    if tz is not None and str(tz) in ("UTC", "utc"):
        seconds = datetime_seconds(series)
        text = pd.Series(iso_utc(seconds), index=series.index, dtype=object)
    elif tz is not None:
        text = series.map(_iso_with_offset)
    else:
        seconds = datetime_seconds(series.dt.tz_localize("UTC"))
        text = pd.Series(
            [s[:-1] if s else s for s in iso_utc(seconds)], index=series.index, dtype=object
        )
    return text.where(~missing, "")


def _iso_with_offset(stamp: object) -> str:
    if not isinstance(stamp, pd.Timestamp):
        return ""
    return stamp.isoformat(timespec="milliseconds").replace(".000", "", 1)


def csv_ready(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with its datetime columns as ISO-8601 text (:func:`datetimes_as_text`), for CSV."""
    stamped = [
        k for k in range(frame.shape[1]) if pd.api.types.is_datetime64_any_dtype(frame.iloc[:, k])
    ]
    if not stamped:
        return frame
    out = frame.copy()
    for k in stamped:
        out.isetitem(k, datetimes_as_text(frame.iloc[:, k]).to_numpy(dtype=object))
    return out


def output_time_text(frame: pd.DataFrame, column: str | None) -> np.ndarray | None:
    """Each row's time as the output writes it, where the input wrote text or datetimes.

    ``None`` for numbers (epochs, relative seconds: a report shows them as
    readable UTC instead) or when there is no such column.
    """
    if column is None or column not in frame.columns:
        return None
    series = frame[column]
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        return np.asarray(datetimes_as_text(series), dtype=object)
    if pd.api.types.is_numeric_dtype(series.dtype) or pd.api.types.is_bool_dtype(series.dtype):
        return None
    return np.asarray(series.astype("string").fillna("").str.strip(), dtype=object)
