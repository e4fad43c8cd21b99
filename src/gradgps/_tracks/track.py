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
fix_quality float64    optional: the receiver's fix quality, GGA-style (0 = no
                       fix; RMC ``V``, GPX ``none`` read as 0; other words
                       see :data:`gradgps._result.FIX_QUALITY_WORDS`; NaN
                       where not reported or unreadable)
satellites float64     optional: satellites in use (NaN where not reported)
=========  ==========  ======================================================

A fix whose receiver reports no fix (``fix_quality`` 0 or 0 ``satellites``)
is invalid in every mode (:func:`gradgps._result.invalid_reasons`). Unlike
the other columns, an unreadable receiver field is *not reported* (NaN),
never an error: they are hints, never required.

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
from typing import Any, TypedDict

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .._result import fix_quality_code

__all__ = [
    "CANONICAL_COLUMNS",
    "OPTIONAL_CHANNELS",
    "RECEIVER_COLUMNS",
    "SPEED_UNITS",
    "ColumnKeywords",
    "ColumnMap",
    "GeoPoints",
    "ReadKeywords",
    "ReadOptions",
    "Table",
    "check_keywords",
    "datetime_seconds",
    "resolve_columns",
    "to_fixes",
    "track_rows",
    "units_per_degree",
]

OPTIONAL_CHANNELS = ("speed", "heading", "alt", "hdop")
#: What the receiver says about its own fix, read leniently (see the module docstring).
RECEIVER_COLUMNS = ("fix_quality", "satellites")
CANONICAL_COLUMNS = ("track", "t", "lat", "lon", *OPTIONAL_CHANNELS, *RECEIVER_COLUMNS)

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
        "timestampms",
        "timems",
        "tms",
        "epochms",
        "unixtimems",
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
        # degrees x 1e7 (Google location history, Android's latitudeE7)
        "latitudee7",
        "late7",
        "y",
        "northing",
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
        "longitudee7",
        "lnge7",
        "lone7",
        "x",
        "easting",
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
        # fleet exports name the vehicle by its device or asset
        "deviceid",
        "device",
        "imei",
        "unitid",
        "assetid",
        "carid",
        "taxiid",
        "busid",
        "userid",
        "objectid",
        "vin",
        "id",
    ),
    "speed": (
        "speed",
        "speedmps",
        "speedms",
        "velocity",
        "gpsspeed",
        "spd",
        "speedkmh",
        "speedkph",
        "speedmph",
        "speedknots",
        "speedkn",
        "speedkt",
    ),
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
    "fix_quality": (
        "fix_quality",
        "fixquality",
        "quality",
        "fix",
        "gpsquality",
        "gpsfix",
        "fixtype",
        "fix_type",
        "fixmode",
    ),
    "satellites": (
        "satellites",
        "sats",
        "num_sats",
        "numsats",
        "nsats",
        "numsat",
        "sat",
        "satellitesused",
        "satsused",
        "numsv",
    ),
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
    fix_quality: str | None = None
    satellites: str | None = None

    def as_dict(self) -> dict[str, str | None]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class ColumnKeywords(TypedDict, total=False):
    """:class:`ColumnMap` as keyword arguments (``time="ts"``; left out or ``None``: found by name).

    The column keywords of :func:`gradgps.detect`, :func:`gradgps.clean` and
    :class:`gradgps.Detector`'s ``detect``, ``clean`` and ``events``, spelled
    once here (``**columns: Unpack[ColumnKeywords]``) so those five signatures
    cannot drift apart.
    """

    time: str | None
    lat: str | None
    lon: str | None
    track: str | None
    speed: str | None
    heading: str | None
    alt: str | None
    hdop: str | None
    fix_quality: str | None
    satellites: str | None


def check_keywords(given: Mapping[str, Any], spec: Any) -> None:
    """A ``TypeError`` for a keyword of ``given`` that the TypedDict ``spec`` does not name.

    Python raised it when each signature spelled its keywords out; a
    ``**kwargs: Unpack[spec]`` signature is checked only by a type checker,
    so the functions that take one call this first, and a misspelt keyword
    fails as it always did.
    """
    for name in given:
        if name not in spec.__annotations__:
            raise TypeError(f"got an unexpected keyword argument {name!r}")


