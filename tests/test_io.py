"""CSV/Parquet reading and writing: structure errors, value errors, detection, round trips."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gradgps import ColumnMap, ConfigError, InputError, to_fixes
from gradgps._io.read import iter_csv_tables, read_fixes, read_table, resolve_format, write_table


def drive(n: int = 100) -> pd.DataFrame:
    """A small 1 Hz drive heading north-east."""
    i = np.arange(n, dtype=np.float64)
    return pd.DataFrame(
        {
            "t": 1_558_644_851.0 + i,
            "lat": 41.25 + 1e-4 * i,
            "lon": -95.98 + 1e-4 * i,
            "speed": np.full(n, 12.5),
            "note": ["ok"] * n,
        }
    )


def write_text(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def bad_row_57_csv(tmp_path: Path) -> Path:
    frame = drive().astype({"lat": object})
    frame.loc[56, "lat"] = "41.2x"
    path = tmp_path / "bad57.csv"
    frame.to_csv(path, index=False)
    return path


# --- values ------------------------------------------------------------------


def test_non_numeric_latitude_names_row_line_and_column(tmp_path: Path) -> None:
    path = bad_row_57_csv(tmp_path)
    with pytest.raises(InputError) as info:
        read_fixes(path)
    err = info.value
    assert (err.row, err.line, err.column) == (57, 58, "lat")
    assert "row 57 (line 58), column 'lat'" in str(err)
    assert "'41.2x'" in str(err)
    assert str(path) in str(err)


def test_every_input_column_kept_in_order(tmp_path: Path) -> None:
    path = tmp_path / "d.csv"
    drive()[["note", "lon", "speed", "lat", "t"]].to_csv(path, index=False)
    table = read_table(path)
    assert list(table.frame.columns) == ["note", "lon", "speed", "lat", "t"]
    assert table.first_line == 2
    assert table.source == str(path)


def test_blank_lines_inside_drop_line_numbers_but_keep_rows(tmp_path: Path) -> None:
    # Rows after a blank line no longer sit at first_line + k; a wrong line
    # number is worse than none, so only rows are named.
    path = write_text(tmp_path / "b.csv", "t,lat,lon\n0,1,2\n\n1,abc,2\n")
    table = read_table(path)
    assert table.first_line is None
    with pytest.raises(InputError) as info:
        to_fixes(table)
    assert (info.value.row, info.value.line) == (2, None)


@pytest.mark.parametrize(
    ("header", "time_value"),
    [
        ("time,latitude,longitude", "10"),
        ("Time,Latitude,Longitude", "10"),
        ("t,gps_lat,gps_lon", "10"),
        ("ts,GPS Latitude,GPS Longitude", "10"),
        ("t,lat,lng", "10"),
        ("t,lat,long", "10"),
        ("timestamp,lat,lon", "1970-01-01T00:00:10Z"),
        ("timestamp,Latitude,Longitude", "1970-01-01T01:00:10+01:00"),
    ],
)
def test_column_auto_detection(tmp_path: Path, header: str, time_value: str) -> None:
    path = write_text(tmp_path / "a.csv", f"{header}\n{time_value},41.5,-95.25\n")
    fixes = read_fixes(path)
    assert fixes[["t", "lat", "lon"]].iloc[0].tolist() == [10.0, 41.5, -95.25]
    assert fixes["track"].tolist() == ["0"]


def test_semicolon_and_tab_delimiters(tmp_path: Path) -> None:
    for name, sep in (("a.csv", ";"), ("b.tsv", "\t")):
        path = write_text(
            tmp_path / name,
            sep.join(["t", "lat", "lon"]) + "\n" + sep.join(["1", "2.5", "3.5"]) + "\n",
        )
        assert read_fixes(path)[["t", "lat", "lon"]].iloc[0].tolist() == [1.0, 2.5, 3.5]


def test_track_ids_stay_text(tmp_path: Path) -> None:
    path = write_text(tmp_path / "a.csv", "trip,t,lat,lon\n007,0,1,2\n7,1,1,2\n")
    assert read_fixes(path)["track"].tolist() == ["007", "7"]


def test_explicit_columns_override_detection(tmp_path: Path) -> None:
    path = write_text(tmp_path / "a.csv", "when,y,x,t\n5,1,2,99\n")
    fixes = read_fixes(path, columns=ColumnMap(time="when", lat="y", lon="x"))
    assert fixes[["t", "lat", "lon"]].iloc[0].tolist() == [5.0, 1.0, 2.0]


def test_channels_carried(tmp_path: Path) -> None:
    path = write_text(tmp_path / "a.csv", "t,lat,lon,accel_x_g\n0,1,2,0.25\n")
    assert read_fixes(path, channels=["accel_x_g"])["accel_x_g"].tolist() == [0.25]


# --- malformed files -----------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "match", "line"),
    [
        ("", "empty file", None),
        ("\n\n  \n", "empty file", None),
        ("t,lat,lon\n0,1,2\n1,1,2,9\n", "4 fields where the header has 3", 3),
        ("t,lat,lon\n0,1,2\n1,1.00", "2 fields where the header has 3", 3),  # truncated
        ('t,lat,lon\n0,1,2\n1,"x"y,2\n', "malformed CSV record", 3),
        ('t,lat,lon\n0,1,2\n1,"open,2\n2,1,2\n', "malformed CSV record", 3),
        ("0,41.2,-95.9\n1,41.2,-95.9\n", "no header", 1),
        ("t,a,b\n0,1,2\n", "cannot find the lat column", None),
    ],
    ids=[
        "empty",
        "blank-lines-only",
        "ragged-long",
        "truncated",
        "bad-quote",
        "unclosed-quote",
        "no-header",
        "wrong-columns",
    ],
)
def test_malformed_csv(tmp_path: Path, text: str, match: str, line: int | None) -> None:
    path = write_text(tmp_path / "m.csv", text)
    with pytest.raises(InputError, match=match) as info:
        read_fixes(path)
    assert info.value.line == line
    assert str(path) in str(info.value)


def test_wrong_columns_lists_the_available_ones(tmp_path: Path) -> None:
    path = write_text(tmp_path / "m.csv", "t,a,b\n0,1,2\n")
    with pytest.raises(InputError, match=r"--lat-col; available columns: t, a, b"):
        read_fixes(path)


def test_not_utf8_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes("t,lat,lon,place\n0,1,2,Berlin\n1,1,2,München\n".encode("latin-1"))
    with pytest.raises(InputError, match="not UTF-8 text") as info:
        read_table(path)
    assert info.value.line == 3


def test_binary_garbage(tmp_path: Path) -> None:
    path = tmp_path / "noise.csv"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match=r"not UTF-8|NUL bytes"):
        read_table(path)


def test_nul_bytes(tmp_path: Path) -> None:
    path = tmp_path / "nul.csv"
    path.write_bytes(b"t,lat,lon\n0,1,2\n\x00\x00,1,2\n")
    with pytest.raises(InputError, match="NUL bytes") as info:
        read_table(path)
    assert info.value.line == 3


def test_missing_file_and_directory(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        read_table(tmp_path / "absent.csv")
    with pytest.raises(InputError, match="is a directory"):
        read_table(tmp_path, fmt="csv")


def test_damaged_gzip(tmp_path: Path) -> None:
    garbage = tmp_path / "g.csv.gz"
    garbage.write_bytes(b"this is not gzip at all\n")
    with pytest.raises(InputError, match="compressed"):
        read_table(garbage)
    whole = gzip.compress(b"t,lat,lon\n" + b"0,1,2\n" * 5000)
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(InputError, match="compressed"):
        read_table(cut)


def test_parquet_garbage_and_truncation(tmp_path: Path) -> None:
    garbage = tmp_path / "g.parquet"
    garbage.write_bytes(b"PAR1 not really")
    with pytest.raises(InputError, match="not a readable Parquet file"):
        read_table(garbage)
    good = tmp_path / "good.parquet"
    write_table(drive(), good)
    cut = tmp_path / "cut.parquet"
    cut.write_bytes(good.read_bytes()[:-40])
    with pytest.raises(InputError, match="not a readable Parquet file"):
        read_table(cut)


# --- formats -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("a.csv", "csv"),
        ("a.CSV.gz", "csv"),
        ("a.txt", "csv"),
        ("a.pq", "parquet"),
        ("a.parquet", "parquet"),
        ("a.gpx", "gpx"),
        ("a.nmea", "nmea"),
        ("a.nma", "nmea"),
        ("a.log", "nmea"),
    ],
)
def test_format_from_extension(name: str, expected: str) -> None:
    assert resolve_format(name) == expected


def test_format_sniffed_for_unknown_extension(tmp_path: Path) -> None:
    cases = {
        "a.dat": (b"<?xml version='1.0'?><gpx/>", "gpx"),
        "b.dat": (b"$GPGGA,", "nmea"),
        "c.dat": (b"PAR1....", "parquet"),
        "d.dat": (b"t,lat,lon\n", "csv"),
    }
    for name, (content, expected) in cases.items():
        (tmp_path / name).write_bytes(content)
        assert resolve_format(tmp_path / name) == expected


def test_unknown_format_name() -> None:
    with pytest.raises(ConfigError, match="unknown format 'xls'"):
        resolve_format("a.csv", "xls")


def test_write_needs_a_known_format(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot tell the output format"):
        write_table(drive(), tmp_path / "out.dat")
    with pytest.raises(ConfigError, match="writing gpx is not supported"):
        write_table(drive(), tmp_path / "out.gpx")


@pytest.mark.parametrize("name", ["out.csv", "out.csv.gz", "out.parquet"])
def test_round_trip(tmp_path: Path, name: str) -> None:
    frame = drive()
    frame.insert(0, "drive", ["a"] * 50 + ["b"] * 50)
    frame["t"] = frame["t"] + 0.123456789
    path = tmp_path / name
    write_table(frame, path)
    back = read_table(path).frame
    assert list(back.columns) == list(frame.columns)
    pd.testing.assert_frame_equal(to_fixes(back), to_fixes(frame), check_exact=True)


# --- streaming -----------------------------------------------------------------


def test_chunks_keep_rows_and_lines(tmp_path: Path) -> None:
    path = bad_row_57_csv(tmp_path)
    chunks = list(iter_csv_tables(path, chunksize=20))
    assert [len(c.frame) for c in chunks] == [20, 20, 20, 20, 20]
    assert [(c.row_offset, c.first_line) for c in chunks] == [
        (0, 2),
        (20, 22),
        (40, 42),
        (60, 62),
        (80, 82),
    ]
    with pytest.raises(InputError) as info:
        to_fixes(chunks[2])
    assert (info.value.row, info.value.line, info.value.column) == (57, 58, "lat")
    good = [to_fixes(c) for i, c in enumerate(chunks) if i != 2]
    assert sum(len(g) for g in good) == 80


def test_chunks_concatenate_to_the_whole(tmp_path: Path) -> None:
    path = tmp_path / "d.csv"
    drive(95).to_csv(path, index=False)
    chunks = [c.frame for c in iter_csv_tables(path, chunksize=10)]
    pd.testing.assert_frame_equal(pd.concat(chunks), read_table(path).frame)


def test_chunked_structure_error_comes_first(tmp_path: Path) -> None:
    path = write_text(tmp_path / "d.csv", "t,lat,lon\n" + "0,1,2\n" * 50 + "1,2\n")
    with pytest.raises(InputError, match="fields where") as info:
        iter_csv_tables(path, chunksize=10)
    assert info.value.line == 52


@pytest.mark.parametrize("size", [0, -1, 2.5, True])
def test_chunksize_must_be_positive_int(tmp_path: Path, size: object) -> None:
    with pytest.raises(ConfigError, match="chunksize"):
        iter_csv_tables(tmp_path / "x.csv", chunksize=size)  # type: ignore[arg-type]


# --- property ------------------------------------------------------------------

_finite = {"allow_nan": False, "allow_infinity": False}


@st.composite
def frames(draw: st.DrawFn) -> pd.DataFrame:
    n = draw(st.integers(1, 30))
    floats = st.floats(width=64, **_finite)
    return pd.DataFrame(
        {
            "vehicle": draw(
                st.lists(
                    st.sampled_from(["a", "b b", "007", "7", "x,y", "ü"]), min_size=n, max_size=n
                )
            ),
            "t": draw(st.lists(st.floats(0, 4e9, **_finite), min_size=n, max_size=n)),
            "lat": draw(st.lists(st.floats(-90, 90, **_finite), min_size=n, max_size=n)),
            "lon": draw(st.lists(st.floats(-180, 180, **_finite), min_size=n, max_size=n)),
            "speed": draw(
                st.lists(st.one_of(floats, st.just(float("nan"))), min_size=n, max_size=n)
            ),
        }
    )


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(frame=frames())
def test_csv_round_trip_gives_the_same_fixes(tmp_path: Path, frame: pd.DataFrame) -> None:
    path = tmp_path / "p.csv"
    write_table(frame, path)
    pd.testing.assert_frame_equal(read_fixes(path), to_fixes(frame), check_exact=True)


def test_big_chunk_with_late_text_value(tmp_path: Path) -> None:
    # pandas types long files in pieces unless told not to, and warns about
    # (warnings are errors here) a column that is numbers first, text later.
    path = write_text(tmp_path / "long.csv", "t,lat,lon\n" + "0,1,2\n" * 300_000 + "x,1,2\n")
    (chunk,) = iter_csv_tables(path, chunksize=400_000)
    with pytest.raises(InputError) as info:
        to_fixes(chunk)
    assert (info.value.row, info.value.line, info.value.column) == (300_001, 300_002, "t")


def test_text_in_a_seconds_column_names_its_row(tmp_path: Path) -> None:
    path = write_text(tmp_path / "t.csv", "t,lat,lon\n0,1,2\n1,1,2\nnoon,1,2\n3,1,2\n")
    with pytest.raises(InputError, match="not a time") as info:
        read_fixes(path)
    assert (info.value.row, info.value.line, info.value.column) == (3, 4, "t")
