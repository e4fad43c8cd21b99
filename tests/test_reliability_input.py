"""Hostile input files (issue 18, items 6 and 7): bounded memory, one ``error:`` line.

On main a CSV line was read whole before the 128 KB field limit applied: a
4 MB ``.csv.gz`` holding a 4 GiB line peaked at 9.4 GB; a header of 10^6
columns took 4.9 GB for a 14 MB file. Lines are now read at most 1 MiB at a
time, and a chunk of a very wide file holds fewer rows.
"""

from __future__ import annotations

import gzip
import tracemalloc
from pathlib import Path

import pytest
from click.testing import CliRunner

from _whole_file import detect_whole
from gradgps import InputError, iter_csv_tables, read_table
from gradgps._cli import main
from gradgps._io.files import MAX_LINE_BYTES
from gradgps._io.read import MAX_CHUNK_CELLS


def _peak(action: object) -> int:
    tracemalloc.start()
    try:
        action()  # type: ignore[operator]
    except InputError:
        pass
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def test_a_huge_line_in_a_gzip_file_is_refused_without_reading_it(tmp_path: Path) -> None:
    path = tmp_path / "long.csv.gz"
    with gzip.open(path, "wb", compresslevel=1) as out:
        out.write(b"t,lat,lon\n1,2,3\n")
        block = b"9" * 2**20
        for _ in range(64):  # a 64 MiB line (the issue's: 4 GiB)
            out.write(block)
        out.write(b"\n")
    with pytest.raises(InputError, match="longer than 1 MiB") as info:
        read_table(path)
    assert "line 3" in str(info.value)
    assert _peak(lambda: read_table(path)) < 8 * MAX_LINE_BYTES


def test_a_header_of_a_million_columns_is_refused_cheaply(tmp_path: Path) -> None:
    path = tmp_path / "wide.csv"
    path.write_text(",".join(f"c{i}" for i in range(10**6)) + "\n")
    assert _peak(lambda: read_table(path)) < 16 * MAX_LINE_BYTES