#: The units ``speed_unit`` (``--speed-unit``) names, and the factor of each to m/s.
SPEED_UNITS = {"m/s": 1.0, "km/h": 1 / 3.6, "mph": 0.44704, "knots": 0.514444}
#: pandas' own format keywords, which have no ``%`` directive yet are formats.
_PANDAS_FORMATS = ("ISO8601", "mixed")


@dataclass(frozen=True)
class ReadOptions:
    """How to read the values of a table, when guessing them is not good enough.

    ``None`` keeps the automatic behaviour: ``decimal`` sniffed per column
    (decimal commas read when a whole column uses them), times parsed as
    numbers, ISO-8601 or day-first dates, a leading row-count line skipped
    (``skip_rows``), speeds in m/s unless the column name says its unit
    (``speed_kmh``), coordinates in degrees WGS84 (``crs``: the CRS of the
    ``X``/``Y`` or longitude/latitude columns, e.g. ``"EPSG:25832"``,
    converted to WGS84 with pyproj, extra ``geo``). A value forces the
    choice, because a guess can be wrong for one file and there must be a
    way to say what the file holds.
    ``cli`` says whether errors name the CLI's flags (``--time-format``) or
    Python's keyword arguments (``time_format=``), so every message names
    what its reader can type.
    """

    decimal: str | None = None
    time_format: str | None = None
    skip_rows: int | None = None
    speed_unit: str | None = None
    crs: str | None = None
    cli: bool = False

    def name(self, option: str) -> str:
        """How the caller spells ``option``: ``--time-format`` or ``time_format=``."""
        return "--" + option.replace("_", "-") if self.cli else f"{option}="

    @property
    def given(self) -> list[str]:
        """The options set (not ``None``), by their Python names."""
        return [
            f.name for f in fields(self) if f.name != "cli" and getattr(self, f.name) is not None
        ]

    def checked(self) -> ReadOptions:
        """``self`` once every value is valid; else a :class:`ConfigError` naming the option."""
        if self.decimal is not None and self.decimal not in (".", ","):
            raise ConfigError(f"{self.name('decimal')} must be '.' or ',', got {self.decimal!r}")
        fmt = self.time_format
        if fmt is not None and (
            not isinstance(fmt, str) or ("%" not in fmt and fmt not in _PANDAS_FORMATS)
        ):
            raise ConfigError(
                f"{self.name('time_format')} {fmt!r} has no %-directive; give a strptime "
                "format such as '%d.%m.%Y %H:%M:%S'"
            )
        rows = self.skip_rows
        if rows is not None and (isinstance(rows, bool) or not isinstance(rows, int) or rows < 0):
            raise ConfigError(f"{self.name('skip_rows')} must be a whole number >= 0, got {rows!r}")
        if self.crs is not None and (not isinstance(self.crs, str) or not self.crs.strip()):
            raise ConfigError(
                f"{self.name('crs')} must name a coordinate reference system, e.g. "
                f"'EPSG:25832', got {self.crs!r}"
            )
        if self.speed_unit is not None and self.speed_unit not in SPEED_UNITS:
            raise ConfigError(
                f"{self.name('speed_unit')} must be one of {', '.join(SPEED_UNITS)}, "
                f"got {self.speed_unit!r}"
            )
        return self


class ReadKeywords(TypedDict, total=False):
    """:class:`ReadOptions` as keyword arguments (``None`` or left out: guessed).

    What :func:`gradgps.read_table`, :func:`gradgps.read_fixes` and
    :func:`gradgps.iter_csv_tables` take to say what guessing cannot, spelled
    once here (``**options: Unpack[ReadKeywords]``) so the three cannot drift
    apart; ``cli`` stays the CLI's own.
    """

    decimal: str | None
    time_format: str | None
    skip_rows: int | None
    speed_unit: str | None
    crs: str | None


