"""GeoParquet in and out (issue 14): point geometry read with its CRS, written back as GeoParquet."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from _whole_file import detect_whole
from gradgps import InputError, read_fixes
from gradgps._cli import main

pytest.importorskip("pyarrow")
gpd = pytest.importorskip("geopandas")
shapely = pytest.importorskip("shapely")

LAT = 48.1 + np.arange(30) * 1.35e-4
LON = np.full(30, 11.55)


def _geoparquet(path: Path, crs: str = "EPSG:4326") -> Path:
    frame = gpd.GeoDataFrame(
        {"time": pd.date_range("2026-11-23 10:00", periods=30, freq="1s", tz="UTC"), "car": "a"},
        geometry=gpd.points_from_xy(LON, LAT),
        crs="EPSG:4326",
    ).to_crs(crs)
    frame.to_parquet(path)
    return path


def _detect(args: list[str]) -> None:
    result = CliRunner().invoke(main, ["detect", *args])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize("crs", ["EPSG:4326", "EPSG:25832"])
def test_geoparquet_positions_are_read_from_the_geometry_in_its_crs(tmp_path: Path, crs) -> None:
    path = _geoparquet(tmp_path / "drive.parquet", crs)
    fixes = read_fixes(path)
    assert fixes["lat"].to_numpy() == pytest.approx(LAT, abs=1e-9)
    assert fixes["lon"].to_numpy() == pytest.approx(LON, abs=1e-9)
    assert fixes["t"].iloc[1] - fixes["t"].iloc[0] == 1.0


def test_geoparquet_is_read_without_geopandas(tmp_path: Path, monkeypatch) -> None:
    path = _geoparquet(tmp_path / "drive.parquet")
    monkeypatch.setitem(sys.modules, "geopandas", None)  # plain pyarrow decodes the WKB
    fixes = read_fixes(path)
    assert fixes["lat"].to_numpy() == pytest.approx(LAT, abs=1e-12)


def test_geoparquet_in_gives_geoparquet_out(tmp_path: Path) -> None:
    path = _geoparquet(tmp_path / "drive.parquet", "EPSG:25832")
    out = tmp_path / "out.parquet"
    _detect([str(path), "-o", str(out)])
    back = gpd.read_parquet(out)  # fails unless the output has geometry and 'geo' metadata
    original = gpd.read_parquet(path)
    assert back.crs == original.crs
    assert len(back) == 30
    assert back.geometry.geom_equals_exact(original.geometry, tolerance=0).all()
    assert list(back.columns[:3]) == ["time", "car", "geometry"]
    assert back["lat_clean"].to_numpy() == pytest.approx(LAT, abs=1e-5)


def test_geoparquet_to_csv_writes_the_geometry_as_wkt(tmp_path: Path) -> None:
    path = _geoparquet(tmp_path / "drive.parquet")
    out = tmp_path / "out.csv"
    _detect([str(path), "-o", str(out)])
    frame = pd.read_csv(out)
    assert len(frame) == 30
    assert frame["geometry"].iloc[0] == "POINT (11.55 48.1)"
    assert frame["time"].iloc[0] == "2026-11-23T10:00:00Z"


@pytest.mark.parametrize("chunked", [False, True])
def test_geoparquet_with_lines_names_the_row(tmp_path: Path, chunked: bool) -> None:
    """Read whole or in chunks of 10 (issue 18), a line names its row in the file."""
    from gradgps._io.read import table_chunks

    geometry = list(gpd.points_from_xy(LON, LAT))
    geometry[24] = shapely.LineString([(11.5, 48.1), (11.6, 48.2)])
    frame = gpd.GeoDataFrame({"t": np.arange(30.0)}, geometry=geometry, crs="EPSG:4326")
    frame.to_parquet(tmp_path / "lines.parquet")
    path = tmp_path / "lines.parquet"
    read = (lambda: list(table_chunks(path, 10))) if chunked else (lambda: read_fixes(path))
    with pytest.raises(InputError, match=r"row 25.*geometry|geometry.*row 25") as info:
        read()
    assert "a LineString, not a Point" in str(info.value)


@pytest.mark.parametrize("crs", ["EPSG:4326", "EPSG:25832"])
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_geoparquet_is_read_in_chunks_with_the_whole_file_results(
    tmp_path: Path, crs: str, suffix: str
) -> None:
    """Issue 18: GeoParquet is read a record batch at a time (row groups of 7 rows here,
    chunks of 4, and the largest chunks, --chunk-size 0), its points decoded chunk by chunk:
    the output of the file read whole and detected at once (``detect_whole``), values,
    geometry and ``geo`` metadata alike."""
    import pyarrow.parquet as pq

    path = _geoparquet(tmp_path / "drive.parquet", crs)
    table = pq.read_table(path)
    pq.write_table(table, path, row_group_size=7)
    assert pq.ParquetFile(path).metadata.num_row_groups == 5
    chunked, largest = tmp_path / f"chunked{suffix}", tmp_path / f"largest{suffix}"
    whole = tmp_path / f"whole{suffix}"
    _detect([str(path), "-o", str(chunked), "--chunk-size", "4"])
    _detect([str(path), "-o", str(largest), "--chunk-size", "0"])
    detect_whole(path, whole)
    if suffix == ".csv":
        assert chunked.read_bytes() == whole.read_bytes()
        assert largest.read_bytes() == whole.read_bytes()
        return
    pd.testing.assert_frame_equal(pd.read_parquet(chunked), pd.read_parquet(whole))
    pd.testing.assert_frame_equal(pd.read_parquet(largest), pd.read_parquet(whole))
    assert pq.read_schema(chunked).metadata[b"geo"] == pq.read_schema(path).metadata[b"geo"]
    back = gpd.read_parquet(chunked)
    assert back.crs == gpd.read_parquet(path).crs
    assert back["lat_clean"].to_numpy() == pytest.approx(LAT, abs=1e-5)
