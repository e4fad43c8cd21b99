"""The track model: what a fix is, how columns are found, how a table becomes fixes.

A *track* is a time-ordered series of fixes from one vehicle. At the API
boundary tracks live in a pandas DataFrame, one row per fix; a track-id column
separates several tracks in one table. Inside, everything is NumPy arrays.

:func:`to_fixes` turns any table (read from CSV, Parquet, GPX, NMEA or passed
in by a user) into the *canonical fixes frame*:

=========  ==========  ======================================================
column     dtype       meaning
=========  ==========  ======================================================
track      object      track id (``"0"`` when the table has no track column)
t          float64     seconds (unix or relative; ISO-8601 strings converted)
lat, lon   float64     degrees WGS84 (NaN where missing)
speed      float64     m/s, optional
heading    float64     degrees, optional, taken modulo 360
alt        float64     metres, optional
hdop       float64     optional
=========  ==========  ======================================================

Its index is the input row number (0-based), so every later result maps back
1:1 to the input rows. Missing or out-of-range *values* are kept (NaN) and
dealt with downstream as invalid fixes; *unparseable* values (text in a number
column) are an :class:`InputError` naming the row and column, because they
mean the file or the column mapping is wrong.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields, replace

import numpy as np
import pandas as pd

from .._exceptions import InputError

__all__ = [
    "CANONICAL_COLUMNS",
    "OPTIONAL_CHANNELS",
    "ColumnMap",
    "Table",
    "resolve_columns",
    "to_fixes",
]

OPTIONAL_CHANNELS = ("speed", "heading", "alt", "hdop")
CANONICAL_COLUMNS = ("track", "t", "lat", "lon", *OPTIONAL_CHANNELS)

# Common spellings, compared after lower-casing and dropping everything that is
# not a letter or digit ("GPS Latitude" -> "gpslatitude"). First match wins.
_ALIASES: dict[str, tuple[str, ...]] = {
    "time": (
        "t",
        "time",
        "timestamp",
        "ts",
        "datetime",
        "date_time",
        "utc",
        "gpstime",
        "unixtime",
        "epoch",
        "timeutc",
        "utctime",
        "trel",
        "seconds",
        "sec",
        "timesec",
        "times",
        "timestamps",
    ),
    "lat": (
        "lat",
        "latitude",
        "gpslat",
        "gpslatitude",
        "latdeg",
        "latitudedeg",
        "y_lat",
        "latwgs84",
    ),
    "lon": (
        "lon",
        "lng",
        "long",
        "longitude",
        "gpslon",
        "gpslng",
        "gpslong",
        "gpslongitude",
        "londeg",
        "longitudedeg",
        "lonwgs84",
    ),
    "track": (
        "track",
        "trackid",
        "track_id",
        "trip",
        "tripid",
        "drive",
        "driveid",
        "vehicle",
        "vehicleid",
        "trace",
        "traceid",
        "segment",
        "id",
    ),
    "speed": ("speed", "speedmps", "speedms", "velocity", "gpsspeed", "spd"),
    "heading": (
        "heading",
        "headingdeg",
        "course",
        "coursedeg",
        "bearing",
        "cog",
        "track_angle",
        "azimuth",
        "yaw",
    ),
    "alt": ("alt", "altm", "altitude", "elevation", "ele", "height", "altitudem"),
    "hdop": ("hdop",),
}


def _norm(name: str) -> str:
    return re.sub(r"[^0-9a-z]", "", name.lower())


@dataclass(frozen=True)
class ColumnMap:
    """Which input column holds which quantity; ``None`` means auto-detect.

    Pass names to override detection (the CLI's ``--time-col`` etc.). An
    empty string for an optional column means "do not use one".
    """

    time: str | None = None
    lat: str | None = None
    lon: str | None = None
    track: str | None = None
    speed: str | None = None
    heading: str | None = None
    alt: str | None = None
    hdop: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass
class Table:
    """A table as read from a file, before conversion to canonical fixes.

    ``frame`` keeps every input column with its original name and order (the
    ``detect`` output keeps them all). ``first_line`` is the file line of data
    row 1 (2 for a CSV with a header) so errors can name lines; ``None`` where
    lines mean nothing (Parquet). ``row_offset`` is the number of input rows
    before this table when it is one chunk of a bigger file (streaming), so
    errors name rows of the file. ``rejected`` counts records a lenient reader
    skipped (bad NMEA checksums), with ``notes`` saying which.
    """

    frame: pd.DataFrame
    source: str = "<data>"
    columns: ColumnMap = ColumnMap()
    first_line: int | None = None
    rejected: int = 0
    notes: list[str] | None = None
    row_offset: int = 0


def resolve_columns(
    names: Iterable[str], overrides: ColumnMap | None = None, *, source: str = "<data>"
) -> ColumnMap:
    """Auto-detect the role of each column, honouring explicit overrides.

    Raises :class:`InputError` when a named column does not exist or when time,
    latitude or longitude cannot be found, listing the available columns.
    """
    names = list(names)
    by_norm: dict[str, str] = {}
    for n in names:
        by_norm.setdefault(_norm(str(n)), str(n))
    wanted = (overrides or ColumnMap()).as_dict()
    chosen: dict[str, str | None] = {}
    used: set[str] = set()
    for role, given in wanted.items():
        if given is not None:
            if given == "":
                chosen[role] = None
                continue
            if given not in names:
                raise InputError(
                    f"no column named {given!r} for {role}",
                    source=source,
                    hint=f"available columns: {', '.join(map(str, names))}",
                )
            chosen[role] = given
            used.add(given)
    for role in wanted:
        if role in chosen:
            continue
        found = None
        for alias in _ALIASES[role]:
            cand = by_norm.get(_norm(alias))
            if cand is not None and cand not in used:
                found = cand
                break
        chosen[role] = found
        if found is not None:
            used.add(found)
    for role, flag in (("time", "--time-col"), ("lat", "--lat-col"), ("lon", "--lon-col")):
        if chosen[role] is None:
            raise InputError(
                f"cannot find the {role} column",
                source=source,
                hint=f"name it with {flag}; available columns: {', '.join(map(str, names))}",
            )
    return ColumnMap(**chosen)


def _numeric(frame: pd.DataFrame, col: str, table: Table, *, what: str) -> np.ndarray:
    """Column as float64; text that is not a number raises naming the first bad row."""
    series = frame[col]
    if pd.api.types.is_bool_dtype(series.dtype):
        raise InputError(f"expected {what}, found booleans", source=table.source, column=col)
    if pd.api.types.is_numeric_dtype(series.dtype):
        return np.asarray(series.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)
    as_str = series.astype("string").str.strip()
    blank = series.isna() | (as_str == "") | as_str.str.lower().isin(["nan", "na", "null", "none"])
    values = pd.to_numeric(as_str.where(~blank, None), errors="coerce")
    bad = values.isna() & ~blank
    if bool(bad.any()):
        pos = int(np.flatnonzero(bad.to_numpy())[0])
        raise _row_error(table, pos, col, f"not a number ({what}): {series.iloc[pos]!r}")
    return np.asarray(values.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)


def _row_error(table: Table, pos: int, col: str, reason: str) -> InputError:
    line = None if table.first_line is None else table.first_line + pos
    return InputError(
        reason,
        source=table.source,
        row=table.row_offset + pos + 1,
        line=line,
        column=col,
        hint="fix the value or choose another column",
    )


def _times(frame: pd.DataFrame, col: str, table: Table) -> np.ndarray:
    """Seconds as float64: numbers as they are (ms or us epochs scaled), datetimes/ISO strings to unix."""
    series = frame[col]
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        dt = pd.to_datetime(series, utc=True)
        return _datetime_seconds(dt)
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        t = np.asarray(series.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)
        return _scale_epoch(t)
    as_str = series.astype("string").str.strip()
    numeric = pd.to_numeric(as_str, errors="coerce")
    if bool(numeric.notna().all()) or bool(
        (numeric.notna() | as_str.isna() | (as_str == "")).all()
    ):
        return _scale_epoch(np.asarray(numeric.to_numpy(dtype=np.float64, na_value=np.nan)))
    blank = series.isna() | (as_str == "")
    not_number = numeric.isna() & ~blank
    if int(numeric.notna().sum()) > int(not_number.sum()):
        # Mostly numbers: the few text values are the mistakes, not the numbers.
        pos = int(np.flatnonzero(not_number.to_numpy())[0])
        raise _row_error(table, pos, col, f"not a time (seconds or ISO-8601): {series.iloc[pos]!r}")
    try:
        parsed = pd.to_datetime(
            as_str.where(~blank, None), utc=True, format="ISO8601", errors="coerce"
        )
    except (ValueError, TypeError):
        parsed = pd.Series(pd.NaT, index=series.index, dtype="datetime64[ns, UTC]")
    bad = parsed.isna() & ~blank
    if bool(bad.any()):
        pos = int(np.flatnonzero(bad.to_numpy())[0])
        raise _row_error(table, pos, col, f"not a time (seconds or ISO-8601): {series.iloc[pos]!r}")
    # ISO-8601 allows years far outside what nanosecond times (1677-2262) can hold.
    year = parsed.dt.year
    outside = ((year < 1678) | (year > 2261)).fillna(False).to_numpy(dtype=bool)
    if outside.any():
        pos = int(np.flatnonzero(outside)[0])
        raise _row_error(
            table, pos, col, f"time out of range (years 1678-2261): {series.iloc[pos]!r}"
        )
    return _datetime_seconds(parsed)


def _datetime_seconds(dt: pd.Series) -> np.ndarray:
    """Unix seconds of UTC datetimes, in their own unit: a Parquet or GPX time in year 1
    (a logger's placeholder) or 3000 does not fit nanoseconds, but is still a time."""
    naive = dt.dt.tz_convert("UTC").dt.tz_localize(None).to_numpy()
    unit, _ = np.datetime_data(naive.dtype)
    per_second = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9}.get(unit)
    if per_second is None:
        naive = naive.astype("datetime64[us]")
        per_second = 10**6
    out = naive.astype("int64").astype(np.float64) / per_second
    out[np.isnat(naive)] = np.nan
    return np.asarray(out, dtype=np.float64)


def _scale_epoch(t: np.ndarray) -> np.ndarray:
    """Treat epochs in milliseconds or microseconds as such (years 2001-2286 in any unit)."""
    finite = t[np.isfinite(t)]
    if finite.size == 0:
        return t
    mag = float(np.median(np.abs(finite)))
    if mag > 1e14:
        return t / 1e6
    if mag > 1e11:
        return t / 1e3
    return t


def to_fixes(
    table: Table | pd.DataFrame,
    columns: ColumnMap | None = None,
    *,
    channels: Iterable[str] = (),
) -> pd.DataFrame:
    """Convert a table to the canonical fixes frame (see the module docstring).

    ``columns`` overrides ``table.columns``; anything left ``None`` is
    auto-detected. ``channels`` names extra numeric sensor columns to carry
    along under their own names (``accel_x_g``, ``gyro_z_dps``...). The
    result's index is 0..n-1, the input row order.
    """
    if isinstance(table, pd.DataFrame):
        table = Table(frame=table)
    frame = table.frame
    base = table.columns.as_dict()
    if columns is not None:
        base.update({k: v for k, v in columns.as_dict().items() if v is not None})
    cmap = resolve_columns(frame.columns, ColumnMap(**base), source=table.source)
    n = len(frame)
    out: dict[str, object] = {}
    if cmap.track is not None:
        tr = frame[cmap.track]
        out["track"] = tr.astype("string").fillna("").astype(object).to_numpy()
    else:
        out["track"] = np.full(n, "0", dtype=object)
    # resolve_columns guarantees these three; the asserts narrow the types.
    assert cmap.time is not None
    assert cmap.lat is not None
    assert cmap.lon is not None
    out["t"] = _times(frame, cmap.time, table)
    out["lat"] = _numeric(frame, cmap.lat, table, what="latitude in degrees")
    out["lon"] = _numeric(frame, cmap.lon, table, what="longitude in degrees")
    for role in OPTIONAL_CHANNELS:
        col = getattr(cmap, role)
        if col is not None:
            values = _numeric(frame, col, table, what=role)
            if role == "heading":
                # An infinite heading has no direction: NaN, quietly (no RuntimeWarning).
                values = np.mod(np.where(np.isinf(values), np.nan, values), 360.0)
            out[role] = values
    for col in channels:
        if col not in frame.columns:
            raise InputError(
                f"no channel column named {col!r}",
                source=table.source,
                hint=f"available columns: {', '.join(map(str, frame.columns))}",
            )
        if col not in out:
            out[col] = _numeric(frame, col, table, what=f"channel {col}")
    fixes = pd.DataFrame(out, index=pd.RangeIndex(n))
    fixes.attrs["columns"] = cmap
    fixes.attrs["source"] = table.source
    return fixes


def with_columns(table: Table, columns: Mapping[str, str | None]) -> Table:
    """A copy of ``table`` whose column map has the given roles set."""
    return replace(table, columns=replace(table.columns, **columns))
