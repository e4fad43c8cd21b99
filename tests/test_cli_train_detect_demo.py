"""The main job's commands end to end: train on the user's own clean logs, detect, demo."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
from click.testing import CliRunner

from gradgps import simulate_fleet
from gradgps._cli import main
from gradgps._grad.detector import Detector


def test_train_on_own_logs_then_detect_with_that_model(tmp_path: Path) -> None:
    logs = tmp_path / "mylogs.csv"
    simulate_fleet(5, 3.0, 1.0, seed=21).to_csv(logs, index=False)
    model = tmp_path / "model"
    res = CliRunner().invoke(
        main,
        [
            "train",
            "--data",
            str(logs),
            "--protocol",
            "grad",
            "-o",
            str(model),
            "--time-budget",
            "5",
            "--max-epochs",
            "2",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "training points" in res.output
    cfg = json.loads((model / "config.json").read_text())
    assert cfg["mode"] == "stream"
    assert cfg["training"]["data"]["source"] == str(logs)
    out = tmp_path / "out.csv"
    res = CliRunner().invoke(main, ["detect", str(logs), "-o", str(out), "--model", str(model)])
    assert res.exit_code == 0, res.output
    written = pd.read_csv(out, keep_default_na=False)
    original = pd.read_csv(logs)
    assert len(written) == len(original)
    assert list(written.columns[: len(original.columns)]) == list(original.columns)
    for col in (
        "anomaly",
        "score",
        "bias_type",
        "time_type",
        "lat_clean",
        "lon_clean",
        "alert",
        "invalid_reason",
    ):
        assert col in written.columns
    assert Detector(model).model_.checksum == cfg["weights_sha256"]


def test_train_needs_data(tmp_path: Path) -> None:
    res = CliRunner().invoke(main, ["train", "-o", str(tmp_path / "m")])
    assert res.exit_code == 2
    assert "nothing to train on" in res.output


def test_demo_prints_scores_and_writes_its_report(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    res = CliRunner().invoke(main, ["demo", "--tracks", "2", "--minutes", "5", "--out", str(out)])
    assert res.exit_code == 0, res.output
    for text in ("precision", "recall", "anomaly", "bias type", "time type", "RMSE", "us per fix"):
        assert text in res.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["fixes"] == 600
    assert 0.0 <= metrics["scores"]["anomaly"]["f1"] <= 1.0
    assert (out / "detections.csv").is_file()
