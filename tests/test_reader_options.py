"""Reader options: say what a file holds where guessing is not good enough (issue 14).

``--decimal``, ``--time-format``, ``--skip-rows`` and ``--speed-unit`` on every
command that reads tracks, and the same as keyword arguments of the readers;
errors name the flag on the command line and the argument in Python.
"""

from __future__ import annotations

import json
from pathlib import Path

import click
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps import ConfigError, InputError, iter_csv_tables, read_fixes, read_table
from gradgps._cli import main

READER_FLAGS = ("--decimal", "--time-format", "--skip-rows", "--speed-unit")


def run(*args: str) -> click.testing.Result:
    return CliRunner().invoke(main, list(args))


def summary(*args: str) -> dict[str, object]:
    result = run("info", *args, "--json")
    assert result.exit_code == 0, result.output
    data: dict[str, object] = json.loads(result.output)
    return data


def one_error_line(result: click.testing.Result) -> str:
    """The one ``error:`` line (detect's progress bar may have drawn on stderr before it)."""
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.output.splitlines()
    assert [line for line in lines if line.startswith("error: ")] == lines[-1:], result.output
    return lines[-1]


@pytest.mark.parametrize("command", ["detect", "detect-fleet", "info", "inject", "train"])
def test_every_reading_command_has_the_options_with_their_defaults(command: str) -> None:
    text = " ".join(run(command, "--help").output.split())
    for flag in READER_FLAGS:
        assert flag in text
    assert "[default: m/s, or the unit the column name says" in text
    assert "[default: automatic" in text
    assert "[default: sniffed per column" in text
    assert "[default: 0, or 1 when the first line is only a number]" in text


def test_decimal_comma_forced_and_refused(tmp_path: Path) -> None:
    path = tmp_path / "eu.csv"
    path.write_text("t;lat;lon\n0;48,1375;11,5755\n1;48,1376;11,5756\n2;48,1377;11,5757\n")
    data = summary(str(path), "--decimal", ",")
    total = data["total"]
    assert isinstance(total, dict)
    assert (total["lat_min"], total["lat_max"]) == (48.1375, 48.1377)
    out = tmp_path / "out.csv"
    detected = run("detect", str(path), "--decimal", ",", "-o", str(out))
    assert detected.exit_code == 0, detected.output
    assert pd.read_csv(out, sep=",")["lat_clean"].round(4).tolist() == [48.1375, 48.1376, 48.1377]
    # "." turns the guess off: a comma is then an error, not a silently different number.
    refused = one_error_line(run("info", str(path), "--decimal", "."))
    assert "row 1 (line 2), column 'lat': not a number" in refused
    assert "'48,1375'" in refused


def test_time_format_day_first_with_seconds(tmp_path: Path) -> None:
    path = tmp_path / "de.csv"
    path.write_text(
        "time,lat,lon\n"
        "01.02.2026 10:00:00,48.1,11.5\n01.02.2026 10:00:01,48.1,11.5001\n"
        "01.02.2026 10:00:02,48.1,11.5002\n"
    )
    data = summary(str(path), "--time-format", "%d.%m.%Y %H:%M:%S")
    total = data["total"]
    assert isinstance(total, dict)
    assert total["start_s"] == pd.Timestamp("2026-02-01 10:00:00", tz="UTC").timestamp()
    assert total["duration_s"] == 2.0
    # The same format read month first is another day: the format, not a guess, decides.
    month_first = summary(str(path), "--time-format", "%m.%d.%Y %H:%M:%S")["total"]
    assert isinstance(month_first, dict)
    assert month_first["start_s"] == pd.Timestamp("2026-01-02 10:00:00", tz="UTC").timestamp()


def test_time_not_matching_the_format_is_one_line_naming_row_and_value(tmp_path: Path) -> None:
    path = tmp_path / "mixed.csv"
    path.write_text(
        "time,lat,lon\n23.11.2026 10:00:00,48.1,11.5\n2026-11-23 10:00:01,48.1,11.5001\n"
    )
    text = one_error_line(
        run(
            "detect", str(path), "-o", str(tmp_path / "o.csv"), "--time-format", "%d.%m.%Y %H:%M:%S"
        )
    )
    assert f"{path}: row 2 (line 3), column 'time'" in text
    assert "'2026-11-23 10:00:01' does not match --time-format '%d.%m.%Y %H:%M:%S'" in text
    # From Python the same error names the keyword argument, not the flag.
    with pytest.raises(InputError, match=r"does not match time_format= ") as err:
        read_fixes(path, time_format="%d.%m.%Y %H:%M:%S")
    assert "--time-format" not in str(err.value)
    assert err.value.row == 2
    no_directive = one_error_line(run("info", str(path), "--time-format", "dd.mm.yyyy"))
    assert "--time-format 'dd.mm.yyyy' has no %-directive" in no_directive


