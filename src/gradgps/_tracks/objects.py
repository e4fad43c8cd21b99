"""What a Python user hands to ``detect``/``clean``, and how the answer goes back in the same type.

Accepted: a pandas DataFrame (columns found by name, or named by keyword:
``time="ts"``; a ``DatetimeIndex`` is the time when no column is), a
GeoPandas GeoDataFrame (point geometry in any CRS, converted to WGS84 for
detection; the caller's geometry and CRS are kept), a movingpandas
``Trajectory`` or ``TrajectoryCollection`` (extra ``geo``). The user's object
is never modified: answers are new objects of the same type.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .track import _ALIASES, ColumnMap, Table, _norm, to_fixes, units_per_degree

__all__ = ["PYTHON_ARGS", "TrackInput", "as_track_input"]

#: How Python errors name the column options (the CLI names its flags instead).
PYTHON_ARGS = {"time": "time=", "lat": "lat=", "lon": "lon="}
_INDEX_TIME = "__gradgps_index_time__"
_GEO_LAT = "__gradgps_lat__"
_GEO_LON = "__gradgps_lon__"


@dataclass
class TrackInput:
    """The user's object, its canonical fixes (index 0..n-1) and how to rebuild its type."""

    kind: str  # "frame", "geoframe", "trajectory", "collection"
    original: Any
    flat: pd.DataFrame  # one row per fix, the caller's index, the caller's columns (geometry kept)
    fixes: pd.DataFrame
    columns: ColumnMap

    @property
    def index(self) -> pd.Index:
        return self.flat.index

    def rebuild(self, frame: pd.DataFrame) -> Any:
        """``frame`` (same rows as :attr:`flat`, any columns) as the caller's type."""
        if self.kind in ("frame", "geoframe"):
            return frame
        if self.kind == "trajectory":
            return _trajectory_like(self.original, frame)
        import movingpandas as mpd

        parts = []
        start = 0
        for traj in self.original.trajectories:
            n = len(traj.df)
            parts.append(_trajectory_like(traj, frame.iloc[start : start + n]))
            start += n
        return mpd.TrajectoryCollection(parts)


def _trajectory_like(traj: Any, frame: pd.DataFrame) -> Any:
    new = traj.copy()
    new.df = frame
    return new


def _geo_kind(obj: Any) -> str | None:
    module = type(obj).__module__
    name = type(obj).__name__
    if module.startswith("movingpandas"):
        if name == "Trajectory":
            return "trajectory"
        if name == "TrajectoryCollection":
            return "collection"
    if module.startswith("geopandas") and name == "GeoDataFrame":
        return "geoframe"
    return None


def _with_lat_lon(gdf: Any) -> pd.DataFrame:
    """A plain copy of a point GeoDataFrame with WGS84 latitude/longitude columns added."""
    geom = gdf.geometry
    if gdf.crs is not None and not gdf.crs.equals("EPSG:4326"):
        geom = geom.to_crs("EPSG:4326")
    kinds = set(geom.geom_type.dropna().unique())
    if kinds - {"Point"}:
        raise InputError(
            f"the geometry holds {sorted(kinds - {'Point'})}, not points",
            hint="one row per fix with a Point geometry (explode lines into points first)",
        )
    missing = geom.isna() | geom.is_empty
    x = np.full(len(gdf), np.nan)
    y = np.full(len(gdf), np.nan)
    keep = ~missing.to_numpy()
    x[keep] = geom[keep].x.to_numpy(np.float64)
    y[keep] = geom[keep].y.to_numpy(np.float64)
    if gdf.crs is None and keep.any() and (np.nanmax(np.abs(y)) > 90 or np.nanmax(np.abs(x)) > 180):
        raise InputError(
            "the GeoDataFrame has no CRS and its coordinates are not degrees",
            hint="set one first: gdf.set_crs('EPSG:xxxx')",
        )
    flat = pd.DataFrame(gdf.drop(columns=gdf.geometry.name)).copy()
    flat[_GEO_LAT] = y
    flat[_GEO_LON] = x
    return flat


def _has_time_column(frame: pd.DataFrame) -> bool:
    names = {_norm(str(c)) for c in frame.columns}
    return any(_norm(a) in names for a in _ALIASES["time"])


