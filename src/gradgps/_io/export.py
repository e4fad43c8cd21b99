"""Detection results as GeoJSON (for QGIS, geojson.io) and GPX (the repaired track).

GeoJSON (RFC 7946): one FeatureCollection, WGS84 longitude/latitude, no
``crs`` member. Features, each with ``properties.kind``:

* ``"repaired track"``: one LineString per track and segment of usable
  fixes, through the repaired positions (``lat_clean``/``lon_clean``);
* ``"flagged fix"``: a Point at each fix flagged anomalous (as received),
  with its verdict (score, bias type, time type, repaired position, alert,
  time, input row);
* ``"event"``: a LineString through the fixes of each fault event (a Point
  for a one-fix event) with the event's columns.

Unusable fixes have no trustworthy position and are left out (they are in
the CSV with their reason). Both files are written atomically.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np
import pandas as pd

__all__ = ["geojson_document", "write_geojson", "write_gpx"]

#: A repaired track is split where two usable fixes are further apart in time than this.
LINE_GAP_S = 60.0


def _atomic_write(path: str | os.PathLike[str], text: str) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(out)
    return out


def _num(value: Any) -> float | None:
    v = float(value)
    return v if math.isfinite(v) else None


def _iso(t: float) -> str | None:
    if not math.isfinite(t) or abs(t) > 1e11:
        return None
    return pd.Timestamp(t, unit="s", tz="UTC").isoformat().replace("+00:00", "Z")


def _lines(fixes: pd.DataFrame, result: pd.DataFrame) -> list[tuple[str, np.ndarray]]:
    """Per track and time-contiguous run of usable fixes: (track, row positions)."""
    usable = (
        (result["invalid_reason"].to_numpy() == "")
        & np.isfinite(result["lat_clean"].to_numpy(np.float64))
        & np.isfinite(result["lon_clean"].to_numpy(np.float64))
    )
    tracks = fixes["track"].to_numpy(object)
    t = fixes["t"].to_numpy(np.float64)
    out: list[tuple[str, np.ndarray]] = []
    for track in pd.unique(tracks[usable]):
        rows = np.flatnonzero(usable & (tracks == track))
        cuts = np.flatnonzero(np.diff(t[rows]) > LINE_GAP_S) + 1
        out.extend((str(track), part) for part in np.split(rows, cuts))
    return out


def geojson_document(
    fixes: pd.DataFrame, result: pd.DataFrame, events: pd.DataFrame | None = None
) -> dict[str, Any]:
    """The GeoJSON FeatureCollection (see the module docstring) as a dict."""
    lat = fixes["lat"].to_numpy(np.float64)
    lon = fixes["lon"].to_numpy(np.float64)
    t = fixes["t"].to_numpy(np.float64)
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = result["lon_clean"].to_numpy(np.float64)
    features: list[dict[str, Any]] = []
    for track, rows in _lines(fixes, result):
        coords = [[float(lon_c[i]), float(lat_c[i])] for i in rows]
        geometry: dict[str, Any] = (
            {"type": "LineString", "coordinates": coords}
            if len(coords) >= 2
            else {"type": "Point", "coordinates": coords[0]}
        )
        features.append(
            {
                "type": "Feature",
                "geometry": geometry,
                "properties": {
                    "kind": "repaired track",
                    "track": track,
                    "fixes": len(coords),
                    "start": _iso(t[rows[0]]),
                    "end": _iso(t[rows[-1]]),
                },
            }
        )
    flagged = np.flatnonzero(
        (result["anomaly"].to_numpy() == 1)
        & (result["invalid_reason"].to_numpy() == "")
        & np.isfinite(lat)
        & np.isfinite(lon)
    )
    tracks = fixes["track"].to_numpy(object)
    score = result["score"].to_numpy(np.float64)
    bias = result["bias_type"].to_numpy(object)
    time_type = result["time_type"].to_numpy(object)
    alert = result["alert"].to_numpy()
    for i in flagged.tolist():
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [float(lon[i]), float(lat[i])]},
                "properties": {
                    "kind": "flagged fix",
                    "row": i,
                    "track": str(tracks[i]),
                    "t": _num(t[i]),
                    "time": _iso(t[i]),
                    "score": _num(score[i]),
                    "bias_type": str(bias[i]),
                    "time_type": str(time_type[i]),
                    "alert": int(alert[i]),
                    "lat_clean": _num(lat_c[i]),
                    "lon_clean": _num(lon_c[i]),
                },
            }
        )
    if events is not None:
        records: list[dict[Any, Any]] = events.to_dict("records")
        for ev in records:
            rows = np.arange(int(ev["first_row"]), int(ev["last_row"]) + 1)
            rows = rows[
                (tracks[rows] == ev["track"])
                & (result["anomaly"].to_numpy()[rows] == 1)
                & (result["invalid_reason"].to_numpy()[rows] == "")
            ]
            coords = [[float(lon[i]), float(lat[i])] for i in rows]
            geom: dict[str, Any] = (
                {"type": "LineString", "coordinates": coords}
                if len(coords) >= 2
                else {"type": "Point", "coordinates": coords[0]}
            )
            props = {
                "kind": "event",
                "track": str(ev["track"]),
                "start": _iso(float(ev["start"])),
                "end": _iso(float(ev["end"])),
                "duration_s": _num(ev["duration_s"]),
                "fixes": int(ev["fixes"]),
                "bias_type": str(ev["bias_type"]),
                "time_type": str(ev["time_type"]),
                "peak_offset_m": _num(ev["peak_offset_m"]),
                "peak_score": _num(ev["peak_score"]),
                "alert": int(ev["alert"]),
                "first_row": int(ev["first_row"]),
                "last_row": int(ev["last_row"]),
            }
            features.append({"type": "Feature", "geometry": geom, "properties": props})
    return {"type": "FeatureCollection", "features": features}


def write_geojson(
    path: str | os.PathLike[str],
    fixes: pd.DataFrame,
    result: pd.DataFrame,
    events: pd.DataFrame | None = None,
) -> Path:
    """Write :func:`geojson_document` to ``path`` (strict JSON, atomically)."""
    doc = geojson_document(fixes, result, events)
    return _atomic_write(path, json.dumps(doc, allow_nan=False, separators=(",", ":")))


def write_gpx(path: str | os.PathLike[str], fixes: pd.DataFrame, result: pd.DataFrame) -> Path:
    """The repaired track as GPX 1.1: one ``trk`` per track, one ``trkseg`` per run of usable fixes."""
    t = fixes["t"].to_numpy(np.float64)
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = result["lon_clean"].to_numpy(np.float64)
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<gpx version="1.1" creator="gradgps" xmlns="http://www.topografix.com/GPX/1/1">\n'
    ]
    by_track: dict[str, list[np.ndarray]] = {}
    for track, rows in _lines(fixes, result):
        by_track.setdefault(track, []).append(rows)
    for track, runs in by_track.items():
        parts.append(f"<trk><name>{escape(track)}</name>\n")
        for rows in runs:
            parts.append("<trkseg>\n")
            for i in rows.tolist():
                when = _iso(t[i])
                time_el = f"<time>{when}</time>" if when is not None else ""
                parts.append(
                    f'<trkpt lat="{lat_c[i]:.8f}" lon="{lon_c[i]:.8f}">{time_el}</trkpt>\n'
                )
            parts.append("</trkseg>\n")
        parts.append("</trk>\n")
    parts.append("</gpx>\n")
    return _atomic_write(path, "".join(parts))