@dataclass
class Table:
    """A table as read from a file, before conversion to canonical fixes.

    ``frame`` keeps every input column with its original name and order (the
    ``detect`` output keeps them all). ``first_line`` is the file line of data
    row 1 (2 for a CSV with a header) so errors can name lines; ``None`` where
    lines mean nothing (Parquet). ``row_offset`` is the number of input rows
    before this table when it is one chunk of a bigger file (streaming), so
    errors name rows of the file. ``rejected`` counts records a lenient reader
    skipped (bad NMEA checksums), with ``notes`` saying which. ``options``
    says how :func:`to_fixes` reads the values (decimal separator, time
    format, speed unit), as the caller of the reader asked. ``times``: the
    seconds of each row where the reader assembled them itself (NMEA: a time
    of day plus a date it may have carried; GPX), while the time column holds
    the input's own text (:mod:`gradgps._io.times`); :func:`to_fixes` uses
    them unless another time column is named.
    """

    frame: pd.DataFrame
    source: str = "<data>"
    columns: ColumnMap = ColumnMap()
    first_line: int | None = None
    rejected: int = 0
    notes: list[str] | None = None
    row_offset: int = 0
    options: ReadOptions = ReadOptions()
    times: np.ndarray | None = None
    #: The point geometry of a GeoParquet file (:mod:`gradgps._io.geoparquet`).
    geometry: GeoPoints | None = None


@dataclass(frozen=True)
class GeoPoints:
    """Points decoded from a geometry column: ``x``/``y`` in ``crs``, and how to write them back.

    ``crs``: PROJJSON (a dict) or text pyproj reads; ``None`` is longitude/latitude
    (GeoParquet's default, OGC:CRS84). ``metadata``: the file's ``geo`` metadata,
    written back unchanged with the geometry column, so the output stays GeoParquet.
    """

    column: str
    x: np.ndarray
    y: np.ndarray
    crs: object = None
    metadata: bytes = b""


_CLI_FLAGS = {"time": "--time-col", "lat": "--lat-col", "lon": "--lon-col"}


def resolve_columns(
    names: Iterable[str],
    overrides: ColumnMap | None = None,
    *,
    source: str = "<data>",
    arg_names: Mapping[str, str] | None = None,
) -> ColumnMap:
    """Auto-detect the role of each column, honouring explicit overrides.

    Raises :class:`InputError` when a named column does not exist or when time,
    latitude or longitude cannot be found, listing the available columns.
    ``arg_names`` says how the caller names the options in hints (the CLI's
    ``--time-col`` by default; ``time=`` from Python).
    """
    flags = _CLI_FLAGS if arg_names is None else arg_names
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
    for role in ("time", "lat", "lon"):
        flag = flags[role]
        if chosen[role] is None:
            raise InputError(
                f"cannot find the {role} column",
                source=source,
                hint=f"name it with {flag}; available columns: {', '.join(map(str, names))}",
            )
    return ColumnMap(**chosen)


#: A decimal comma (``48,1375``; semicolon CSVs from European locales).
_DECIMAL_COMMA = re.compile(r"^[+-]?\d*,\d+(?:[eE][+-]?\d+)?$")


def _decimal_commas(as_str: pd.Series, blank: pd.Series) -> pd.Series | None:
    """The column with decimal commas read as points, when every non-blank value has one or none."""
    text = as_str[~blank]
    if text.empty or not bool(text.str.contains(",", regex=False).any()):
        return None
    if not bool(
        text.str.match(_DECIMAL_COMMA).fillna(False).where(text.str.contains(","), True).all()
    ):
        return None
    return as_str.str.replace(",", ".", regex=False)


#: Speed column name endings that say their unit (``speed_kmh``), and that unit.
_SPEED_UNIT_OF_SUFFIX = {
    suffix: unit
    for unit, suffixes in (
        ("km/h", ("kmh", "kph")),
        ("mph", ("mph",)),
        ("knots", ("knots", "kn", "kt")),
    )
    for suffix in suffixes
}


def canonical_heading(values: np.ndarray) -> np.ndarray:
    """Headings in degrees as the fixes frame holds them: modulo 360, an infinite one NaN
    (it has no direction), quietly (no RuntimeWarning)."""
    out: np.ndarray = np.mod(np.where(np.isinf(values), np.nan, values), 360.0)
    return out


def units_per_degree(name: str | None) -> float:
    """Units per degree of a latitude or longitude column, as its name says: ``1e7`` for
    degrees x 1e7 (``latitudeE7``, Google location history's integers), else (``None``
    too) 1."""
    norm = _norm(name or "")
    return 1e7 if norm.endswith("e7") and norm != "e7" else 1.0