def test_detect_reports_a_long_line_as_an_error_line(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_bytes(b"t,lat,lon\n1,48,11\n" + b"1" * (MAX_LINE_BYTES + 10) + b"\n")
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o.csv")])
    assert result.exit_code != 0
    assert "error:" in result.output
    assert "longer than 1 MiB" in result.output


def test_a_wide_file_is_read_in_smaller_chunks(tmp_path: Path) -> None:
    columns = 2000
    path = tmp_path / "wide.csv"
    header = "t,lat,lon," + ",".join(f"x{i}" for i in range(columns - 3))
    row = "1,48,11," + ",".join("0" for _ in range(columns - 3))
    path.write_text(header + "\n" + "\n".join([row] * 3000) + "\n")
    chunks = [len(c.frame) for c in iter_csv_tables(path, 200_000)]
    assert sum(chunks) == 3000
    assert max(chunks) <= MAX_CHUNK_CELLS // columns


# --- item 7: tracebacks instead of error lines ------------------------------------------


def _nmea_line(body: str) -> str:
    from gradgps._io.nmea import nmea_checksum

    return f"${body}*{nmea_checksum(body):02X}\n"


def test_checksum_valid_nmea_with_huge_fields_is_a_rejected_sentence(tmp_path: Path) -> None:
    """On main: OverflowError (a 400-digit latitude), ValueError (a 4,300-digit field)."""
    good = [
        _nmea_line(f"GPGGA,1200{i:02d}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
        for i in range(5)
    ]
    bad = [
        _nmea_line("GPGGA,120010.00," + "9" * 400 + ",N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"),
        _nmea_line("GPGGA,120011.00,4807.038,N,01131.000,E,1," + "9" * 4300 + ",0.9,545.4,M,,M,,"),
    ]
    path = tmp_path / "huge.nmea"
    path.write_text("".join(good + bad))
    table = read_table(path)
    assert len(table.frame) == 5
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o.csv")])
    assert result.exit_code == 0, result.output


def test_gga_counts_too_big_for_their_column_are_a_rejected_sentence(tmp_path: Path) -> None:
    """Found by ``make fuzz`` (2,500 cases): a checksum-valid GGA whose fix quality is
    2**63 or 2**64 raised TypeError / OverflowError from pandas' Int64 column; a
    superscript digit passed ``isdigit`` and raised ValueError from ``int``."""
    good = [
        _nmea_line(f"GPGGA,1200{i:02d}.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
        for i in range(5)
    ]
    bad = [
        _nmea_line(
            "GPGGA,120010.00,4807.038,N,01131.000,E,9223372036854775808,08,0.9,545.4,M,,M,,"
        ),
        _nmea_line("GPGGA,120011.00,4807.038,N,01131.000,E,18446744073709551616,08,0.9,5.4,M,,M,,"),
        _nmea_line("GPGGA,120012.00,4807.038,N,01131.000,E,1,99999999999999999999,0.9,5.4,M,,M,,"),
        _nmea_line("GPGGA,120013.00,4807.038,N,01131.000,E,\u00b2,08,0.9,5.4,M,,M,,"),
        _nmea_line("GPGGA,120014.00,4807.038,N,01131.000,E,1,\u00b2,0.9,5.4,M,,M,,"),
    ]
    path = tmp_path / "counts.nmea"
    path.write_text("".join(good + bad), encoding="utf-8")
    table = read_table(path)
    assert len(table.frame) == 5
    assert table.frame["fix_quality"].tolist() == [1] * 5
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(tmp_path / "o.csv")])
    assert result.exit_code == 0, result.output


def test_gpx_and_parquet_times_in_year_1_or_3000_are_read(tmp_path: Path) -> None:
    """On main: OutOfBoundsDatetime tracebacks (year 1 is a common logger placeholder)."""
    import numpy as np
    import pandas as pd

    gpx = tmp_path / "y1.gpx"
    gpx.write_text(
        '<?xml version="1.0"?><gpx version="1.1"><trk><trkseg>'
        '<trkpt lat="48.1" lon="11.5"><time>0001-01-01T00:00:00Z</time></trkpt>'
        '<trkpt lat="48.1" lon="11.5001"><time>2020-01-01T00:00:01Z</time></trkpt>'
        "</trkseg></trk></gpx>"
    )
    parquet = tmp_path / "y1.parquet"
    times = np.array(["0001-01-01", "2020-01-01", "3000-01-01"], dtype="datetime64[us]")
    pd.DataFrame({"time": times, "lat": 48.1, "lon": [11.5, 11.6, 11.7]}).to_parquet(parquet)
    for path, n in ((gpx, 2), (parquet, 3)):
        out = tmp_path / f"{path.stem}.csv"
        result = CliRunner().invoke(main, ["detect", str(path), "-o", str(out)])
        assert result.exit_code == 0, result.output
        assert len(pd.read_csv(out)) == n


def _model_copy(tmp_path: Path) -> Path:
    import shutil

    from gradgps._grad.detector import _default_model_dir

    folder = tmp_path / "model"
    shutil.copytree(_default_model_dir(), folder)
    return folder


def test_an_editor_lock_file_in_the_model_directory_is_ignored(tmp_path: Path) -> None:
    from gradgps import Detector

    folder = _model_copy(tmp_path)
    (folder / ".#config.json").symlink_to(tmp_path / "nowhere")  # what emacs leaves
    assert Detector(folder).update(0.0, 48.1, 11.5).invalid_reason == ""


@pytest.mark.parametrize(
    "config_text",
    ["[" * 100_000 + "]" * 100_000, '{"format_version": ' + "1" * 5000 + "}"],
    ids=["nested 100k deep", "5000-digit integer"],
)
def test_hostile_model_configs_are_model_errors(tmp_path: Path, config_text: str) -> None:
    from gradgps import Detector, ModelError

    folder = _model_copy(tmp_path)
    (folder / "config.json").write_text(config_text)
    with pytest.raises(ModelError, match=r"config\.json"):
        Detector(folder)


def test_an_extra_array_in_the_weights_is_refused_before_it_is_loaded(tmp_path: Path) -> None:
    import hashlib
    import io
    import json
    import zipfile

    from gradgps import Detector, ModelError

    folder = _model_copy(tmp_path)
    data = (folder / "weights.npz").read_bytes()
    buffer = io.BytesIO(data)
    # 256 MiB of zeros (the was 8 GiB), a few hundred KB compressed
    with (
        zipfile.ZipFile(buffer, "a", compression=zipfile.ZIP_DEFLATED) as archive,
        archive.open("extra.npy", "w", force_zip64=True) as member,
    ):
        member.write(b"\x93NUMPY\x01\x00v\x00{'descr': '<f4', 'fortran_order': False, }")
        zeros = bytes(2**20)
        for _ in range(256):
            member.write(zeros)
    data = buffer.getvalue()
    (folder / "weights.npz").write_bytes(data)
    config = json.loads((folder / "config.json").read_text())
    config["weights_sha256"] = hashlib.sha256(data).hexdigest()
    (folder / "config.json").write_text(json.dumps(config))
    tracemalloc.start()
    try:
        with pytest.raises(ModelError, match="unexpected arrays"):
            Detector(folder)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64 * 2**20


def test_a_header_only_file_with_repeated_column_names_is_written(tmp_path: Path) -> None:
    """On main: 'chunk columns ... differ from the first chunk's' (item 8)."""
    path = tmp_path / "header.csv"
    path.write_text("t,lat,lon,x,x\n")
    out = tmp_path / "o.csv"
    result = CliRunner().invoke(main, ["detect", str(path), "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert out.read_text().splitlines()[0].startswith("t,lat,lon,x,x.1,anomaly")


@pytest.mark.parametrize("index", ["time", "two levels", "unnamed"])
def test_a_parquet_file_with_a_stored_index_is_read_in_chunks(tmp_path: Path, index: str) -> None:
    """Issue 18: a Parquet file with a stored index (what pandas writes for a time-indexed
    frame) was read whole, as one chunk, however big. Its chunks now have the whole file's
    columns (the index first, as the whole-file reader makes it), rows and values, and
    ``detect`` gives the whole-file bytes."""
    import numpy as np
    import pandas as pd

    from gradgps._io.read import load_table, table_chunks

    n = 900
    frame = pd.DataFrame(
        {
            "vehicle": np.tile(["a", "b", "c"], n // 3),
            "time": pd.to_datetime(1.7e9 + np.repeat(np.arange(n // 3.0), 3), unit="s"),
            "lat": 48.1 + np.arange(n) * 1e-6,
            "lon": 11.5 + np.zeros(n),
        }
    )
    if index == "time":
        frame = frame.set_index("time")
    elif index == "two levels":
        frame = frame.set_index(["vehicle", "time"])
    else:
        frame.index = pd.Index(np.arange(n) * 2)
    source = tmp_path / "indexed.parquet"
    frame.to_parquet(source, row_group_size=200)
    whole = load_table(source)
    chunks = table_chunks(source, 97)
    tables = list(chunks)
    assert max(len(t.frame) for t in tables) == 97
    assert chunks.header == tuple(whole.frame.columns)
    pd.testing.assert_frame_equal(
        pd.concat([t.frame for t in tables], ignore_index=True), whole.frame
    )
    reference = tmp_path / "whole.csv"
    detect_whole(source, reference)
    out = tmp_path / "out.csv"
    result = CliRunner().invoke(main, ["detect", str(source), "-o", str(out), "--chunk-size", "97"])
    assert result.exit_code == 0, result.output
    assert out.read_bytes() == reference.read_bytes()


def test_parquet_is_read_in_chunks_with_the_same_results(tmp_path: Path) -> None:
    """Parquet input goes through the chunked path (record batches, one row group at a time):
    on main it was read whole, its memory growing with the file. The output equals
    whole-file detection (the library's on the file read whole, ``detect_whole``) byte for
    byte at any chunk size, 0 (the largest) included, with several tracks interleaved, text
    ids, datetime times, a repeated and a backward timestamp."""
    import numpy as np
    import pandas as pd

    from gradgps._io.read import table_chunks

    n = 3000
    rng = np.random.default_rng(4)
    t = 1.7e9 + np.repeat(np.arange(n // 3, dtype=float), 3)
    t[100], t[200] = t[97], t[150]  # repeated, backward (track 1)
    frame = pd.DataFrame(
        {
            "vehicle": np.tile(["a", "b", "c"], n // 3),
            "time": pd.to_datetime(t, unit="s", utc=True),
            "lat": 48.1 + np.arange(n) * 1e-6 + rng.normal(0, 1e-5, n),
            "lon": 11.5 + rng.normal(0, 1e-5, n),
            "note": ["x"] * n,
        }
    )
    source = tmp_path / "fleet.parquet"
    frame.to_parquet(source, index=False, row_group_size=700)
    chunks = list(table_chunks(source, 97, fmt="parquet"))
    assert max(len(c.frame) for c in chunks) == 97
    assert sum(len(c.frame) for c in chunks) == n
    whole = tmp_path / "whole.csv"
    detect_whole(source, whole)
    for size in (0, 1000, 97):
        out = tmp_path / f"out_{size}.csv"
        result = CliRunner().invoke(
            main, ["detect", str(source), "-o", str(out), "--chunk-size", str(size)]
        )
        assert result.exit_code == 0, result.output
        assert out.read_bytes() == whole.read_bytes(), size
    assert pd.read_csv(whole)["invalid_reason"].notna().sum() == 2


def test_parquet_chunks_read_without_pandas_3s_converter(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """pyproject allows pandas 2.2, whose ``pandas.io._util`` has no
    ``arrow_table_to_pandas`` (pandas 3 added it): the chunked Parquet reader must
    still read, through ``to_pandas``, the same numbers a whole read gives."""
    import numpy as np
    import pandas as pd
    import pandas.io._util as pandas_util

    from gradgps._io.read import table_chunks

    frame = pd.DataFrame(
        {
            "t": 1.7e9 + np.arange(50.0),
            "lat": 48.1 + np.arange(50) * 1e-5,
            "lon": 11.5,
            "id": ["a"] * 50,
        }
    )
    source = tmp_path / "d.parquet"
    frame.to_parquet(source, index=False, row_group_size=20)
    monkeypatch.delattr(pandas_util, "arrow_table_to_pandas", raising=False)
    chunks = list(table_chunks(source, 20, fmt="parquet"))
    read = pd.concat([c.frame for c in chunks], ignore_index=True)
    assert [len(c.frame) for c in chunks] == [20, 20, 10]
    for column in ("t", "lat", "lon"):
        np.testing.assert_array_equal(read[column].to_numpy(), frame[column].to_numpy())
    assert read["id"].astype(str).tolist() == frame["id"].tolist()


def test_a_model_saved_before_the_singer_clean_track_asks_to_be_retrained(tmp_path: Path) -> None:
    """Its feature names are today's, its offset tracker's values are not: loading it
    must fail loudly rather than run it on features it never saw."""
    import json

    from gradgps import Detector, ModelError

    folder = _model_copy(tmp_path)
    config = json.loads((folder / "config.json").read_text())
    offset = config["features"]["params"]["pipeline"]["offset"]
    del offset["tau_a"]
    offset["sigma_a"] = 1.5  # as the constant-velocity track saved it
    (folder / "config.json").write_text(json.dumps(config))
    with pytest.raises(ModelError, match=r"no tau_a.*retrain it"):
        Detector(folder)
