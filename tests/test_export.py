"""--events, --geojson and --gpx: fault events and the repaired track in formats GIS tools open."""

from __future__ import annotations

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


def _position(c: Any) -> None:
    assert isinstance(c, list)
    assert len(c) in (2, 3)
    assert all(isinstance(v, int | float) and math.isfinite(v) for v in c)
    assert -180 <= c[0] <= 180
    assert -90 <= c[1] <= 90


def _check_geometry(g: dict[str, Any]) -> None:
    kind = g["type"]
    if kind == "Point":
        _position(g["coordinates"])
    elif kind == "LineString":
        assert len(g["coordinates"]) >= 2
        for c in g["coordinates"]:
            _position(c)
    else:
        raise AssertionError(f"unexpected geometry {kind}")


def validate_geojson(doc: dict[str, Any]) -> None:
    """The parts of RFC 7946 a reader relies on."""
    assert doc["type"] == "FeatureCollection"
    assert "crs" not in doc  # RFC 7946 removed it: WGS84 only
    assert isinstance(doc["features"], list)
    for f in doc["features"]:
        assert f["type"] == "Feature"
        assert set(f) <= {"type", "geometry", "properties", "id", "bbox"}
        _check_geometry(f["geometry"])
        assert isinstance(f["properties"], dict)


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
    doc = json.loads(geo.read_text())
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