def speed_unit_named(name: str) -> str:
    """The unit (a key of :data:`SPEED_UNITS`) a speed column's name says (``speed_kmh``);
    ``"m/s"`` if none."""
    norm = _norm(name)
    for suffix, unit in _SPEED_UNIT_OF_SUFFIX.items():
        if norm.endswith(suffix) and norm != suffix:
            return unit
    return "m/s"


def _numeric(frame: pd.DataFrame, col: str, table: Table, *, what: str) -> np.ndarray:
    """Column as float64; text that is not a number raises naming the first bad row.

    Decimal commas (``48,1375``) are read as decimal points when the whole
    column uses them, or always with ``decimal=","``; ``decimal="."`` turns
    that guess off, so a comma is an error, not a silently different number."""
    series = frame[col]
    if pd.api.types.is_bool_dtype(series.dtype):
        raise InputError(f"expected {what}, found booleans", source=table.source, column=col)
    if pd.api.types.is_numeric_dtype(series.dtype):
        return np.asarray(series.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)
    decimal = table.options.decimal
    as_str = series.astype("string").str.strip()
    blank = series.isna() | (as_str == "") | as_str.str.lower().isin(["nan", "na", "null", "none"])
    text = as_str.str.replace(",", ".", regex=False) if decimal == "," else as_str
    values = pd.to_numeric(text.where(~blank, None), errors="coerce")
    bad = values.isna() & ~blank
    if bool(bad.any()) and decimal is None:
        dotted = _decimal_commas(as_str, blank)
        if dotted is not None:
            values = pd.to_numeric(dotted.where(~blank, None), errors="coerce")
            bad = values.isna() & ~blank
    if bool(bad.any()):
        pos = int(np.flatnonzero(bad.to_numpy())[0])
        value = series.iloc[pos]
        hint = None
        if decimal != "," and "," in str(value):
            # The column mixes decimal commas with other text: say how to force them.
            hint = f"fix the value, or pass {table.options.name('decimal')} ',' for decimal commas"
        raise _row_error(table, pos, col, f"not a number ({what}): {value!r}", hint=hint)
    return np.asarray(values.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)


def _row_error(
    table: Table, pos: int, col: str, reason: str, *, hint: str | None = None
) -> InputError:
    line = None if table.first_line is None else table.first_line + pos
    return InputError(
        reason,
        source=table.source,
        row=table.row_offset + pos + 1,
        line=line,
        column=col,
        hint=hint or "fix the value or choose another column",
    )


def _times(frame: pd.DataFrame, col: str, table: Table) -> np.ndarray:
    """Seconds as float64: numbers as they are (ms or us epochs scaled), datetimes/ISO strings to unix."""
    series = frame[col]
    if pd.api.types.is_datetime64_any_dtype(series.dtype):
        dt = pd.to_datetime(series, utc=True)
        return datetime_seconds(dt)
    if table.options.time_format is not None:
        return _formatted_times(series, col, table, table.options.time_format)
    in_ms = _norm(col).endswith("ms") and _norm(col) not in ("times", "timestamps")
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        t = np.asarray(series.to_numpy(dtype=np.float64, na_value=np.nan), dtype=np.float64)
        return t / 1e3 if in_ms else _scale_epoch(t)
    as_str = series.astype("string").str.strip()
    # Seconds written with a decimal comma (0,5) only when asked: dates may hold commas.
    numbers = as_str.str.replace(",", ".", regex=False) if table.options.decimal == "," else as_str
    numeric = pd.to_numeric(numbers, errors="coerce")
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
    of_day = _times_of_day(as_str.where(~blank, None))
    if of_day is not None:
        return of_day
    try:
        parsed = pd.to_datetime(
            as_str.where(~blank, None), utc=True, format="ISO8601", errors="coerce"
        )
    except (ValueError, TypeError):
        parsed = pd.Series(pd.NaT, index=series.index, dtype="datetime64[ns, UTC]")
    bad = parsed.isna() & ~blank
    if bool(bad.any()):
        parsed = _day_first(as_str.where(~blank, None), parsed)
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
    return datetime_seconds(parsed)


#: A time of day lower than the previous one by more than this (12 h) is the next day's.
ROLLOVER_S = 43200.0


def rolled_over(previous: Any, tod: Any) -> Any:
    """Whether time of day ``tod`` follows ``previous`` across a midnight (it falls by more
    than :data:`ROLLOVER_S`): the one rule of a log without dates, for the NMEA reader,
    ``--follow`` and NMEA times read back. NaN never rolls over. Scalars or arrays."""
    return tod < previous - ROLLOVER_S


