"""Readers take files as people and loggers write them, whatever the extension."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from gradgps import ColumnMap, read_fixes, read_table
from gradgps._cli import main
from gradgps._io.read import resolve_format

GGA = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"


def test_nmea_saved_as_txt_and_csv_named_log_are_read_by_content(tmp_path: Path) -> None:
    nmea = tmp_path / "drive.txt"
    nmea.write_text(GGA + "\n")
    assert resolve_format(nmea) == "nmea"
    csv = tmp_path / "drive.log"
    csv.write_text("t,lat,lon\n0,48.1,11.5\n1,48.1,11.5001\n")
    assert resolve_format(csv) == "csv"
    assert len(read_fixes(csv)) == 2


def test_geojson_points_and_linestring_with_times(tmp_path: Path) -> None:
    points = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [11.5 + i * 1e-4, 48.1]},
                "properties": {"time": f"2026-11-23T10:00:0{i}Z", "speed": 5.0},
            }
            for i in range(3)
        ],
    }
    path = tmp_path / "pts.geojson"
    path.write_text(json.dumps(points))
    fixes = read_fixes(path)
    assert fixes["lon"].tolist() == [11.5, 11.5001, 11.5002]
    assert np.diff(fixes["t"]).tolist() == [1.0, 1.0]
    line = {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [[11.5, 48.1, 500], [11.6, 48.2, 501]]},
        "properties": {"coordTimes": ["2026-11-23T10:00:00Z", "2026-11-23T10:00:01Z"]},
    }
    other = tmp_path / "line.dat"  # no telling extension: recognised by content
    other.write_text(json.dumps(line))
    fixes = read_fixes(other)
    assert fixes["alt"].tolist() == [500, 501]


def test_semicolon_csv_with_decimal_commas_and_day_first_dates(tmp_path: Path) -> None:
    path = tmp_path / "eu.csv"
    path.write_text(
        "Zeit;Breite;Laenge\n23.11.2026 10:00:00;48,1375;11,5755\n23.11.2026 10:00:01;48,1376;11,5756\n"
    )
    run = CliRunner().invoke(
        main,
        ["info", str(path), "--time-col", "Zeit", "--lat-col", "Breite", "--lon-col", "Laenge"],
    )
    assert run.exit_code == 0, run.output
    fixes = read_fixes(path, columns=ColumnMap(time="Zeit", lat="Breite", lon="Laenge"))
    assert fixes["lat"].tolist() == [48.1375, 48.1376]
    assert fixes["t"].iloc[1] - fixes["t"].iloc[0] == 1.0
    assert fixes["t"].iloc[0] == 1795428000.0  # 2026-11-23 10:00:00 UTC, day first


def test_date_and_time_in_two_columns_and_a_leading_count_line(tmp_path: Path) -> None:
    path = tmp_path / "gpslogger.csv"
    path.write_text(
        "2\ndate,time,lat,lng,speed_kmh\n2026-11-23,10:00:00,48.1,11.5,36\n"
        "2026-11-23,10:00:02,48.1,11.5001,72\n"
    )
    fixes = read_fixes(path)
    assert len(fixes) == 2
    assert fixes["t"].tolist() == [1795428000.0, 1795428002.0]
    assert fixes["speed"].tolist() == pytest.approx([10.0, 20.0])  # km/h -> m/s
    assert fixes["lon"].tolist() == [11.5, 11.5001]


def test_timestamp_ms_and_x_y_columns(tmp_path: Path) -> None:
    path = tmp_path / "ms.csv"
    path.write_text("timestamp_ms,Y,X\n0,48.1,11.5\n500,48.1,11.5001\n")
    fixes = read_fixes(path)
    assert fixes["t"].tolist() == [0.0, 0.5]
    assert fixes["lat"].tolist() == [48.1, 48.1]
    projected = tmp_path / "utm.csv"
    projected.write_text("t,X,Y\n0,691000.0,5334000.0\n1,691001.0,5334000.0\n")
    with pytest.raises(Exception, match="projected coordinates"):
        read_fixes(projected)


def test_table_keeps_every_column_of_a_geojson(tmp_path: Path) -> None:
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [11.5, 48.1]},
                "properties": {"timestamp": 1795428000, "vehicle": "A7"},
            }
        ],
    }
    path = tmp_path / "one.json"
    path.write_text(json.dumps(doc))
    table = read_table(path)
    assert {"timestamp", "vehicle", "lat", "lon"} <= set(table.frame.columns)


def _takeout_csv(tmp_path: Path, n: int = 200) -> tuple[Path, np.ndarray, np.ndarray]:
    """Google location history written as CSV: times in ms, degrees x 1e7 as integers."""
    i = np.arange(n)
    lat = 48.1 + 0.00015 * i  # about 17 m/s north
    lon = 11.5 + 0.0002 * i + 0.001 * np.sin(i / 30.0)
    e7_lat, e7_lon = np.rint(lat * 1e7).astype(np.int64), np.rint(lon * 1e7).astype(np.int64)
    path = tmp_path / "takeout.csv"
    rows = [
        f"{1_600_000_000_000 + 1000 * i},{a},{b},5"
        for i, (a, b) in enumerate(zip(e7_lat, e7_lon, strict=True))
    ]
    path.write_text("timestampMs,latitudeE7,longitudeE7,accuracy\n" + "\n".join(rows) + "\n")
    return path, e7_lat / 1e7, e7_lon / 1e7


def test_coordinates_in_degrees_times_1e7_are_read_as_degrees(tmp_path: Path) -> None:
    """latitudeE7/longitudeE7 (Google location history) are found and read as degrees, in
    batch and --follow alike (before: not found, and named by hand every fix was invalid,
    'latitude outside +-90'); a latitude column otherwise named is read as it is."""
    path, lat, lon = _takeout_csv(tmp_path)
    fixes = read_fixes(path)
    assert fixes.attrs["columns"].lat == "latitudeE7"
    np.testing.assert_array_equal(fixes["lat"].to_numpy(), lat)
    np.testing.assert_array_equal(fixes["lon"].to_numpy(), lon)
    runner = CliRunner()
    batch, follow = tmp_path / "batch.csv", tmp_path / "follow.csv"
    assert runner.invoke(main, ["detect", str(path), "-o", str(batch)]).exit_code == 0
    result = runner.invoke(main, ["detect", "--follow", str(path), "-o", str(follow)])
    assert result.exit_code == 0, result.output
    import pandas as pd

    a, b = pd.read_csv(batch), pd.read_csv(follow)
    assert (a["invalid_reason"].isna()).all(), a["invalid_reason"].unique()
    pd.testing.assert_frame_equal(a, b)
    np.testing.assert_allclose(a["lat_clean"], lat, atol=1e-6)
    plain = tmp_path / "plain.csv"
    plain.write_text("t,lat,lon\n0,48.1,11.5\n1,48.1001,11.5001\n")
    assert read_fixes(plain)["lat"].tolist() == [48.1, 48.1001]


def test_faults_and_repairs_are_written_back_in_degrees_times_1e7(tmp_path: Path) -> None:
    """Injected faults and the cleaned positions go back into a latitudeE7 column in its own
    unit: the injected file's untouched fixes keep their values, and a cleaned table reads
    as the positions it repaired."""
    import pandas as pd

    import gradgps
    from gradgps.inject import inject_grad

    path, lat, _ = _takeout_csv(tmp_path)
    table = pd.read_csv(path)
    injected = inject_grad(table, seed=0)
    clean = injected["label_anomaly"] == 0
    np.testing.assert_allclose(injected["latitudeE7"][clean], table["latitudeE7"][clean])
    np.testing.assert_allclose(injected["lat_true"], lat)
    cleaned = gradgps.Detector().clean(table)
    np.testing.assert_allclose(cleaned["latitudeE7"] / 1e7, lat, atol=1e-5)
