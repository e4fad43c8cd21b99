"""``gradgps simulate`` through click's CliRunner."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from click.testing import CliRunner

from gradgps import simulate_drive, simulate_fleet
from gradgps._cli import main


def test_simulate_writes_csv_matching_the_api(tmp_path: Path) -> None:
    out = tmp_path / "drive.csv"
    result = CliRunner().invoke(
        main, ["simulate", "--minutes", "2", "--rate", "1", "--seed", "4", "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert "120 fixes" in result.output
    assert len(result.output.strip().splitlines()) == 1
    expected = simulate_drive(2, 1.0, 4)
    expected.to_csv(tmp_path / "expected.csv", index=False)
    assert out.read_bytes() == (tmp_path / "expected.csv").read_bytes()


def test_simulate_fleet_to_parquet_without_imu(tmp_path: Path) -> None:
    out = tmp_path / "fleet.parquet"
    result = CliRunner().invoke(
        main,
        [
            "simulate",
            "--minutes",
            "1",
            "--rate",
            "10",
            "--tracks",
            "25",
            "--no-imu",
            "-o",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    written = pd.read_parquet(out)
    assert "accel_x" not in written.columns
    assert written["track"].nunique() == 25
    pd.testing.assert_frame_equal(
        written, simulate_fleet(25, 1, 10.0, 0, imu=False), check_dtype=False
    )


def test_simulate_rejects_unknown_extension_and_bad_minutes(tmp_path: Path) -> None:
    runner = CliRunner()
    result = runner.invoke(main, ["simulate", "-o", str(tmp_path / "drive.txt")])
    assert result.exit_code == 2
    assert ".csv or .parquet" in result.output
    result = runner.invoke(main, ["simulate", "--minutes", "0", "-o", str(tmp_path / "d.csv")])
    assert result.exit_code == 2
    assert "--minutes" in result.output