def test_skip_rows_skips_a_leading_count_line(tmp_path: Path) -> None:
    # A count line the guess cannot see (not a bare number) is skipped only when asked.
    path = tmp_path / "logger.csv"
    path.write_text("points: 2\nt,lat,lon\n0,48.1,11.5\n1,48.1,11.5001\n")
    assert summary(str(path), "--skip-rows", "1")["n_points"] == 2
    unskipped = one_error_line(run("info", str(path)))
    assert "row 1 (line 2): 3 fields where the header has 1" in unskipped
    too_many = one_error_line(run("info", str(path), "--skip-rows", "9"))
    assert "no header line after the 9 skipped lines" in too_many
    assert "--skip-rows" in too_many
    # The chunked reader skips them too, and counts lines from the file's start.
    chunks = iter_csv_tables(path, 1, skip_rows=1)
    assert chunks.n_rows == 2
    assert [t.first_line for t in chunks] == [3, 4]


def test_speed_unit_converts_to_metres_per_second(tmp_path: Path) -> None:
    path = tmp_path / "kmh.csv"
    path.write_text("t,lat,lon,speed\n0,48.1,11.5,36\n1,48.1,11.5001,72\n")
    total = summary(str(path), "--speed-unit", "km/h")["total"]
    assert isinstance(total, dict)
    assert total["speed"]["max"] == pytest.approx(20.0)
    assert summary(str(path))["total"]["speed"]["max"] == 72.0  # type: ignore[index]
    # The Python API: the same settings as keyword arguments, kept on the table.
    fixes = read_fixes(path, speed_unit="knots")
    assert fixes["speed"].tolist() == pytest.approx([36 * 0.514444, 72 * 0.514444])
    # A named unit wins over the one a column name says (speed_kmh holding m/s).
    named = tmp_path / "named.csv"
    named.write_text("t,lat,lon,speed_kmh\n0,48.1,11.5,10\n")
    assert read_fixes(named)["speed"].tolist() == pytest.approx([10 / 3.6])
    assert read_fixes(named, speed_unit="m/s")["speed"].tolist() == [10.0]


def test_python_errors_name_arguments_and_options_apply_only_where_they_mean_something(
    tmp_path: Path,
) -> None:
    path = tmp_path / "t.csv"
    path.write_text("t,lat,lon\n0,48.1,11.5\n")
    with pytest.raises(ConfigError, match=r"speed_unit= must be one of m/s, km/h, mph, knots"):
        read_fixes(path, speed_unit="kmh")
    with pytest.raises(ConfigError, match=r"decimal= must be '\.' or ','"):
        read_fixes(path, decimal=";")
    with pytest.raises(ConfigError, match=r"skip_rows= must be a whole number >= 0"):
        read_fixes(path, skip_rows=-1)
    gpx = tmp_path / "t.gpx"
    gpx.write_text('<?xml version="1.0"?><gpx version="1.1"></gpx>')
    with pytest.raises(ConfigError, match=r"skip_rows= applies to CSV files, not to gpx"):
        read_fixes(gpx, skip_rows=1)
    text = one_error_line(run("info", str(gpx), "--speed-unit", "mph"))
    assert "--speed-unit applies to CSV and Parquet files, not to gpx" in text


def test_follow_and_inject_refuse_what_they_cannot_honour(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("t,lat,lon\n0,48.1,11.5\n")
    follow = run("detect", "--follow", str(path), "--speed-unit", "km/h")
    assert follow.exit_code == 2
    assert "read files, not --follow" in follow.output
    inject = run(
        "inject", str(path), "--protocol", "grad", "-o", str(tmp_path / "o.csv"), "--decimal", ","
    )
    assert inject.exit_code == 2
    assert "--decimal: not supported by inject" in inject.output


def test_an_option_that_does_not_apply_is_refused_in_chunked_mode_too(tmp_path: Path) -> None:
    """Parquet is read chunk by chunk (in the largest chunks with --chunk-size 0); --skip-rows
    (CSV only) must be refused there exactly as the whole-file reader refuses skip_rows=,
    never silently ignored."""
    path = tmp_path / "t.parquet"
    pd.DataFrame({"t": [0.0, 1.0, 2.0], "lat": 48.1, "lon": 11.5}).to_parquet(path)
    out = str(tmp_path / "o.csv")
    for chunked in ([], ["--chunk-size", "0"]):
        text = one_error_line(run("detect", str(path), "-o", out, "--skip-rows", "1", *chunked))
        assert "--skip-rows applies to CSV files, not to parquet" in text
    with pytest.raises(ConfigError, match="skip_rows= applies to CSV files, not to parquet"):
        read_table(path, skip_rows=1)
