"""GeoParquet: point geometry (WKB) with ``geo`` metadata, read and written back.

A Parquet file whose schema metadata has a ``geo`` key (GeoParquet 1.x) is
read with its primary geometry column decoded here from WKB (2D, Z, M, ZM
points; ISO and EWKB flavours), with plain pyarrow: no GeoPandas needed.
The column's ``crs`` (PROJJSON; absent means OGC:CRS84 longitude/latitude)
says how to get degrees: anything else is converted with pyproj (extra
``geo``), as ``--crs`` would. Every column, the geometry included, is kept
as read, so ``-o out.parquet`` writes the geometry back as WKB with the
same ``geo`` metadata (:func:`write_geoparquet`): a GeoParquet stays one.
A CSV output gets the geometry as WKT (``POINT (x y)``).

Null or empty points are missing positions (invalid fixes, rows kept);
anything but a point is an error naming the row, since a track is points.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .._tracks.track import ColumnMap, GeoPoints, Table

__all__ = ["geo_metadata", "primary_column", "read_geoparquet", "wkt_points", "write_geoparquet"]

_TYPES = {1: "Point", 2: "LineString", 3: "Polygon", 4: "MultiPoint", 5: "MultiLineString"}


def geo_metadata(path: Path) -> bytes | None:
    """The ``geo`` metadata of a Parquet file, or None (not GeoParquet, or unreadable)."""
    try:
        import pyarrow.parquet as pq
    except ImportError:
        return None
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, ValueError):
        return None
    value = meta.get(b"geo")
    return bytes(value) if value is not None else None


def primary_column(metadata: bytes) -> str | None:
    """The name of the primary geometry column in ``geo`` metadata; None when damaged (then
    :func:`read_geoparquet` says so)."""
    try:
        return str(json.loads(metadata)["primary_column"])
    except (ValueError, KeyError, TypeError):
        return None


def read_geoparquet(path: Path, frame: pd.DataFrame, metadata: bytes, row_offset: int = 0) -> Table:
    """A Table of ``frame`` (the file as pandas read it, or the chunk of it that starts after
    ``row_offset`` rows) with its point geometry decoded."""
    source = str(path)
    try:
        geo = json.loads(metadata)
        column = str(geo["primary_column"])
        spec = geo["columns"][column]
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(
            f"damaged GeoParquet 'geo' metadata ({type(exc).__name__}: {exc})",
            source=source,
            hint="write the file again with GeoPandas or GDAL",
        ) from None
    encoding = str(spec.get("encoding", "WKB")).upper()
    if encoding != "WKB":
        raise InputError(
            f"GeoParquet geometry encoding {encoding!r} is not read; only WKB",
            source=source,
            column=column,
            hint="write the file with WKB geometry (GeoPandas' default)",
        )
    if column not in frame.columns:
        raise InputError(f"the geometry column {column!r} is missing", source=source)
    x, y = _points(frame[column], source, column, row_offset)
    crs = spec.get("crs", "OGC:CRS84")
    points = GeoPoints(column=column, x=x, y=y, crs=crs, metadata=metadata)
    return Table(
        frame=frame,
        source=source,
        columns=ColumnMap(lat=column, lon=column),
        geometry=points,
        row_offset=row_offset,
    )


def _points(
    values: pd.Series, source: str, column: str, row_offset: int
) -> tuple[np.ndarray, np.ndarray]:
    """Each row's point (NaN where the geometry is null), decoded from the WKB of ``values``
    (Python ``bytes`` as pandas reads a file whole, or Arrow binary as a chunk holds it):
    vectorised (:func:`_points_at_once`), else row by row, so that a value that is not a
    point is an error naming its row."""
    found = _points_at_once(values)
    if found is not None:
        return found
    n = len(values)
    x = np.full(n, np.nan)
    y = np.full(n, np.nan)
    for i, blob in enumerate(values.tolist()):
        if not isinstance(blob, bytes | bytearray | memoryview) and pd.isna(blob):
            continue
        try:
            x[i], y[i] = _wkb_point(bytes(blob))
        except (struct.error, ValueError, TypeError) as exc:
            raise InputError(
                f"geometry is not a WKB point: {exc}",
                source=source,
                row=row_offset + i + 1,
                column=column,
                hint="gradgps reads tracks of points; convert lines to their vertices first",
            ) from None
    return x, y


def _points_at_once(values: pd.Series) -> tuple[np.ndarray, np.ndarray] | None:
    """The points of a column whose every value is null or a WKB point (2D, Z, M or ZM; ISO
    or EWKB; either byte order), decoded with NumPy from the column's one Arrow buffer, as
    :func:`_wkb_point` decodes one value; ``None`` for anything else (the caller's row by row
    reading then names the bad row). Issue 18: the row-by-row reading made a Python ``bytes``
    and two floats per fix, and a GeoParquet read in chunks was the one format whose
    Python allocator kept growing with the file (docs/reliability.md, "Round three")."""
    try:
        import pyarrow as pa
    except ImportError:
        return None
    try:
        array = pa.array(values, type=pa.binary(), from_pandas=True)
    except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError, TypeError):
        return None
    n = len(array)
    _, offsets_buffer, data_buffer = array.buffers()
    if offsets_buffer is None:
        return None
    offsets = np.frombuffer(offsets_buffer, np.int32)[array.offset : array.offset + n + 1]
    data = (
        np.frombuffer(data_buffer, np.uint8) if data_buffer is not None else np.zeros(0, np.uint8)
    )
    valid = array.is_valid().to_numpy(zero_copy_only=False)
    start = offsets[:-1].astype(np.int64)[valid]
    length = np.diff(offsets).astype(np.int64)[valid]
    if (length < 21).any():  # shorter than a 2D point: empty, or not a point
        return None
    order = data[start]
    if ((order != 0) & (order != 1)).any():
        return None
    little = order == 1

    def numbers(at: np.ndarray, size: int, dtype: str) -> np.ndarray:
        """The ``size``-byte number at ``at`` of each row, in the row's byte order (gathered a
        byte at a time: a row's bytes, not an index matrix, are the memory it takes)."""
        raw = np.empty((len(at), size), np.uint8)
        for k in range(size):
            raw[:, k] = data[at + k]
        raw[~little] = raw[~little, ::-1]
        return raw.view(dtype)[:, 0]

    kind = numbers(start + 1, 4, "<u4")
    at = start + 5 + np.where(kind & 0x20000000, 4, 0)  # EWKB with an SRID
    if ((kind & 0x0FFFFFFF) % 1000 != 1).any() or (at + 16 > start + length).any():
        return None
    x = np.full(n, np.nan)
    y = np.full(n, np.nan)
    x[valid] = numbers(at, 8, "<f8")
    y[valid] = numbers(at + 8, 8, "<f8")
    return x, y


