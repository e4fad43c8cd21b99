"""Detection results as GeoJSON (for QGIS, geojson.io) and GPX (the repaired track).

GeoJSON (RFC 7946): one FeatureCollection, WGS84 longitude/latitude, no
``crs`` member. Features, each with ``properties.kind``:

* ``"repaired track"``: one LineString per track and segment of usable
  fixes, through the repaired positions (``lat_clean``/``lon_clean``);
* ``"flagged fix"``: a Point at each fix flagged anomalous (as received),
  with its verdict (score, bias type, time type, repaired position, alert,
  time, input row);
* ``"event"``: a LineString through the fixes of each fault event (a Point
  for a one-fix event, ``null`` geometry when none of its fixes is in the
  result) with the event's columns.

Strict RFC 7946, so the file opens as is: strict JSON (a missing number or
label is ``null``, never ``NaN``), longitudes wrapped into [-180, 180], and a
line that crosses the antimeridian cut there into a MultiLineString (3.1.9),
or geojson.io and QGIS draw it the long way round the globe. Unusable fixes
have no trustworthy position and are left out (they are in the CSV with
their reason).

The files are written by :mod:`gradgps._io.export_streamed` as results come, in
bounded memory, with the text :func:`geojson_text` gives for
:func:`geojson_document` of the whole result (and the GPX of :data:`GPX_HEADER`,
:func:`gpx_point` and :data:`GPX_FOOTER`): the pieces here are shared by both. The
HTML report (``--report``) embeds :func:`geojson_document` of what it draws (the
whole result, or past 250,000 rows its thinned sample) and draws its repaired
lines and flagged fixes.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import pandas as pd

from .times import iso_utc_one

__all__ = [
    "GPX_FOOTER",
    "GPX_HEADER",
    "LINE_GAP_S",
    "antimeridian_crossing",
    "event_feature",
    "flagged_features",
    "geojson_document",
    "geojson_text",
    "gpx_point",
    "iso_or_none",
    "usable_repairs",
    "wrap_lon",
]

#: A repaired track is split where two usable fixes are further apart in time than this.
LINE_GAP_S = 60.0


def _num(value: Any) -> float | None:
    v = float(value)
    return v if math.isfinite(v) else None


def _label(value: Any) -> str | None:
    """A text property; None/NaN (a label the result does not have) as JSON null, not "nan"."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    return str(value)


def wrap_lon(lon: np.ndarray) -> np.ndarray:
    """Longitudes in [-180, 180): a repair may step just past 180, the same place written otherwise."""
    return np.asarray((lon + 180.0) % 360.0 - 180.0, dtype=np.float64)


def antimeridian_crossing(a: Sequence[float], b: Sequence[float]) -> tuple[float, float] | None:
    """Where the step from position ``a`` to ``b`` ([lon, lat]) crosses 180 degrees:
    (the meridian's longitude on ``a``'s side, the latitude there); None when it does not.

    A step of more than 180 degrees of longitude is the short way across the
    antimeridian; GIS tools would draw it across the whole map (RFC 7946 3.1.9).
    """
    step = b[0] - a[0]
    if abs(step) <= 180.0:
        return None
    edge = 180.0 if step < 0 else -180.0  # eastward crossing: the jump is negative
    unwrapped = b[0] + (360.0 if step < 0 else -360.0)
    frac = (edge - a[0]) / (unwrapped - a[0])
    return edge, a[1] + frac * (b[1] - a[1])


def _cut_at_antimeridian(coords: list[list[float]]) -> list[list[list[float]]]:
    """Split a line where a step crosses 180 degrees, ending and restarting it on the meridian."""
    parts: list[list[list[float]]] = [[coords[0]]]
    for a, b in itertools.pairwise(coords):
        crossing = antimeridian_crossing(a, b)
        if crossing is not None:
            edge, lat = crossing
            parts[-1].append([edge, lat])
            parts.append([[-edge, lat]])
        parts[-1].append(b)
    return parts


