"""``gradgps inject`` and ``gradgps bench`` through the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._cli import main
from gradgps._data.datasets import load_dataset

BLOCK_KEYS = {
    "anomaly",
    "window",
    "window_steps",
    "normal",
    "event_recall",
    "detection_delay_median",
    "false_alarms_per_hour",
    "bias_type_accuracy",
    "time_type_accuracy",
    "recovery_rmse_m",
    "corrupted_rmse_m",
    "us_per_point",
}


@pytest.fixture
def small_csv(shared_data: Path, tmp_path: Path) -> Path:
    path = tmp_path / "drive.csv"
    load_dataset("driveplotr", "test", data_dir=shared_data).to_csv(path, index=False)
    return path


@pytest.mark.shared
@pytest.mark.parametrize("protocol", ["grad", "gnss", "sensor-grid"])
def test_inject_writes_the_same_bytes_for_the_same_seed(
    small_csv: Path, tmp_path: Path, protocol: str
) -> None:
    runner = CliRunner()
    outs = []
    for k in range(2):
        out = tmp_path / f"out{k}.csv"
        res = runner.invoke(
            main, ["inject", str(small_csv), "--protocol", protocol, "--seed", "4", "-o", str(out)]
        )
        assert res.exit_code == 0, res.output
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert "achieved fault rates" in res.output
    assert {"grad": "intermittent", "gnss": "multipath", "sensor-grid": "drift"}[protocol] in (
        res.output
    )
    table = pd.read_csv(tmp_path / "out0.csv")
    original = pd.read_csv(small_csv)
    assert list(table.columns[: original.shape[1]]) == list(original.columns)
    assert "label_anomaly" in table.columns


@pytest.mark.shared
def test_inject_sensor_grid_row_and_errors(small_csv: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "o.csv"
    res = runner.invoke(
        main,
        [
            "inject",
            str(small_csv),
            "--protocol",
            "sensor-grid",
            "--row",
            "drift-4-20",
            "--seed",
            "0",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert set(pd.read_csv(out)["label_type"]) == {"none", "drift"}
    res = runner.invoke(
        main,
        [
            "inject",
            str(small_csv),
            "--protocol",
            "sensor-grid",
            "--row",
            "nope",
            "--seed",
            "0",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code != 0
    assert "known rows" in res.output
    res = runner.invoke(
        main,
        [
            "inject",
            str(small_csv),
            "--protocol",
            "grad",
            "--row",
            "bias-5-3",
            "--seed",
            "0",
            "-o",
            str(out),
        ],
    )
    assert res.exit_code != 0
    assert "--row applies to --protocol sensor-grid only" in res.output


@pytest.mark.shared
def test_bench_grad_speed_gate_writes_the_report(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.json"
    res = CliRunner().invoke(
        main,
        [
            "bench",
            "--protocol",
            "grad",
            "--dataset",
            "driveplotr",
            "--split",
            "test",
            "--seed",
            "0",
            "--detector",
            "speed-gate",
            "--json",
            str(out),
            "--data-dir",
            str(shared_data),
        ],
    )
    assert res.exit_code == 0, res.output
    report = json.loads(out.read_text())
    assert {k: report[k] for k in ("protocol", "dataset", "split", "seed")} == {
        "protocol": "grad",
        "dataset": "driveplotr",
        "split": "test",
        "seed": 0,
    }
    block = report["results"]["speed-gate"]
    assert set(block) == BLOCK_KEYS
    assert set(block["anomaly"]) == {"precision", "recall", "f1"}
    assert block["bias_type_accuracy"] is None  # the gate does not classify
    assert block["time_type_accuracy"] is None
    assert 0 < block["anomaly"]["f1"] < 1
    assert block["recovery_rmse_m"] < block["corrupted_rmse_m"]
    assert "speed-gate" in res.output


@pytest.mark.shared
def test_bench_sensor_grid_has_a_block_per_row(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.json"
    res = CliRunner().invoke(
        main,
        [
            "bench",
            "--protocol",
            "sensor-grid",
            "--dataset",
            "driveplotr",
            "--split",
            "validation",
            "--detector",
            "speed-gate",
            "--json",
            str(out),
            "--data-dir",
            str(shared_data),
        ],
    )
    assert res.exit_code == 0, res.output
    rows = json.loads(out.read_text())["results"]["speed-gate"]
    assert len(rows) == 20
    assert {"instant-25", "bias-5-3", "drift-4-20", "mixed"} <= set(rows)
    assert all(set(b) == BLOCK_KEYS for b in rows.values())


@pytest.mark.shared
def test_bench_sensor_grid_options_rows_window_offset_and_fix_speed(
    shared_data: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out.json"
    args = ["bench", "--protocol", "sensor-grid", "--dataset", "driveplotr"]
    args += ["--split", "validation", "--detector", "speed-gate", "--data-dir", str(shared_data)]
    args += ["--rows", "instant-25,constant-1-10", "--window", "5", "--constant", "offset"]
    res = CliRunner().invoke(main, [*args, "--fix-speed", "--json", str(out)])
    assert res.exit_code == 0, res.output
    report = json.loads(out.read_text())
    assert (report["constant"], report["fix_speed"], report["window_steps"]) == ("offset", True, 5)
    assert list(report["results"]["speed-gate"]) == ["instant-25", "constant-1-10"]
    ref = report["reference"]["constant-1-10"]
    share = ref["faulty_share"]
    assert ref["flag_all_f1"] == pytest.approx(2 * share / (1 + share))
    assert ref["flag_all_window_f1"] > ref["flag_all_f1"]  # windows of 5 catch more
    res = CliRunner().invoke(main, [*args[:-4], "--rows", "nope", "--json", str(out)])
    assert res.exit_code != 0
    assert "unknown rows" in res.output


def test_bench_unknown_detector_and_missing_data_fail_clearly(tmp_path: Path) -> None:
    runner = CliRunner()
    res = runner.invoke(
        main,
        [
            "bench",
            "--protocol",
            "grad",
            "--dataset",
            "driveplotr",
            "--detector",
            "speed-gate",
            "--data-dir",
            str(tmp_path / "none"),
        ],
    )
    assert res.exit_code != 0
    assert "GRADGPS_DATA" in res.output
    res = runner.invoke(
        main,
        [
            "bench",
            "--protocol",
            "grad",
            "--dataset",
            "driveplotr",
            "--detector",
            "speed-gate,magic",
            "--data-dir",
            str(tmp_path),
        ],
    )
    assert res.exit_code != 0
    assert "unknown detector 'magic'; known detectors: speed-gate" in res.output


def test_bench_reports_grad_type_confusions(shared_data: Path, tmp_path: Path) -> None:
    """The shipped model names bias and time types, so the report carries both confusion matrices."""
    out = tmp_path / "out.json"
    args = [
        "bench",
        "--protocol",
        "grad",
        "--dataset",
        "driveplotr",
        "--split",
        "test",
        "--seed",
        "0",
        "--detector",
        "grad-default,rema",
        "--json",
        str(out),
        "--data-dir",
        str(shared_data),
    ]
    res = CliRunner().invoke(main, args)
    assert res.exit_code == 0, res.output
    results = json.loads(out.read_text())["results"]
    grad = results["grad-default"]
    assert set(grad["bias_type_confusion"]) == {"noise", "jump"}
    assert set(grad["time_type_confusion"]) == {"transient", "intermittent", "permanent"}
    detected = sum(sum(row.values()) for row in grad["bias_type_confusion"].values())
    assert detected > 0
    assert grad["bias_type_accuracy"] is not None
    assert "bias_type_confusion" not in results["rema"]  # REMA names no bias type
    assert results["rema"]["bias_type_accuracy"] is None
    assert "time type of detected faults" in res.output
