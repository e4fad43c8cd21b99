"""REMA tuning and the REMA detectors in the benchmark: CLI round trip, acceptance on real drives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from gradgps._baselines.rema_detector import RemaDetector
from gradgps._cli import main
from gradgps._eval.bench import make_detector, run_bench
from gradgps._exceptions import ConfigError
from gradgps._grad.rema import RemaParams, rema_batch, rema_reference
from gradgps._train.tune_rema import tune_time


@pytest.mark.shared
def test_tune_rema_cli_writes_settings_that_bench_loads(shared_data: Path, tmp_path: Path) -> None:
    grid = tmp_path / "grid.json"
    grid.write_text(
        json.dumps(
            {"min_margin": [3.0, 8.0], "sensitivity": [5.0], "slide_size": [6], "run_growth": [0.5]}
        )
    )
    out = tmp_path / "rema.json"
    table = tmp_path / "table.csv"
    res = CliRunner().invoke(
        main,
        [
            "tune-rema",
            "--dataset",
            "driveplotr",
            "--seeds",
            "0",
            "--grid",
            str(grid),
            "--data-dir",
            str(shared_data),
            "--table",
            str(table),
            "-o",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.output
    assert "2 REMA combinations" in res.output
    settings = json.loads(out.read_text())
    assert settings["rema"]["mode"] == "trend"
    assert settings["rema"]["min_margin"] == 8.0  # 3 m is inside 1 Hz GPS noise
    assert settings["scores"]["seeds"] == [0]
    detector = RemaDetector.from_file(out)
    assert detector.rema.min_margin == 8.0
    assert detector.time.permanent_run == settings["time"]["permanent_run"]
    res = CliRunner().invoke(
        main,
        [
            "bench",
            "--protocol",
            "grad",
            "--dataset",
            "driveplotr",
            "--split",
            "validation",
            "--detector",
            "rema",
            "--rema-params",
            str(out),
            "--data-dir",
            str(shared_data),
        ],
    )
    assert res.exit_code == 0, res.output


def test_tune_rema_cli_rejects_a_bad_grid(tmp_path: Path) -> None:
    grid = tmp_path / "grid.json"
    grid.write_text('{"min_margin": 3}')
    res = CliRunner().invoke(
        main,
        [
            "tune-rema",
            "--dataset",
            "driveplotr",
            "--grid",
            str(grid),
            "-o",
            str(tmp_path / "x.json"),
        ],
    )
    assert res.exit_code != 0
    assert "non-empty lists" in res.output


def test_settings_file_errors_name_the_problem(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"rema": {"min_margin": 5}, "colour": 1}')
    with pytest.raises(ConfigError, match="colour"):
        RemaDetector.from_file(bad)
    with pytest.raises(ConfigError, match="cannot read"):
        RemaDetector.from_file(tmp_path / "missing.json")
    assert RemaDetector.from_dict(RemaDetector().to_dict()) == RemaDetector()


def test_tune_time_prefers_thresholds_matching_the_shapes() -> None:
    flags = [np.r_[np.zeros(5), np.ones(12), np.zeros(5)]]
    truth = [np.array(["none"] * 5 + ["permanent"] * 12 + ["none"] * 5, dtype=object)]
    best, table = tune_time(flags, truth, {"permanent_run": [1, 20]})
    assert best.permanent_run == 1
    assert table["time_type_accuracy"].tolist() == [1.0, 0.0]


def test_known_step_keeps_a_turning_car_in_bounds_and_catches_a_jump() -> None:
    # A car on a circle: the step EMA lags the turn, the reported velocity does not.
    t = np.arange(200.0)
    x = 200.0 * np.sin(t / 20.0)
    step = 10.0 * np.cos(t / 20.0)  # derivative, one point per second
    x[100:103] += 20.0
    prm = RemaParams(mode="trend", min_margin=3.0, slide_size=6)
    with_step = rema_batch(x, prm, known_step=step)
    assert np.flatnonzero(with_step.flag).tolist() == [100, 101, 102]
    ref = rema_reference(x, prm, known_step=step)
    np.testing.assert_allclose(with_step.ema, ref.ema, rtol=1e-9, atol=1e-9)


def test_reacquire_after_consistent_shift_but_not_after_noise() -> None:
    rng = np.random.default_rng(5)
    x = np.cumsum(np.full(300, 10.0)) + rng.normal(0, 0.3, 300)
    shifted = x.copy()
    shifted[100:] += 60.0  # a lasting shift: the new track moves consistently
    prm = RemaParams(mode="trend", min_margin=5.0, reacquire_after=5)
    flags = rema_batch(shifted, prm).flag
    assert flags[100:105].all()
    assert not flags[106:].any()
    noisy = x.copy()
    noisy[100:150] += rng.choice([-1, 1], 50) * rng.uniform(10, 50, 50)
    assert rema_batch(noisy, prm).flag[100:150].sum() >= 45
    assert not rema_batch(noisy, prm).flag[152:].any()
    with pytest.raises(ConfigError, match="reacquire_after"):
        RemaParams(reacquire_after=-1).checked()


def test_make_detector_knows_the_rema_detectors() -> None:
    assert isinstance(make_detector("rema"), RemaDetector)
    paper = make_detector("rema-paper")
    assert isinstance(paper, RemaDetector)
    assert paper.rema.mode == "paper"
    with pytest.raises(ConfigError, match="rema-paper"):
        make_detector("rema2")


@pytest.mark.shared
def test_rema_beats_the_speed_gate_on_driveplotr_test(shared_data: Path) -> None:
    """Issue C acceptance: REMA alone beats the speed gate on anomaly F1 (grad, seed 0)."""
    report = run_bench(
        "grad", "driveplotr", ["rema", "speed-gate"], split="test", seed=0, data_dir=shared_data
    )
    rema, gate = report["results"]["rema"], report["results"]["speed-gate"]
    assert rema["anomaly"]["f1"] > gate["anomaly"]["f1"] + 0.3
    assert rema["normal"]["f1"] > 0.95