def _geometry(coords: list[list[float]]) -> dict[str, Any] | None:
    """Point, LineString or (cut at the antimeridian) MultiLineString; None without positions."""
    if not coords:
        return None
    if len(coords) == 1:
        return {"type": "Point", "coordinates": coords[0]}
    parts = _cut_at_antimeridian(coords)
    if len(parts) == 1:
        return {"type": "LineString", "coordinates": parts[0]}
    return {"type": "MultiLineString", "coordinates": parts}


def iso_or_none(t: float) -> str | None:
    """One time as every other output writes it (:func:`gradgps._io.times.iso_utc`);
    ``None`` for a missing or absurd one."""
    if not math.isfinite(t) or abs(t) > 1e11:
        return None
    return iso_utc_one(t)


def usable_repairs(result: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which rows have a usable repaired position (a valid fix, a finite one in range), and
    the repaired latitudes and (wrapped) longitudes of every row."""
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = result["lon_clean"].to_numpy(np.float64)
    usable = (
        (result["invalid_reason"].to_numpy() == "")
        & np.isfinite(lat_c)
        & (np.abs(lat_c) <= 90.0)
        & np.isfinite(lon_c)
    )
    return usable, lat_c, wrap_lon(lon_c)


def _lines(
    fixes: pd.DataFrame, result: pd.DataFrame, parts: np.ndarray | None = None
) -> list[tuple[str, np.ndarray]]:
    """Per track and time-contiguous run of usable fixes: (track, row positions).

    ``parts``: each row's run number within its track, where the rows are a thinned
    sample of a longer result (:mod:`gradgps._run.report_data`) whose time gaps are
    no longer the track's; ``None`` cuts where usable fixes are more than
    :data:`LINE_GAP_S` apart."""
    usable = usable_repairs(result)[0]
    tracks = fixes["track"].to_numpy(object)
    t = fixes["t"].to_numpy(np.float64)
    out: list[tuple[str, np.ndarray]] = []
    for track in pd.unique(tracks[usable]):
        rows = np.flatnonzero(usable & (tracks == track))
        if parts is None:
            cuts = np.flatnonzero(np.diff(t[rows]) > LINE_GAP_S) + 1
        else:
            cuts = np.flatnonzero(np.diff(parts[rows]) != 0) + 1
        out.extend((str(track), part) for part in np.split(rows, cuts))
    return out


def geojson_document(
    fixes: pd.DataFrame,
    result: pd.DataFrame,
    events: pd.DataFrame | None = None,
    *,
    rows: np.ndarray | None = None,
    parts: np.ndarray | None = None,
) -> dict[str, Any]:
    """The GeoJSON FeatureCollection (see the module docstring) as a dict.

    ``rows`` and ``parts``: where ``fixes``/``result`` are a thinned sample of a
    run (the report of a long one, :mod:`gradgps._run.report_data`), each row's
    input row number (sorted) and its line's run number within its track.
    """
    numbers = np.arange(len(fixes)) if rows is None else np.asarray(rows, dtype=np.int64)
    lat = fixes["lat"].to_numpy(np.float64)
    lon = wrap_lon(fixes["lon"].to_numpy(np.float64))
    t = fixes["t"].to_numpy(np.float64)
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = wrap_lon(result["lon_clean"].to_numpy(np.float64))
    features: list[dict[str, Any]] = []
    for track, line in _lines(fixes, result, parts):
        coords = [[float(lon_c[i]), float(lat_c[i])] for i in line]
        features.append(
            {
                "type": "Feature",
                "geometry": _geometry(coords),
                "properties": {
                    "kind": "repaired track",
                    "track": track,
                    "fixes": len(coords),
                    "start": iso_or_none(t[line[0]]),
                    "end": iso_or_none(t[line[-1]]),
                },
            }
        )
    features.extend(f for _, f in flagged_features(fixes, result, numbers))
    if events is not None:
        tracks = fixes["track"].to_numpy(object)
        flagged = _flagged(result, lat, lon)
        records: list[dict[Any, Any]] = events.to_dict("records")
        for ev in records:
            first, last = np.searchsorted(numbers, [int(ev["first_row"]), int(ev["last_row"])])
            if last < len(numbers) and numbers[last] == int(ev["last_row"]):
                last += 1
            within = np.arange(first, last)
            within = within[(tracks[within] == ev["track"]) & flagged[within]]
            coords = [[float(lon[i]), float(lat[i])] for i in within]
            features.append(event_feature(ev, coords))
    return {"type": "FeatureCollection", "features": features}


def _flagged(result: pd.DataFrame, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """Flagged usable fixes with a position to draw (as received: ``lat``, wrapped ``lon``)."""
    flagged: np.ndarray = (
        (result["anomaly"].to_numpy() == 1)
        & (result["invalid_reason"].to_numpy() == "")
        & (np.abs(lat) <= 90.0)
        & np.isfinite(lon)
    )
    return flagged


def flagged_features(
    fixes: pd.DataFrame, result: pd.DataFrame, numbers: np.ndarray
) -> Iterator[tuple[int, dict[str, Any]]]:
    """The ``"flagged fix"`` features of a result (or a chunk of one), in row order, each
    with its row position in ``fixes``; ``numbers``: each row's input row number."""
    lat = fixes["lat"].to_numpy(np.float64)
    lon = wrap_lon(fixes["lon"].to_numpy(np.float64))
    t = fixes["t"].to_numpy(np.float64)
    tracks = fixes["track"].to_numpy(object)
    score = result["score"].to_numpy(np.float64)
    bias = result["bias_type"].to_numpy(object)
    time_type = result["time_type"].to_numpy(object)
    alert = result["alert"].to_numpy()
    lat_c = result["lat_clean"].to_numpy(np.float64)
    lon_c = wrap_lon(result["lon_clean"].to_numpy(np.float64))
    for i in np.flatnonzero(_flagged(result, lat, lon)).tolist():
        yield (
            i,
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [float(lon[i]), float(lat[i])]},
                "properties": {
                    "kind": "flagged fix",
                    "row": int(numbers[i]),
                    "track": str(tracks[i]),
                    "t": _num(t[i]),
                    "time": iso_or_none(t[i]),
                    "score": _num(score[i]),
                    "bias_type": _label(bias[i]),
                    "time_type": _label(time_type[i]),
                    "alert": int(alert[i]),
                    "lat_clean": _num(lat_c[i]),
                    "lon_clean": _num(lon_c[i]),
                },
            },
        )


