"""``benchmarks/run_all.py --quick``: the whole bench on tiny data; checks the output's shape, not numbers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd

from _robustness_support import write_tiny_new_drives
from gradgps import simulate_fleet

REPO = Path(__file__).resolve().parents[1]
GRID_ROWS = 20  # the paper's 19 rows plus mixed


def _tiny_data(folder: Path) -> None:
    """DrivePlotR- and TUC-shaped files from the simulator: a few two-minute drives per split."""
    fleet = simulate_fleet(6, 2.0, 1.0, seed=5)
    ids = dict(zip(sorted(fleet["track"].unique()), [1, 2, 9, 10, 11, 14], strict=True))
    dp = pd.DataFrame(
        {
            "drive": fleet["track"].map(ids),
            "t": fleet["t"].round().astype("int64"),
            "lat": fleet["lat"],
            "lon": fleet["lon"],
            "speed_mps": fleet["speed"],
            "heading_deg": fleet["heading"],
            "accel_x_g": fleet["accel_x"] / 9.80665,
            "gyro_z_dps": fleet["yaw_rate"],
        }
    )
    dp.to_csv(folder / "driveplotr_nds.csv", index=False)
    names = dict(
        zip(
            sorted(fleet["track"].unique()),
            ["a", "b", "frankfurt_westend_tower", "c", "chemnitz_city", "d"],
            strict=True,
        )
    )
    tuc = pd.DataFrame(
        {
            "trace": fleet["track"].map(names),
            "t_rel": fleet["t"] - fleet["t"].min(),
            "lat": fleet["lat"],
            "lon": fleet["lon"],
            "speed_mps": fleet["speed"],
            "heading_deg": fleet["heading"],
        }
    )
    tuc.to_csv(folder / "tuc_urban_gt.csv", index=False)


def test_quick_bench_writes_every_table(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    _tiny_data(data)
    write_tiny_new_drives(data)
    results, markdown = tmp_path / "results", tmp_path / "BENCHMARKS.md"
    markdown.write_text("# Benchmarks\n\n## Memory\n\nkept\n")
    env = {
        **os.environ,
        "GRADGPS_CACHE": str(tmp_path / "cache"),
        "PYTHONPATH": str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
    }
    subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "run_all.py"),
            "--quick",
            "--data-dir",
            str(data),
            "--results",
            str(results),
            "--markdown",
            str(markdown),
        ],
        check=True,
        env=env,
        capture_output=True,
        timeout=600,
    )
    report = json.loads((results / "bench_all_quick.json").read_text())["results"]
    assert set(report) == {
        "grad-driveplotr",
        "grad-tuc",
        "sensor-grid",
        "sweep",
        "speed",
        "robustness",
    }
    robust = json.loads((results / "robustness_grad-default_quick.json").read_text())
    assert robust == report["robustness"]
    assert robust["n_cells"] == len(robust["cells"]) > 0
    methods = {"grad", "grad-default", "rema", "speed-gate", "kf", "cnn", "cnn-kf", "lstm-cnn"}
    for key in ("grad-driveplotr", "grad-tuc"):
        assert set(report[key]["results"]) == methods
        for block in report[key]["results"].values():
            assert set(block["anomaly"]) == {"precision", "recall", "f1"}
    grid = report["sensor-grid"]["results"]
    assert set(grid) == {"grad", "kf", "cnn", "cnn-kf", "lstm-cnn"}
    assert all(len(rows) == GRID_ROWS for rows in grid.values())
    assert set(report["sweep"]) == {"0.25", "0.5", "1.0", "2.0"}
    assert set(report["speed"]) == methods | {"points"}
    assert report["speed"]["kf"]["stream_us_per_point"] > 0
    assert (results / "bench_sweep_quick.png").stat().st_size > 0
    text = markdown.read_text()
    assert "## Memory\n\nkept" in text  # other sections survive
    assert text.count("<!-- bench:start -->") == 1
    assert text.count("<!-- bench:end -->") == 1
    assert "quick mode" in text
    assert text.count("| instant-25 |") == 1
    assert text.count("<!-- robustness:start -->") == text.count("<!-- robustness:end -->") == 1
    assert "| data set | columns | native | 1 Hz | 0.5 Hz |" in text
