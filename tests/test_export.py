"""--events, --geojson and --gpx: fault events and the repaired track in formats GIS tools open."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet


def _source(tmp_path: Path) -> Path:
    drives = inject_grad(simulate_fleet(2, 4.0, 1.0, seed=11), seed=1)
    frame = drives[["track", "t", "lat", "lon", "speed"]].copy()
    frame["t"] = pd.to_datetime(frame["t"], unit="s", utc=True).dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    path = tmp_path / "in.csv"
    frame.to_csv(path, index=False)
    return path


_GEOMETRIES = {
    "Point",
    "MultiPoint",
    "LineString",
    "MultiLineString",
    "Polygon",
    "MultiPolygon",
    "GeometryCollection",
}


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _position(c: Any) -> None:
    """RFC 7946 3.1.1: [longitude, latitude(, altitude)], numbers, WGS84 ranges."""
    assert isinstance(c, list), c
    assert len(c) in (2, 3), c
    assert all(_number(v) for v in c), c
    assert -180 <= c[0] <= 180, f"longitude first and within +-180: {c}"
    assert -90 <= c[1] <= 90, f"latitude second and within +-90: {c}"


def _line(coords: Any) -> None:
    assert isinstance(coords, list)
    assert len(coords) >= 2, "a LineString has two or more positions (3.1.4)"
    for c in coords:
        _position(c)


def _ring(coords: Any) -> None:
    _line(coords)
    assert len(coords) >= 4, "a ring has four or more positions (3.1.6)"
    assert coords[0] == coords[-1], "a closed ring (3.1.6)"


def _check_geometry(g: Any) -> None:
    assert isinstance(g, dict)
    kind = g.get("type")
    assert kind in _GEOMETRIES, f"unknown geometry type {kind!r}"
    if "bbox" in g:
        _bbox(g["bbox"])
    if kind == "GeometryCollection":
        assert "coordinates" not in g
        assert isinstance(g["geometries"], list)
        for part in g["geometries"]:
            _check_geometry(part)
        return
    coords = g["coordinates"]
    assert isinstance(coords, list)
    if kind == "Point":
        _position(coords)
    elif kind == "MultiPoint":
        for c in coords:
            _position(c)
    elif kind == "LineString":
        _line(coords)
    elif kind == "MultiLineString":
        for part in coords:
            _line(part)
    elif kind == "Polygon":
        for ring in coords:
            _ring(ring)
    else:
        for polygon in coords:
            for ring in polygon:
                _ring(ring)


def _bbox(b: Any) -> None:
    """RFC 7946 5: [west, south, east, north] (or with altitudes), numbers in range."""
    assert isinstance(b, list), b
    assert len(b) in (4, 6), b
    assert all(_number(v) for v in b), b
    half = len(b) // 2
    west, south, east, north = b[0], b[1], b[half], b[half + 1]
    assert -180 <= west <= 180, b
    assert -180 <= east <= 180, b
    assert -90 <= south <= north <= 90, b


def _reject_constant(name: str) -> Any:
    raise AssertionError(f"{name} is not JSON (RFC 8259); RFC 7946 needs strict JSON")


def load_strict(text: str) -> Any:
    """``json.loads`` that fails on NaN / Infinity / -Infinity instead of reading them."""
    return json.loads(text, parse_constant=_reject_constant)


def validate_geojson(doc: Any) -> None:
    """RFC 7946, strictly: what QGIS, geojson.io and ogr2ogr rely on."""
    assert isinstance(doc, dict)
    assert doc.get("type") == "FeatureCollection"
    assert "crs" not in doc, "RFC 7946 removed 'crs': WGS84 only"
    assert set(doc) <= {"type", "features", "bbox"}, set(doc)
    if "bbox" in doc:
        _bbox(doc["bbox"])
    assert isinstance(doc["features"], list)
    for f in doc["features"]:
        assert isinstance(f, dict)
        assert f.get("type") == "Feature"
        assert "crs" not in f
        assert set(f) <= {"type", "geometry", "properties", "id", "bbox"}, set(f)
        assert "geometry" in f, "a Feature has a geometry member (3.2), null or not"
        assert "properties" in f, "a Feature has a properties member (3.2), null or not"
        if f["geometry"] is not None:
            _check_geometry(f["geometry"])
        assert f["properties"] is None or isinstance(f["properties"], dict)
        if "id" in f:
            assert isinstance(f["id"], str) or _number(f["id"])
        if "bbox" in f:
            _bbox(f["bbox"])


def test_events_geojson_and_gpx_from_one_run(tmp_path: Path) -> None:
    src = _source(tmp_path)
    out, events, geo, gpx = (tmp_path / n for n in ("o.csv", "e.csv", "t.geojson", "t.gpx"))
    run = CliRunner().invoke(
        main,
        [
            "detect",
            str(src),
            "-o",
            str(out),
            "--threshold",
            "0.2",
            "--events",
            str(events),
            "--geojson",
            str(geo),
            "--gpx",
            str(gpx),
        ],
    )
    assert run.exit_code == 0, run.output
    result = pd.read_csv(out, keep_default_na=False)
    ev = pd.read_csv(events)
    flagged = result[(result["anomaly"] == 1) & (result["invalid_reason"] == "")]
    assert len(ev) > 0
    assert int(ev["fixes"].sum()) == len(flagged)
    # Times in the input's own form: ISO-8601 in, ISO-8601 out.
    assert str(ev["start"].iloc[0]).endswith("Z")
    assert "T" in str(ev["start"].iloc[0])
    doc = load_strict(geo.read_text())
    validate_geojson(doc)
    kinds = pd.Series([f["properties"]["kind"] for f in doc["features"]]).value_counts()
    assert kinds["flagged fix"] == len(flagged)
    assert kinds["event"] == len(ev)
    assert kinds["repaired track"] >= 2
    gpxpy = pytest.importorskip("gpxpy")
    parsed = gpxpy.parse(gpx.read_text())
    points = [p for t in parsed.tracks for s in t.segments for p in s.points]
    assert len(points) == int((result["invalid_reason"] == "").sum())
    assert points[0].time is not None


def test_output_is_optional_when_another_output_is_named(tmp_path: Path) -> None:
    src = _source(tmp_path)
    events = tmp_path / "e.csv"
    run = CliRunner().invoke(main, ["detect", str(src), "--events", str(events)])
    assert run.exit_code == 0, run.output
    assert events.exists()
    run = CliRunner().invoke(main, ["detect", str(src)])
    assert run.exit_code == 2
    assert "name an output" in run.output


def _frames(lon: list[float], lon_clean: list[float]) -> tuple[pd.DataFrame, pd.DataFrame]:
    n = len(lon)
    fixes = pd.DataFrame(
        {
            "track": ["a"] * n,
            "t": [1_700_000_000.0 + i for i in range(n)],
            "lat": [48.0 + 1e-5 * i for i in range(n)],
            "lon": lon,
        }
    )
    result = pd.DataFrame(
        {
            "anomaly": [1] * n,
            "score": [math.nan, math.inf, *[0.9] * (n - 2)],
            "bias_type": [None, math.nan, *["jump"] * (n - 2)],
            "time_type": [math.nan, None, *["abrupt"] * (n - 2)],
            "lat_clean": [48.0 + 1e-5 * i for i in range(n)],
            "lon_clean": lon_clean,
            "alert": [0] * n,
            "invalid_reason": [""] * n,
        }
    )
    return fixes, result


def _segments(g: dict[str, Any]) -> list[list[list[float]]]:
    if g["type"] == "LineString":
        return [g["coordinates"]]
    if g["type"] == "MultiLineString":
        return list(g["coordinates"])
    return []


def test_geojson_is_strict_with_missing_values_and_the_antimeridian(tmp_path: Path) -> None:
    """NaN/inf/None become null, positions stay in range, lines are cut at 180 (RFC 7946 3.1.9)."""
    from gradgps._grad.events import fault_events
    from gradgps._io.export_streamed import write_geojson

    lon = [179.9997, 179.9998, 179.9999, -179.9999, -179.9998, -179.9997]
    # A repaired longitude just past 180 is the same place written the other way round.
    lon_clean = [179.9997, 179.9998, 180.00005, -179.9999, -180.00002, -179.9997]
    fixes, result = _frames(lon, lon_clean)
    events = fault_events(fixes, result)
    stale = events.copy()
    stale["track"] = "gone"  # an event whose fixes are not in this result: no geometry, no crash
    path = write_geojson(tmp_path / "o.geojson", fixes, result, pd.concat([events, stale]))
    text = path.read_text()
    doc = load_strict(text)
    validate_geojson(doc)
    for f in doc["features"]:
        for part in _segments(f["geometry"] or {"type": "Point"}):
            steps = [abs(b[0] - a[0]) for a, b in itertools.pairwise(part)]
            assert max(steps) <= 180, "a line crossing the antimeridian must be cut there"
    points = [f for f in doc["features"] if f["properties"]["kind"] == "flagged fix"]
    assert len(points) == 6
    first, second = points[0]["properties"], points[1]["properties"]
    assert first["score"] is None
    assert second["score"] is None
    assert first["bias_type"] is None
    assert second["bias_type"] is None
    assert first["time_type"] is None
    assert second["time_type"] is None
    assert points[2]["properties"]["lon_clean"] == pytest.approx(-179.99995)
    assert "nan" not in text.lower()
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("repaired track") == 1
    assert kinds.count("event") == 2 * len(events)
    track = next(f for f in doc["features"] if f["properties"]["kind"] == "repaired track")
    assert track["geometry"]["type"] == "MultiLineString"
    assert [f["geometry"] for f in doc["features"] if f["properties"]["track"] == "gone"] == [
        None
    ] * len(events)


def test_validator_rejects_what_rfc_7946_forbids() -> None:
    """The checks above are strict: each of these documents is refused."""
    point = {"type": "Feature", "geometry": {"type": "Point", "coordinates": [11.5, 48.1]}}
    good = {"type": "FeatureCollection", "features": [{**point, "properties": None}]}
    validate_geojson(good)
    bad: list[Any] = [
        {**good, "crs": {"type": "name"}},
        {"type": "FeatureCollection", "features": [point]},  # no properties member
        {"type": "FeatureCollection", "features": [{**point, "properties": []}]},
        {
            "type": "FeatureCollection",
            "features": [
                {
                    "type": "Feature",
                    "properties": {},
                    "geometry": {"type": "Point", "coordinates": [48.1, 181.0]},
                }
            ],
        },
        {
            "type": "FeatureCollection",
            "features": [
                {
                    "type": "Feature",
                    "properties": {},
                    "geometry": {"type": "LineString", "coordinates": [[11.5, 48.1]]},
                }
            ],
        },
        {**good, "bbox": [11.5, 48.1, 11.6]},
        {**good, "bbox": [11.5, 49.0, 11.6, 48.0]},
    ]
    for doc in bad:
        with pytest.raises(AssertionError):
            validate_geojson(doc)
    with pytest.raises(AssertionError):
        load_strict('{"type": "FeatureCollection", "features": [], "x": NaN}')


def test_geojson_and_gpx_times_are_written_as_every_other_output_writes_them(
    tmp_path: Path,
) -> None:
    """One formatter for output times (``gradgps._io.times.iso_utc``): a fix 0.2 s past a
    second is ``...05.200Z`` in the GeoJSON and the GPX as in the event table, not the
    float's nanosecond tail (``...05.200000048Z``)."""
    import json

    from gradgps._io.export import geojson_document
    from gradgps._io.times import iso_utc_one

    t = 1790157605.2
    fixes = pd.DataFrame(
        {"track": ["a", "a"], "t": [t, t + 1.0], "lat": [48.1, 48.1001], "lon": [11.5, 11.5]}
    )
    result = pd.DataFrame(
        {
            "anomaly": [1, 0],
            "score": [0.99, 0.01],
            "bias_type": ["jump", "none"],
            "time_type": ["transient", "none"],
            "lat_clean": [48.1, 48.1001],
            "lon_clean": [11.5, 11.5],
            "alert": [0, 0],
            "invalid_reason": ["", ""],
        }
    )
    document = json.loads(json.dumps(geojson_document(fixes, result)))
    times = [
        f["properties"]["time"] for f in document["features"] if f["geometry"]["type"] == "Point"
    ]
    assert times == [iso_utc_one(t)] == ["2026-09-23T10:00:05.200Z"]