def day_rollovers(tod: np.ndarray) -> np.ndarray:
    """Per time of day, the midnights passed since the first (:func:`rolled_over` from the
    previous one that is not NaN); 0 where ``tod`` is NaN."""
    out = np.zeros(tod.size, dtype=np.int64)
    present = np.flatnonzero(~np.isnan(tod))
    values = tod[present]
    out[present[1:]] = np.cumsum(rolled_over(values[:-1], values[1:]))
    return out


#: A time of day without a date, in the ISO-8601 form NMEA logs without a date are written in.
_UTC_TIME_OF_DAY = re.compile(r"^(\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)Z$")


def _times_of_day(text: pd.Series) -> np.ndarray | None:
    """Times of day (``10:00:05.200Z``) as seconds since the first one's midnight, else None.

    What an NMEA log without a date is written as (:mod:`gradgps._io.times`),
    read back the way the NMEA reader counts: a time of day falling by more
    than 12 hours is the next day, so a drive across midnight stays ordered.
    """
    present = text.dropna()
    if present.empty:
        return None
    parts = present.str.extract(_UTC_TIME_OF_DAY)
    if bool(parts.isna().any().any()):
        return None
    seconds = np.full(len(text), np.nan)
    values = (
        parts[0].astype(float) * 3600.0 + parts[1].astype(float) * 60.0 + parts[2].astype(float)
    ).to_numpy()
    seconds[np.flatnonzero(text.notna().to_numpy())] = values + day_rollovers(values) * 86400.0
    return seconds


def _formatted_times(series: pd.Series, col: str, table: Table, fmt: str) -> np.ndarray:
    """Times parsed with the caller's ``time_format`` only: no guessing, so no silent misreads.

    Whole numbers (``20261123100000`` typed as a number by the CSV reader)
    are formatted as the digits they were written with.
    """
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        whole = series.dropna()
        if bool((whole == whole.round()).all()):
            series = series.astype("Int64")
    as_str = series.astype("string").str.strip()
    blank = series.isna() | (as_str == "")
    option = f"{table.options.name('time_format')} {fmt!r}"
    try:
        parsed = pd.to_datetime(as_str.where(~blank, None), utc=True, format=fmt, errors="coerce")
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{option} is not a time format pandas can use: {exc}") from None
    bad = parsed.isna() & ~blank
    if bool(bad.any()):
        pos = int(np.flatnonzero(bad.to_numpy())[0])
        raise _row_error(
            table,
            pos,
            col,
            f"time {series.iloc[pos]!r} does not match {option}",
            hint="fix the value, or give the format the times are written in",
        )
    return datetime_seconds(parsed)


#: Day-first dates (``23.11.2026 10:00:05``, ``23/11/2026``), read when ISO-8601 does not fit.
_DAY_FIRST = re.compile(r"^\d{1,2}[./-]\d{1,2}[./-]\d{4}")


def _day_first(text: pd.Series, iso: pd.Series) -> pd.Series:
    """Times written day first, as most of the world writes them; ``iso`` where that fails."""
    present = text.dropna()
    if present.empty or not bool(present.str.match(_DAY_FIRST).all()):
        return iso
    try:
        parsed = pd.to_datetime(text, utc=True, dayfirst=True, format="mixed", errors="coerce")
    except (ValueError, TypeError):
        return iso
    return parsed if int(parsed.notna().sum()) >= int(iso.notna().sum()) else iso


