"""GeoJSON track files: Point features with a time property, or LineStrings with per-vertex times.

What QGIS, geojson.io, ogr2ogr and many loggers write: a FeatureCollection
(or a single Feature) in WGS84 longitude/latitude. Every Point feature is one
fix, its properties become columns; a LineString or MultiLineString is a
track whose vertices are fixes, with times from a per-vertex array property
(``coordTimes``, ``times``, ``timestamps``, as togeojson writes from GPX) and
the feature's index as its track id. A third coordinate is the altitude.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

from .._exceptions import InputError
from .._tracks.track import ColumnMap, Table
from .files import READ_ERRORS, open_bytes

__all__ = ["read_geojson"]

_TIME_ARRAYS = ("coordTimes", "coordinateTimes", "times", "timestamps", "time")


def read_geojson(path: str | Path) -> Table:
    """Read a GeoJSON file into a :class:`Table` (see the module docstring)."""
    source = str(path)
    try:
        with open_bytes(Path(path)) as raw:
            doc = json.loads(raw.read().decode("utf-8-sig"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"not valid GeoJSON: {exc}", source=source) from None
    except READ_ERRORS as exc:
        raise InputError(f"cannot read: {exc}", source=source) from None
    if isinstance(doc, dict) and doc.get("type") == "Feature":
        features = [doc]
    elif isinstance(doc, dict) and doc.get("type") == "FeatureCollection":
        features = list(doc.get("features") or [])
    else:
        raise InputError(
            "not a GeoJSON FeatureCollection or Feature",
            source=source,
            hint="a track as Point features with a time property, or LineStrings",
        )
    rows: list[dict[str, Any]] = []
    for k, feature in enumerate(features):
        geometry = (feature or {}).get("geometry") or {}
        props = dict((feature or {}).get("properties") or {})
        kind = geometry.get("type")
        coords = geometry.get("coordinates")
        if kind == "Point" and coords:
            rows.append({**_flat(props), **_position(coords)})
        elif kind in ("LineString", "MultiLineString") and coords:
            lines = [coords] if kind == "LineString" else coords
            times = next((props[n] for n in _TIME_ARRAYS if isinstance(props.get(n), list)), None)
            if kind == "MultiLineString" and times and isinstance(times[0], list):
                times = [t for part in times for t in part]
            vertices = [c for line in lines for c in line]
            for i, c in enumerate(vertices):
                row = {"track": str(props.get("name", k)), **_position(c)}
                row["time"] = times[i] if times is not None and i < len(times) else None
                rows.append(row)
    if not rows:
        raise InputError(
            "no Point or LineString features",
            source=source,
            hint="a track as Point features with a time property, or LineStrings",
        )
    frame = pd.DataFrame(rows)
    columns = ColumnMap(lat="lat", lon="lon", alt="alt" if "alt" in frame else None)
    return Table(frame=frame, source=source, columns=columns)


def _position(coords: Any) -> dict[str, Any]:
    out = {"lon": coords[0], "lat": coords[1]}
    if len(coords) > 2:
        out["alt"] = coords[2]
    return out


def _flat(props: dict[str, Any]) -> dict[str, Any]:
    # Nested values (lists, objects) are kept as JSON text: a column per property.
    return {
        str(k): (json.dumps(v) if isinstance(v, dict | list) else v)
        for k, v in props.items()
        if str(k) not in ("lat", "lon", "alt")
    }
