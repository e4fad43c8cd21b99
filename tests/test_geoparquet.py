"""GeoParquet in and out (issue 14): point geometry read with its CRS, written back as GeoParquet."""

from __future__ import annotations

import json
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


def test_every_wkb_point_flavour_decodes_at_once_as_one_by_one() -> None:
    """The vectorised decoder (issue 18) gives :func:`_wkb_point`'s values for both byte
    orders, ISO and EWKB Z/M/ZM, an SRID, and nulls; anything else it leaves to the row by
    row reading, which names the bad row."""
    import struct

    from gradgps._io.geoparquet import _points_at_once, _wkb_point

    rng = np.random.default_rng(1)
    kinds = [1, 1001, 2001, 3001, 0x20000001, 0x80000001, 0x40000001, 0xC0000001]
    blobs: list[bytes | None] = []
    for i in range(400):
        order = int(rng.integers(0, 2))
        e = "<" if order == 1 else ">"
        kind = kinds[i % len(kinds)]
        srid = struct.pack(e + "I", 4326) if kind & 0x20000000 else b""
        dims = (kind in (1001, 2001, 0x80000001, 0x40000001)) + 2 * (kind in (3001, 0xC0000001))
        xy = struct.pack(e + "dd", *rng.normal(0, 100, 2))
        blob = bytes([order]) + struct.pack(e + "I", kind) + srid + xy + b"\0" * 8 * dims
        blobs.append(None if i % 37 == 0 else blob)
    found = _points_at_once(pd.Series(blobs, dtype=object))
    assert found is not None
    for i, blob in enumerate(blobs):
        want = (np.nan, np.nan) if blob is None else _wkb_point(blob)
        np.testing.assert_array_equal([found[0][i], found[1][i]], want)
    line = b"\x01\x02\x00\x00\x00" + b"\x00" * 40
    assert _points_at_once(pd.Series([line])) is None
    assert _points_at_once(pd.Series([b""])) is None


def test_a_geoparquet_chunk_holds_no_python_object_per_point(tmp_path: Path) -> None:
    """Issue 18: a GeoParquet read in chunks was the one format whose memory still grew with
    the file (10 MB per million fixes): each chunk made a Python ``bytes`` per point (the
    WKB column as pandas converts it) and two floats per point to decode it, and Python's
    allocator, with those made and dropped chunk after chunk, kept more arenas at every
    chunk. A chunk now keeps the column in Arrow and decodes it with NumPy: what it holds in
    Python objects does not grow with its rows."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from gradgps._io.read import table_chunks

    n = 20_000
    wkb = np.zeros(n, np.dtype([("order", "u1"), ("kind", "<u4"), ("x", "<f8"), ("y", "<f8")]))
    wkb["order"], wkb["kind"] = 1, 1
    wkb["x"], wkb["y"] = 11.5 + 1e-6 * np.arange(n), 48.1
    points = pa.Array.from_buffers(pa.binary(21), n, [None, pa.py_buffer(wkb.tobytes())])
    table = pa.table({"t": 1.7e9 + np.arange(n, dtype=float), "geometry": points.cast(pa.binary())})
    geo = {
        "version": "1.0.0",
        "primary_column": "geometry",
        "columns": {"geometry": {"encoding": "WKB", "geometry_types": ["Point"]}},
    }
    path = tmp_path / "points.parquet"
    pq.write_table(table.replace_schema_metadata({b"geo": json.dumps(geo).encode()}), path)
    chunks = table_chunks(path, n)
    before = sys.getallocatedblocks()
    chunk = next(chunks)
    held = sys.getallocatedblocks() - before
    assert chunk.geometry is not None
    np.testing.assert_array_equal(chunk.geometry.x, wkb["x"])
    assert held < n // 10, held
