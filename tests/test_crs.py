"""X/Y (easting/northing) columns in a projected CRS: ``--crs`` / ``crs=`` (issue 14, item 5)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps import ConfigError, InputError, read_fixes
from gradgps._cli import main

pyproj = pytest.importorskip("pyproj")

#: A drive north through Munich, 1 Hz, ~15 m/s, as WGS84 degrees.
LAT = 48.1 + np.arange(30) * 1.35e-4
LON = np.full(30, 11.55)


def _utm(path: Path, x_name: str = "X", y_name: str = "Y") -> Path:
    """The drive in UTM zone 32N (EPSG:25832): eastings ~690 km, northings ~5330 km."""
    to_utm = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:25832", always_xy=True)
    x, y = to_utm.transform(LON, LAT)
    frame = pd.DataFrame({"t": 1795428000 + np.arange(30), x_name: x, y_name: y})
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize(("x_name", "y_name"), [("X", "Y"), ("x", "y"), ("easting", "northing")])
def test_crs_converts_projected_columns_to_wgs84(tmp_path: Path, x_name: str, y_name: str) -> None:
    path = _utm(tmp_path / "utm.csv", x_name, y_name)
    fixes = read_fixes(path, crs="EPSG:25832")
    assert fixes["lat"].to_numpy() == pytest.approx(LAT, abs=1e-9)
    assert fixes["lon"].to_numpy() == pytest.approx(LON, abs=1e-9)
    assert fixes.attrs["columns"].lon == x_name


def test_cli_crs_detects_on_the_converted_positions(tmp_path: Path) -> None:
    path = _utm(tmp_path / "utm.csv")
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(main, ["detect", str(path), "--crs", "EPSG:25832", "-o", str(out)])
    assert result.exit_code == 0, result.output
    frame = pd.read_csv(out)
    assert len(frame) == 30  # no row lost
    assert frame["X"].iloc[0] > 600_000  # the input columns are kept as written
    assert frame["lat_clean"].to_numpy() == pytest.approx(LAT, abs=1e-5)
    assert frame["invalid_reason"].isna().all()  # every fix usable
    assert "warning: columns" not in result.stderr


def test_projected_columns_without_crs_name_the_column_and_the_option(tmp_path: Path) -> None:
    path = _utm(tmp_path / "utm.csv", "easting", "northing")
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o.csv")])
    assert result.exit_code != 0
    assert "Traceback" not in result.output
    assert "'easting'" in result.output
    assert "--crs" in result.output
    with pytest.raises(InputError, match="'easting' holds projected coordinates") as info:
        read_fixes(path)
    assert "crs=" in str(info.value)


def test_x_y_in_degree_ranges_are_lon_lat_with_one_warning_line(tmp_path: Path) -> None:
    path = tmp_path / "deg.csv"
    pd.DataFrame({"t": 1795428000 + np.arange(30), "X": LON, "Y": LAT}).to_csv(path, index=False)
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(out), "--chunk-size", "7"])
    assert result.exit_code == 0, result.output
    warnings = [w for w in result.stderr.splitlines() if "taken as longitude/latitude" in w]
    assert len(warnings) == 1  # once, though the file was read in five chunks
    assert "--crs" in warnings[0]
    assert pd.read_csv(out)["lat_clean"].to_numpy() == pytest.approx(LAT, abs=1e-5)


def test_an_unknown_crs_is_a_one_line_error(tmp_path: Path) -> None:
    path = _utm(tmp_path / "utm.csv")
    result = CliRunner().invoke(
        main, ["detect", str(path), "--crs", "EPSG:999999", "-o", str(tmp_path / "o.csv")]
    )
    assert result.exit_code != 0
    assert "Traceback" not in result.output
    assert "--crs 'EPSG:999999' is not a coordinate reference system" in result.output
    with pytest.raises(ConfigError, match="crs= 'EPSG:999999'"):
        read_fixes(path, crs="EPSG:999999")


def test_crs_without_the_geo_extra_names_it(tmp_path: Path, monkeypatch) -> None:
    path = _utm(tmp_path / "utm.csv")
    monkeypatch.setitem(sys.modules, "pyproj", None)  # as if not installed
    result = CliRunner().invoke(
        main, ["detect", str(path), "--crs", "EPSG:25832", "-o", str(tmp_path / "o.csv")]
    )
    assert result.exit_code != 0
    assert "Traceback" not in result.output
    assert "pip install 'gradgps[geo]'" in result.output
    errors = [line for line in result.output.splitlines() if "error" in line]
    assert errors == ["error: --crs needs pyproj: pip install 'gradgps[geo]'"]


def test_crs_applies_to_csv_and_parquet_only(tmp_path: Path) -> None:
    gpx = tmp_path / "a.gpx"
    gpx.write_text(
        '<gpx version="1.1"><trk><trkseg><trkpt lat="48.1" lon="11.5">'
        "<time>2026-11-23T10:00:00Z</time></trkpt></trkseg></trk></gpx>"
    )
    with pytest.raises(ConfigError, match="crs= applies to CSV and Parquet"):
        read_fixes(gpx, crs="EPSG:25832")