def _wkb_point(blob: bytes) -> tuple[float, float]:
    if not blob:
        raise ValueError("empty value")
    order = "<" if blob[0] == 1 else ">" if blob[0] == 0 else None
    if order is None:
        raise ValueError(f"byte-order mark {blob[0]} is neither 0 nor 1")
    (kind,) = struct.unpack_from(order + "I", blob, 1)
    offset = 5 + (4 if kind & 0x20000000 else 0)  # EWKB with an SRID
    base = (kind & 0x0FFFFFFF) % 1000
    if base != 1:
        raise ValueError(f"a {_TYPES.get(base, f'type {base}')}, not a Point")
    px, py = struct.unpack_from(order + "dd", blob, offset)
    return float(px), float(py)


def wkt_points(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``POINT (x y)`` per row (``POINT EMPTY`` where missing), for a CSV output."""
    return np.asarray(
        [
            f"POINT ({a!r} {b!r})" if math.isfinite(a) and math.isfinite(b) else "POINT EMPTY"
            for a, b in zip(x.tolist(), y.tolist(), strict=True)
        ],
        dtype=object,
    )


def write_geoparquet(frame: pd.DataFrame, path: Path, points: GeoPoints) -> None:
    """``frame`` as Parquet with the input's ``geo`` metadata: the geometry column stays WKB."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise ConfigError(f"writing Parquet needs pyarrow ({exc}); install gradgps[io]") from None
    table: Any = pa.Table.from_pandas(frame, preserve_index=False)
    metadata = dict(table.schema.metadata or {})
    metadata[b"geo"] = points.metadata
    pq.write_table(table.replace_schema_metadata(metadata), path)
