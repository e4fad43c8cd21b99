"""``gradgps info``, the summary behind it, and clean CLI errors."""

from __future__ import annotations

import json
from pathlib import Path

import click
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps import ConfigError, InputError, ModelError, to_fixes
from gradgps._cli import main
from gradgps._cli.errors import ErrorReportingGroup
from gradgps._io.nmea import nmea_checksum
from gradgps._tracks.geo import LocalFrame
from gradgps._tracks.summary import summarize


def run(*args: str) -> click.testing.Result:
    return CliRunner().invoke(main, list(args))


@pytest.mark.shared
def test_driveplotr_counts(shared_data: Path) -> None:
    result = run("info", str(shared_data / "driveplotr_nds.csv"), "--track-col", "drive")
    assert result.exit_code == 0, result.output
    assert "tracks: 28  points: 23,187" in result.output


@pytest.mark.shared
def test_tuc_counts_and_json(shared_data: Path) -> None:
    path = str(shared_data / "tuc_urban_gt.csv")
    result = run("info", path, "--track-col", "trace", "--time-col", "t_rel")
    assert result.exit_code == 0, result.output
    assert "tracks: 5  points: 25,289" in result.output
    data = json.loads(
        run("info", path, "--track-col", "trace", "--time-col", "t_rel", "--json").output
    )
    assert (data["n_tracks"], data["n_points"]) == (5, 25289)
    rates = {t["track"]: round(t["rate_hz"], 3) for t in data["tracks"]}
    assert rates["chemnitz_city"] == 4.0  # 0.248 s and 0.252 s steps alternate
    assert rates["berlin_gendarmenmarkt"] == 5.0


def test_bad_value_is_one_clean_line_with_exit_2(tmp_path: Path) -> None:
    frame = pd.DataFrame(
        {"t": np.arange(100.0), "lat": ["41.25"] * 100, "lon": np.full(100, -95.9)}
    )
    frame.loc[56, "lat"] = "north"
    path = tmp_path / "bad.csv"
    frame.to_csv(path, index=False)
    result = run("info", str(path))
    assert result.exit_code == 2
    assert result.output.count("\n") == 1
    assert result.output.startswith("error: ")
    assert "row 57 (line 58), column 'lat': not a number" in result.output
    assert "Traceback" not in result.output


def test_missing_file_is_clean(tmp_path: Path) -> None:
    result = run("info", str(tmp_path / "nope.csv"))
    assert result.exit_code == 2
    assert result.output == f"error: {tmp_path / 'nope.csv'}: no such file. check the path\n"


def test_nmea_rejected_sentences_are_printed(tmp_path: Path) -> None:
    lines = []
    for second in range(6):
        for body in (
            f"GPRMC,1200{second:02d},A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W",
            f"GPGGA,1200{second:02d},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
        ):
            lines.append(f"${body}*{nmea_checksum(body):02X}")
    for i in (1, 4, 9):
        lines[i] = lines[i][:-2] + ("00" if lines[i][-2:] != "00" else "01")
    path = tmp_path / "drive.nmea"
    path.write_text("\n".join(lines) + "\n")
    result = run("info", str(path))
    assert result.exit_code == 0, result.output
    assert "tracks: 1  points: 6" in result.output
    assert "rejected sentences: 3" in result.output
    assert "note: line 2: GGA checksum mismatch" in result.output
    assert json.loads(run("info", str(path), "--json").output)["rejected"] == 3


def test_format_and_column_options(tmp_path: Path) -> None:
    path = tmp_path / "data.dat"
    path.write_text("when,y,x,who\n0,1,2,a\n1,1,2,a\n0,1,2,b\n")
    result = run(
        "info",
        str(path),
        "--format",
        "csv",
        "--time-col",
        "when",
        "--lat-col",
        "y",
        "--lon-col",
        "x",
        "--track-col",
        "who",
    )
    assert result.exit_code == 0, result.output
    assert "tracks: 2  points: 3" in result.output


def test_summary_numbers_on_a_known_track() -> None:
    # 1 Hz due north at 10 m/s, one 10 s dropout, one row with no position.
    t = np.r_[np.arange(50.0), np.arange(59.0, 100.0)]
    frame = LocalFrame(48.0, 11.0)
    lat, lon = frame.to_geodetic(np.zeros(t.size), 10.0 * t)
    fixes = to_fixes(pd.DataFrame({"t": t, "lat": lat, "lon": lon}))
    fixes.loc[5, "lat"] = np.nan
    summary = summarize(fixes)
    track = summary.tracks[0]
    # The unusable row leaves a 2 s hole in the usable fixes: a second gap.
    assert (track.points, track.invalid, track.gaps) == (91, 1, 2)
    assert track.rate_hz == 1.0
    assert track.longest_gap_s == 10.0
    assert track.duration_s == 99.0
    assert track.speed is not None
    assert track.speed.source == "implied"
    assert track.speed.median == pytest.approx(10.0, rel=5e-3)
    assert summary.invalid_reasons == {"latitude missing or not finite": 1}
    assert summary.total.lat_min == pytest.approx(48.0)


def test_summary_reported_speed_and_totals() -> None:
    fixes = to_fixes(
        pd.DataFrame(
            {
                "track": ["a"] * 3 + ["b"] * 4,
                "t": [0.0, 1.0, 2.0, 0.0, 0.5, 1.0, 3.0],
                "lat": [1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 2.0],
                "lon": [1.0, 1.0, 1.0, 3.0, 3.0, 3.0, 3.0],
                "speed": [1.0, 2.0, 3.0, np.nan, np.nan, np.nan, np.nan],
            }
        )
    )
    summary = summarize(fixes)
    a, b = summary.tracks
    assert a.speed is not None
    assert (a.speed.source, a.speed.max) == ("reported", 3.0)
    assert b.speed is not None
    assert b.speed.source == "implied"
    assert (b.rate_hz, b.gaps, b.longest_gap_s) == (2.0, 1, 2.0)
    total = summary.total
    assert (total.points, total.gaps, total.duration_s) == (7, 1, 5.0)
    assert total.speed is not None
    assert total.speed.source == "mixed"
    assert total.median_step_s == 1.0  # steps 1, 1, 0.5, 0.5, 2
    assert (total.lat_min, total.lat_max, total.lon_min, total.lon_max) == (1.0, 2.0, 1.0, 3.0)


def test_errors_become_one_line_with_their_exit_code() -> None:
    group = ErrorReportingGroup("g")
    raised = {
        "input": InputError("bad", source="f.csv", row=3, column="lat"),
        "config": ConfigError("threshold must be positive"),
        "model": ModelError("model directory is missing weights.npz"),
    }
    for name, exc in raised.items():

        def command(exc: Exception = exc) -> None:
            raise exc

        group.add_command(click.Command(name, callback=command))
    runner = CliRunner()
    expected = {
        "input": (2, "error: f.csv: row 3, column 'lat': bad\n"),
        "config": (2, "error: threshold must be positive\n"),
        "model": (1, "error: model directory is missing weights.npz\n"),
    }
    for name, (code, text) in expected.items():
        result = runner.invoke(group, [name])
        assert (result.exit_code, result.output) == (code, text)