def as_track_input(data: Any, columns: Mapping[str, str | None] | None = None) -> TrackInput:
    """Convert what a Python user passed; ``columns`` maps roles (``time``, ``lat``...) to names."""
    given = {k: v for k, v in (columns or {}).items() if v is not None}
    unknown = sorted(set(given) - set(ColumnMap().as_dict()))
    if unknown:
        raise ConfigError(
            f"unknown column argument(s) {unknown}; use time=, lat=, lon=, track=, "
            "speed=, heading=, alt=, hdop=, fix_quality=, satellites="
        )
    kind = _geo_kind(data)
    if kind is None and not isinstance(data, pd.DataFrame):
        raise ConfigError(
            f"cannot detect faults in a {type(data).__name__}: pass a pandas DataFrame, a "
            "GeoPandas GeoDataFrame or a movingpandas Trajectory/TrajectoryCollection"
        )
    if kind in ("trajectory", "collection"):
        trajs = [data] if kind == "trajectory" else list(data.trajectories)
        pieces = []
        for traj in trajs:
            piece = _with_lat_lon(traj.df)
            piece["__gradgps_track__"] = str(traj.id)
            pieces.append(piece)
        flat_geo = pd.concat(pieces) if pieces else pd.DataFrame()
        originals = pd.concat([t.df for t in trajs]) if trajs else pd.DataFrame()
        given.setdefault("track", "__gradgps_track__")
        given.setdefault("lat", _GEO_LAT)
        given.setdefault("lon", _GEO_LON)
        flat = originals
        work = flat_geo
    elif kind == "geoframe":
        work = _with_lat_lon(data)
        given.setdefault("lat", _GEO_LAT)
        given.setdefault("lon", _GEO_LON)
        flat = data
    else:
        assert isinstance(data, pd.DataFrame)
        work = flat = data
    if (
        "time" not in given
        and isinstance(work.index, pd.DatetimeIndex)
        and not _has_time_column(work)
    ):
        work = work.copy()
        work[_INDEX_TIME] = work.index
        given["time"] = _INDEX_TIME
    work = work.reset_index(drop=True)
    table = Table(frame=work, source="<data>")
    fixes = to_fixes(table, ColumnMap(**given), arg_names=PYTHON_ARGS)
    return TrackInput(
        kind=kind or "frame", original=data, flat=flat, fixes=fixes, columns=fixes.attrs["columns"]
    )


def add_columns(inp: TrackInput, result: pd.DataFrame) -> Any:
    """The caller's object with the result columns added (same type, same index)."""
    clash = [c for c in result.columns if c in inp.flat.columns]
    if clash:
        raise InputError(
            f"the data already has columns {clash}",
            hint="rename or drop them first: the result adds columns of those names",
        )
    frame = inp.flat.copy()
    for name in result.columns:
        frame[name] = result[name].to_numpy()
    return inp.rebuild(frame)


def replace_positions(inp: TrackInput, lat: np.ndarray, lon: np.ndarray, keep: np.ndarray) -> Any:
    """The caller's object with positions replaced (rows where ``keep`` is False dropped)."""
    frame: Any = inp.flat.copy()
    if inp.kind == "frame":
        cols = inp.columns
        assert cols.lat is not None
        assert cols.lon is not None
        frame[cols.lat] = lat * units_per_degree(cols.lat)  # the column's own unit
        frame[cols.lon] = lon * units_per_degree(cols.lon)
    else:
        import geopandas as gpd

        points = gpd.GeoSeries(gpd.points_from_xy(lon, lat), index=frame.index, crs="EPSG:4326")
        crs = frame.crs
        frame = frame.set_geometry(points.to_crs(crs) if crs is not None else points.values)
        if crs is None:
            frame = frame.set_crs(None, allow_override=True)
    return inp.rebuild(frame[keep])


def time_values(inp: TrackInput) -> Callable[[np.ndarray], Any]:
    """Seconds -> times in the input's own form (Timestamps for datetime input, else floats)."""
    col = inp.columns.time
    series = None
    if col == _INDEX_TIME:
        return _to_timestamps
    source = inp.flat
    if col is not None and col in source.columns:
        series = source[col]
    if series is not None and (
        pd.api.types.is_datetime64_any_dtype(series.dtype)
        or (series.dtype == object and _looks_iso(series))
    ):
        return _to_timestamps
    return lambda s: s


def _looks_iso(series: pd.Series) -> bool:
    first = series.dropna()
    return bool(len(first)) and isinstance(first.iloc[0], str) and "-" in first.iloc[0]


def _to_timestamps(seconds: np.ndarray) -> Any:
    return pd.to_datetime(np.asarray(seconds, dtype=np.float64), unit="s", utc=True)
