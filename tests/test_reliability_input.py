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