def event_feature(ev: dict[Any, Any], coords: list[list[float]]) -> dict[str, Any]:
    """The ``"event"`` feature of one fault event (a row of the event table) through
    ``coords``, its flagged fixes ([lon, lat] as received)."""
    props = {
        "kind": "event",
        "track": str(ev["track"]),
        "start": iso_or_none(float(ev["start"])),
        "end": iso_or_none(float(ev["end"])),
        "duration_s": _num(ev["duration_s"]),
        "fixes": int(ev["fixes"]),
        "bias_type": _label(ev["bias_type"]),
        "time_type": _label(ev["time_type"]),
        "peak_offset_m": _num(ev["peak_offset_m"]),
        "peak_score": _num(ev["peak_score"]),
        "alert": int(ev["alert"]),
        "first_row": int(ev["first_row"]),
        "last_row": int(ev["last_row"]),
    }
    return {"type": "Feature", "geometry": _geometry(coords), "properties": props}


def geojson_text(doc: dict[str, Any]) -> str:
    """The document as strict, compact JSON: the exact text of the ``--geojson`` file."""
    return json.dumps(doc, allow_nan=False, separators=(",", ":"))


#: The start and end of the GPX file of the repaired tracks.
GPX_HEADER = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<gpx version="1.1" creator="gradgps" xmlns="http://www.topografix.com/GPX/1/1">\n'
)
GPX_FOOTER = "</gpx>\n"


def gpx_point(t: float, lat: float, lon: float) -> str:
    """One repaired fix as a GPX ``trkpt`` line (``lon`` already in [-180, 180))."""
    when = iso_or_none(t)
    time_el = f"<time>{when}</time>" if when is not None else ""
    return f'<trkpt lat="{lat:.8f}" lon="{lon:.8f}">{time_el}</trkpt>\n'