def datetime_seconds(dt: pd.Series) -> np.ndarray:
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
    arg_names: Mapping[str, str] | None = None,
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
    cmap = resolve_columns(
        frame.columns, ColumnMap(**base), source=table.source, arg_names=arg_names
    )
    n = len(frame)
    out: dict[str, object] = {}
    # What the reading assumed beyond the column map (``speed_unit``: the unit a speed
    # column was read in), for the input checks' messages.
    attrs: dict[str, str] = {}
    if cmap.track is not None:
        tr = frame[cmap.track]
        out["track"] = tr.astype("string").fillna("").astype(object).to_numpy()
    else:
        out["track"] = np.full(n, "0", dtype=object)
    # resolve_columns guarantees these three; the asserts narrow the types.
    assert cmap.time is not None
    assert cmap.lat is not None
    assert cmap.lon is not None
    date_col = _date_partner(frame, cmap.time)
    if table.times is not None and cmap.time == table.columns.time:
        out["t"] = np.asarray(table.times, dtype=np.float64)
    elif date_col is not None:
        joined = (
            frame[date_col].astype("string").str.strip()
            + " "
            + frame[cmap.time].astype("string").str.strip()
        )
        out["t"] = _times(pd.DataFrame({cmap.time: joined}), cmap.time, table)
    else:
        out["t"] = _times(frame, cmap.time, table)
    notes: list[str] = []
    geo = table.geometry
    if geo is not None and cmap.lat == geo.column and cmap.lon == geo.column:
        crs = table.options.crs if table.options.crs is not None else geo.crs
        if crs is None or _is_lon_lat(crs):
            out["lon"], out["lat"] = geo.x, geo.y
            _check_degrees(geo.y, geo.x, cmap, table)
        else:
            out["lon"], out["lat"] = _to_wgs84(geo.x, geo.y, crs, table.options)
    elif table.options.crs is not None:
        x = _numeric(frame, cmap.lon, table, what=f"x coordinate in {table.options.crs}")
        y = _numeric(frame, cmap.lat, table, what=f"y coordinate in {table.options.crs}")
        out["lon"], out["lat"] = _to_wgs84(x, y, table.options.crs, table.options)
    else:
        # A column named latitudeE7 holds degrees x 1e7, as a speed_kmh holds km/h.
        lat = _numeric(frame, cmap.lat, table, what="latitude in degrees")
        lon = _numeric(frame, cmap.lon, table, what="longitude in degrees")
        out["lat"] = lat / units_per_degree(cmap.lat)
        out["lon"] = lon / units_per_degree(cmap.lon)
        if _norm(cmap.lat) in _XY_NAMES or _norm(cmap.lon) in _XY_NAMES:
            _check_degrees(out["lat"], out["lon"], cmap, table)
            notes.append(
                f"columns {cmap.lon!r}/{cmap.lat!r} taken as longitude/latitude in degrees "
                f"(WGS84); if they are projected coordinates, pass {_crs_flag(table.options)}"
            )
    for role in OPTIONAL_CHANNELS:
        col = getattr(cmap, role)
        if col is not None:
            values = _numeric(frame, col, table, what=role)
            if role == "heading":
                values = canonical_heading(values)
            if role == "speed":
                # The unit the caller names wins over the one the column name says (speed_kmh).
                unit = table.options.speed_unit
                speed_unit = speed_unit_named(col) if unit is None else unit
                values = values * SPEED_UNITS[speed_unit]
                attrs["speed_unit"] = speed_unit
            out[role] = values
    if cmap.fix_quality is not None:
        out["fix_quality"] = _fix_qualities(frame[cmap.fix_quality])
    if cmap.satellites is not None:
        out["satellites"] = pd.to_numeric(frame[cmap.satellites], errors="coerce").to_numpy(
            dtype=np.float64, na_value=np.nan
        )
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
    fixes.attrs.update(attrs)
    if notes:
        fixes.attrs["notes"] = notes
    return fixes


_TIME_OF_DAY = re.compile(r"^\d{1,2}:\d{2}(:\d{2}(\.\d+)?)?$")


def _fix_qualities(series: pd.Series) -> np.ndarray:
    """A fix-quality column as GGA-style numbers (:func:`gradgps._result.fix_quality_code`)."""
    if pd.api.types.is_numeric_dtype(series.dtype) and not pd.api.types.is_bool_dtype(series.dtype):
        values = series.to_numpy(dtype=np.float64, na_value=np.nan)
        return np.where(np.isfinite(values), values, np.nan)
    codes = {v: fix_quality_code(v) for v in series.dropna().unique()}
    return np.array([codes.get(v, np.nan) for v in series.tolist()], dtype=np.float64)


def _date_partner(frame: pd.DataFrame, time_col: str) -> str | None:
    """A ``date`` column to join with ``time_col`` when that holds only times of day."""
    series = frame[time_col]
    if pd.api.types.is_numeric_dtype(series.dtype) or pd.api.types.is_datetime64_any_dtype(
        series.dtype
    ):
        return None
    text = series.dropna().astype("string").str.strip()
    if text.empty or not bool(text.head(50).str.match(_TIME_OF_DAY).all()):
        return None
    for name in frame.columns:
        if _norm(str(name)) in ("date", "gpsdate", "utcdate", "day") and name != time_col:
            return str(name)
    return None


