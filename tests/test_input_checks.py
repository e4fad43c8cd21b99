"""Honest inputs: warnings where a file is outside what the model was validated on."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps._tracks.geo import LocalFrame
from gradgps._tracks.input_checks import InputChecks, input_warnings, validated_rates
from gradgps._tracks.summary import summarize


def _track(t: np.ndarray, speed: float = 20.0, name: str = "a") -> pd.DataFrame:
    """Canonical fixes of a straight drive north at ``speed`` m/s, sampled at times ``t``."""
    frame = LocalFrame(52.0, 4.4)
    north = speed * (t - t[0])
    lat, lon = frame.to_geodetic(np.zeros_like(north), north)
    return pd.DataFrame({"track": name, "t": t, "lat": lat, "lon": lon})


def _kinds(fixes: pd.DataFrame, **rates: float) -> set[str]:
    kinds = set()
    for w in input_warnings(fixes, **rates):
        for key, kind in (
            ("slower than", "slow"),
            ("faster than", "fast"),
            ("repeat the previous", "repeats"),
            ("imply speeds", "speeds"),
            ("irregular", "irregular"),
            ("noisy fixes", "noisy"),
        ):
            if key in w:
                kinds.add(kind)
    return kinds


REGULAR = np.arange(300.0)


def test_an_ordinary_drive_gets_no_warning() -> None:
    assert input_warnings(_track(REGULAR)) == []
    jitter = REGULAR + np.random.default_rng(0).uniform(-0.1, 0.1, REGULAR.size)
    assert input_warnings(_track(np.sort(jitter))) == []


def test_slow_sampling_is_named_with_the_validated_rate() -> None:
    assert _kinds(_track(np.arange(300.0) * 5.0)) == {"slow"}
    assert _kinds(_track(np.arange(300.0) * 2.0)) == set()  # 0.5 Hz is validated
    (warning,) = input_warnings(_track(np.arange(300.0) * 5.0))
    assert "5 s (0.2 Hz)" in warning
    assert "0.5 Hz" in warning
    # A model validated down to 1 Hz only: 0.5 Hz is outside.
    assert _kinds(_track(np.arange(300.0) * 2.0), min_rate_hz=1.0) == {"slow"}


def test_fast_sampling_beyond_the_validated_rate() -> None:
    assert _kinds(_track(np.arange(300.0) * 0.05)) == {"fast"}  # 20 Hz
    assert _kinds(_track(np.arange(300.0) * 0.1)) == set()  # 10 Hz


def test_repeated_timestamps() -> None:
    t = REGULAR.copy()
    t[100:110] = t[99]  # 10 of 299 steps repeat a timestamp (3 %)
    assert _kinds(_track(np.sort(t))) >= {"repeats"}
    t = REGULAR.copy()
    t[100] = t[99]  # one (0.3 %): not worth a warning
    assert "repeats" not in _kinds(_track(t))


def test_implausible_speeds() -> None:
    assert _kinds(_track(REGULAR, speed=500.0)) == {"speeds"}  # e.g. a wrong time unit
    # A few real glitches (jumps away and back) are what the detector is for.
    fixes = _track(REGULAR)
    fixes.loc[[50, 120], "lat"] += 0.01  # ~1.1 km away for one fix each: 4 fast steps
    assert _kinds(fixes) == set()
    (warning,) = input_warnings(_track(REGULAR, speed=500.0))
    assert "299 of 299 time steps" in warning
    assert "500 m/s" in warning


def test_irregular_sampling() -> None:
    steps = np.tile([1.0, 1.0, 3.0], 100)  # quartiles 1 s and 3 s around a median of 1 s
    assert _kinds(_track(np.cumsum(steps))) == {"irregular"}


def test_chunks_give_the_same_warnings_as_the_whole_file() -> None:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.choice([1.0, 1.0, 4.0, 0.0], size=900))
    fixes = pd.concat([_track(t, 120.0, "a"), _track(t, 20.0, "b")]).reset_index(drop=True)
    whole = InputChecks().add(fixes)
    chunked = InputChecks()
    for lo in range(0, len(fixes), 250):
        chunked.add(fixes.iloc[lo : lo + 250])
    assert whole.warnings() == chunked.warnings()
    assert len(whole.warnings()) >= 2
    assert (whole.hist == chunked.hist).all()
    assert (whole.second_diff_hist == chunked.second_diff_hist).all()
    assert whole.repeats == chunked.repeats


def test_invalid_fixes_and_single_fixes_give_no_warning() -> None:
    fixes = _track(REGULAR[:1])
    assert input_warnings(fixes) == []
    bad = _track(REGULAR)
    bad.loc[::2, "lat"] = np.nan
    assert input_warnings(bad) == []


def test_validated_rates_come_from_the_model_config() -> None:
    assert validated_rates(None) == (0.5, 10.0)
    assert validated_rates({"validated": {"min_rate_hz": 1, "max_rate_hz": 20}}) == (1.0, 20.0)
    assert validated_rates({"other": 1}) == (0.5, 10.0)


def test_summary_lists_the_warnings() -> None:
    summary = summarize(_track(np.arange(300.0) * 5.0))
    assert len(summary.warnings) == 1
    assert "slower than" in summary.warnings[0]
    assert summary.as_dict()["warnings"] == summary.warnings
    assert summarize(_track(REGULAR)).warnings == []


@pytest.mark.parametrize("chunk_size", ["0", "100"])
def test_detect_says_it_once_on_stderr(tmp_path: Path, chunk_size: str) -> None:
    from gradgps._cli import main

    slow = _track(np.arange(200.0) * 5.0)
    src = tmp_path / "slow.csv"
    slow.to_csv(src, index=False)
    runner = CliRunner()
    result = runner.invoke(
        main, ["detect", str(src), "-o", str(tmp_path / "out.csv"), "--chunk-size", chunk_size]
    )
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("warning: ")]
    assert len(lines) == 1
    assert "slower than the slowest rate" in lines[0]
    assert "warning" not in result.stdout
    ok = tmp_path / "ok.csv"
    _track(REGULAR).to_csv(ok, index=False)
    result = runner.invoke(
        main, ["detect", str(ok), "-o", str(tmp_path / "o2.csv"), "--chunk-size", chunk_size]
    )
    assert result.exit_code == 0
    assert "warning" not in result.output


def test_report_summary_lists_the_warnings(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from gradgps._cli import main

    src = tmp_path / "slow.csv"
    _track(np.arange(200.0) * 5.0).to_csv(src, index=False)
    report = tmp_path / "r.html"
    result = CliRunner().invoke(
        main, ["detect", str(src), "-o", str(tmp_path / "o.csv"), "--report", str(report)]
    )
    assert result.exit_code == 0, result.output
    html = report.read_text()
    assert html.count("slower than the slowest rate the model was validated on") == 1


def _noisy(sigma_m: float, seed: int = 0, t: np.ndarray = REGULAR) -> pd.DataFrame:
    """A straight drive whose fixes scatter by ``sigma_m`` m per axis, independently."""
    fixes = _track(t)
    rng = np.random.default_rng(seed)
    fixes["lat"] += rng.normal(0.0, sigma_m, len(fixes)) / 111_195.0
    fixes["lon"] += rng.normal(0.0, sigma_m, len(fixes)) / (111_195.0 * np.cos(np.radians(52.0)))
    return fixes


def test_a_noisy_receiver_is_named_with_its_noise() -> None:
    """Fixes scattering by 3 m per axis land about 7 m off their predecessors' line (the
    second difference of independent errors: sqrt(6) sigma, a median of 1.18 of that);
    by 0.3 m: under a metre, like every real drive the model knows."""
    assert "noisy" in _kinds(_noisy(3.0))
    (warning,) = input_warnings(_noisy(3.0))
    assert "m off the line" in warning
    assert "1.4 m" in warning
    assert _kinds(_noisy(0.3)) == set()
    checks = InputChecks().add(_noisy(3.0))
    assert 5.0 < checks.second_difference_median() < 12.0
    # Too few triples say nothing; uneven steps make no triple.
    assert _kinds(_noisy(3.0).iloc[:40]) == set()
    assert (
        InputChecks().add(_track(np.cumsum(np.tile([1.0, 2.0], 100)))).second_diff_hist.sum() == 0
    )