#: Column names that say "x/y coordinates", which may or may not be degrees.
_XY_NAMES = ("x", "y", "easting", "northing")


def _crs_flag(options: ReadOptions) -> str:
    return "--crs EPSG:xxxx" if options.cli else "crs='EPSG:xxxx' to the reader"


def _check_degrees(lat: object, lon: object, cmap: ColumnMap, table: Table) -> None:
    """``X``/``Y`` columns are taken as longitude/latitude only when they hold degrees."""
    lat_a = np.asarray(lat, dtype=np.float64)
    lon_a = np.asarray(lon, dtype=np.float64)
    for values, col, limit in ((lon_a, cmap.lon, 180.0), (lat_a, cmap.lat, 90.0)):
        outside = np.flatnonzero(np.isfinite(values) & (np.abs(values) > limit))
        if outside.size:
            assert col is not None
            raise _row_error(
                table,
                int(outside[0]),
                col,
                f"column {col!r} holds projected coordinates ({values[outside[0]]:g}), not degrees",
                hint=f"say which coordinate reference system they are in: pass "
                f"{_crs_flag(table.options)} (e.g. EPSG:25832 for UTM zone 32N); "
                "in Python a GeoDataFrame with its CRS works too",
            )


def _is_lon_lat(crs: object) -> bool:
    """PROJJSON or text naming WGS84 longitude/latitude (no conversion needed)."""
    if isinstance(crs, dict):
        ident = crs.get("id") or {}
        return isinstance(ident, dict) and (
            (ident.get("authority"), str(ident.get("code"))) in (("OGC", "CRS84"), ("EPSG", "4326"))
        )
    return str(crs).strip().upper() in ("OGC:CRS84", "EPSG:4326", "CRS84")


def _to_wgs84(
    x: np.ndarray, y: np.ndarray, crs: object, options: ReadOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates in ``crs`` as WGS84 longitude/latitude (pyproj, extra ``geo``)."""
    flag = options.name("crs") if options.crs is not None else "the file's CRS"
    try:
        from pyproj import CRS, Transformer
        from pyproj.exceptions import CRSError
    except ImportError:
        raise ConfigError(
            f"converting coordinates from {flag} needs pyproj: pip install 'gradgps[geo]'"
            if options.crs is None
            else f"{flag} needs pyproj: pip install 'gradgps[geo]'"
        ) from None
    try:
        source = CRS.from_json_dict(crs) if isinstance(crs, dict) else CRS.from_user_input(crs)
    except CRSError as exc:
        shown = "" if isinstance(crs, dict) else f" {crs!r}"
        raise ConfigError(f"{flag}{shown} is not a coordinate reference system: {exc}") from None
    transformer = Transformer.from_crs(source, "EPSG:4326", always_xy=True)
    lon, lat = transformer.transform(x, y)
    lon = np.asarray(lon, dtype=np.float64)
    lat = np.asarray(lat, dtype=np.float64)
    lost = ~(np.isfinite(lon) & np.isfinite(lat))
    lon[lost] = np.nan
    lat[lost] = np.nan
    return lon, lat


def with_columns(table: Table, columns: Mapping[str, str | None]) -> Table:
    """A copy of ``table`` whose column map has the given roles set."""
    return replace(table, columns=replace(table.columns, **columns))


def track_rows(fixes: pd.DataFrame, usable: np.ndarray | None = None) -> list[np.ndarray]:
    """Row positions of each track's (``usable``) fixes in time order; tracks in order of appearance.

    The one place where canonical fixes are split by track: ties in time keep
    their input order (a stable sort).
    """
    rows = np.arange(len(fixes)) if usable is None else np.flatnonzero(usable)
    if rows.size == 0:
        return []
    tracks = fixes["track"].to_numpy(dtype=object)[rows]
    t = fixes["t"].to_numpy(dtype=np.float64)[rows]
    codes = pd.factorize(pd.Series(tracks, dtype=object), sort=False)[0]
    order = np.lexsort((t, codes))
    cuts = np.flatnonzero(np.diff(codes[order])) + 1
    return np.split(rows[order], cuts)
