"""The end-to-end Detector: batch == streaming, checkpoint/restore, invalid fixes, model checks.

These tests use a model with random weights (the pipeline's arithmetic does
not care whether the network is any good); the shipped default model's
accuracy is measured by the benchmarks, and loaded once here.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _gru_support import random_detector_model
from gradgps import ConfigError, ModelError, simulate_fleet, to_fixes
from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector

RESULT = [
    "anomaly",
    "score",
    "bias_type",
    "time_type",
    "lat_clean",
    "lon_clean",
    "alert",
    "invalid_reason",
]


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return random_detector_model(tmp_path_factory.mktemp("model"), threshold=0.5)


@pytest.fixture(scope="module")
def drives() -> pd.DataFrame:
    clean = simulate_fleet(3, 4.0, 1.0, seed=5)
    return to_fixes(inject_grad(clean, seed=3))


def _stream(det: Detector, fixes: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for r in fixes.itertuples(index=False):
        res = det.update(r.t, r.lat, r.lon, speed=r.speed, heading=r.heading)
        rows.append(
            [
                res.anomaly,
                res.score,
                res.bias_type,
                res.time_type,
                res.lat_clean,
                res.lon_clean,
                res.alert,
                res.invalid_reason,
            ]
        )
    return pd.DataFrame(rows, columns=RESULT)


def _assert_same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    for col in RESULT:
        x, y = a[col].to_numpy(), b[col].to_numpy()
        if x.dtype.kind == "f" or y.dtype.kind == "f":
            np.testing.assert_array_equal(np.asarray(x, float), np.asarray(y, float), err_msg=col)
        else:
            assert list(x) == list(y), col


def test_batch_equals_streaming_bit_for_bit(model_dir: Path, drives: pd.DataFrame) -> None:
    batch = Detector(model_dir).detect(drives)
    assert list(batch.columns) == RESULT
    assert len(batch) == len(drives)
    assert batch["anomaly"].sum() > 0  # the random net flags something: the test has teeth
    for track in drives["track"].unique():
        mine = drives[drives["track"] == track]
        streamed = _stream(Detector(model_dir), mine)
        _assert_same(batch.loc[mine.index].reset_index(drop=True), streamed)


def test_batch_equals_streaming_at_5_hz_with_gaps(model_dir: Path) -> None:
    fixes = to_fixes(simulate_fleet(1, 2.0, 5.0, seed=9))
    keep = np.ones(len(fixes), bool)
    keep[100:115] = False  # a 3 s gap (kept in one segment)
    keep[300:340] = False  # an 8 s gap (a new segment)
    fixes = fixes[keep].reset_index(drop=True)
    _assert_same(Detector(model_dir).detect(fixes), _stream(Detector(model_dir), fixes))


@settings(max_examples=25, deadline=None)
@given(cut=st.integers(0, 239))
def test_checkpoint_in_json_and_restore_continues_identically(model_dir: Path, cut: int) -> None:
    fixes = to_fixes(inject_grad(simulate_fleet(1, 4.0, 1.0, seed=2), seed=1))
    whole = _stream(Detector(model_dir), fixes)
    first = Detector(model_dir)
    head = _stream(first, fixes.iloc[:cut])
    state = json.loads(json.dumps(first.get_state()))
    rest = _stream(Detector(model_dir).set_state(state), fixes.iloc[cut:])
    _assert_same(whole, pd.concat([head, rest], ignore_index=True))


def test_invalid_fixes_are_flagged_and_do_not_touch_state(model_dir: Path) -> None:
    fixes = to_fixes(simulate_fleet(1, 1.0, 1.0, seed=4))
    det, ref = Detector(model_dir), Detector(model_dir)
    bad = [
        (math.nan, 41.0, -96.0, "time missing or not finite"),
        (1e12, math.nan, -96.0, "latitude missing or not finite"),
        (1e12, 95.0, -96.0, "latitude outside +-90"),
        (1e12, 41.0, 181.0, "longitude outside +-180"),
    ]
    for i, r in enumerate(fixes.itertuples(index=False)):
        a = det.update(r.t, r.lat, r.lon, r.speed, r.heading)
        b = ref.update(r.t, r.lat, r.lon, r.speed, r.heading)
        assert a == b
        if i in (5, 30):
            for t, lat, lon, reason in bad:
                res = det.update(t, lat, lon)
                assert res.anomaly == 1
                assert res.invalid_reason == reason
            back = det.update(r.t, r.lat, r.lon)  # the same time again: not after the previous fix
            assert back.invalid_reason == "time not after the previous fix"


def test_batch_reports_invalid_rows_in_place(model_dir: Path) -> None:
    fixes = to_fixes(simulate_fleet(1, 1.0, 1.0, seed=4))
    fixes.loc[7, "lat"] = np.nan
    fixes.loc[9, "lon"] = 500.0
    out = Detector(model_dir).detect(fixes)
    assert len(out) == len(fixes)
    assert out.loc[7, "invalid_reason"] == "latitude missing or not finite"
    assert out.loc[9, "invalid_reason"] == "longitude outside +-180"
    assert out.loc[[7, 9], "anomaly"].tolist() == [1, 1]
    assert (out.drop(index=[7, 9])["invalid_reason"] == "").all()


def test_threshold_override_changes_decisions(model_dir: Path, drives: pd.DataFrame) -> None:
    low = Detector(model_dir, threshold=0.05).detect(drives)["anomaly"].sum()
    high = Detector(model_dir, threshold=0.95).detect(drives)["anomaly"].sum()
    assert low > high
    with pytest.raises(ConfigError):
        Detector(model_dir, threshold=1.5)


def test_state_from_another_model_is_refused(model_dir: Path, tmp_path: Path) -> None:
    other = random_detector_model(tmp_path / "other", seed=1)
    det = Detector(model_dir)
    det.update(0.0, 41.0, -96.0)
    with pytest.raises(ConfigError, match="another model"):
        Detector(other).set_state(det.get_state())
    with pytest.raises(ConfigError, match="not a detector state"):
        Detector(model_dir).set_state({"format": 1})


def test_missing_model_and_wrong_features_are_clear_errors(tmp_path: Path, model_dir: Path) -> None:
    with pytest.raises(ModelError, match="no such model directory"):
        Detector(tmp_path / "nope")
    cfg = json.loads((model_dir / "config.json").read_text())
    cfg["features"]["names"] = cfg["features"]["names"][::-1]
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "weights.npz").write_bytes((model_dir / "weights.npz").read_bytes())
    (bad / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(ModelError, match="retrain"):
        Detector(bad)


def test_default_model_ships_and_loads() -> None:
    det = Detector()
    res = det.update(1_700_000_000.0, 41.25, -95.98, speed=10.0, heading=90.0)
    assert res.anomaly in (0, 1)
    assert 0.0 <= res.score <= 1.0


def test_threaded_batch_gives_the_same_numbers(model_dir: Path, drives: pd.DataFrame) -> None:
    one = Detector(model_dir).detect(drives)
    two = Detector(model_dir).detect(drives, threads=2)
    _assert_same(one, two)


def test_a_confirm_head_settles_each_verdict_one_fix_late(tmp_path, model_dir, drives):
    """A model with a confirm head: a fix's final verdict is the head's read at the next
    fix of its segment against the confirm threshold (a segment's last fix keeps its
    verdict at once); in batch that is the NumPy reference GRU's confirm head on the
    pipeline's features, shifted by one fix; a stream's verdicts at once plus
    ``Detector.settled`` give the batch rows exactly, also across a saved state."""
    from gradgps._grad.gru import reference_stream
    from gradgps._grad.model_io import load_model
    from gradgps._grad.pipeline import O_CONFIRM, O_FLAG, grad_features

    confirm_dir = random_detector_model(tmp_path / "confirm", threshold=0.5, confirm_head=True)
    one = drives[drives["track"] == drives["track"].iloc[0]]
    det = Detector(confirm_dir)
    assert det.model_.params.confirm_threshold == 0.5
    _, usable, prepared, out = det._point_outputs(one)
    (k, _), *rest = list(prepared.segment_slices())
    assert not rest  # one segment: the reference runs it from a zero state
    columns = (
        prepared.points[c].to_numpy(np.float64) for c in ("t", "lat", "lon", "speed", "heading")
    )
    features = grad_features(det.model_.params, prepared.segment_frames[k], *columns).features
    weights, config = load_model(confirm_dir)
    scaler = config["scaler"]
    ref, _ = reference_stream(weights, np.array(scaler["mean"]), np.array(scaler["std"]), features)
    assert ref.confirm is not None
    np.testing.assert_allclose(out[:-1, O_CONFIRM], ref.confirm[1:], atol=1e-5)  # float32 sums
    assert np.isnan(out[-1, O_CONFIRM])
    clear = np.abs(ref.confirm[1:] - 0.5) > 1e-4  # not within float32 noise of the threshold
    np.testing.assert_array_equal(out[:-1, O_FLAG][clear], (ref.confirm[1:] >= 0.5)[clear])
    assert out[-1, O_FLAG] == float(ref.anomaly[-1] >= 0.5)
    plain = Detector(model_dir).detect(one)["anomaly"].to_numpy()
    assert (out[:, O_FLAG] != plain).any()  # the head decides, not the anomaly head

    def final_rows(stream: Detector, rows: pd.DataFrame) -> list[object]:
        finals: list[object] = []
        last = None
        for r in rows.itertuples(index=False):
            last = stream.update(r.t, r.lat, r.lon, speed=r.speed, heading=r.heading)
            settled = stream.settled
            if finals or settled is not None:
                assert settled is not None
                finals.append(settled)
        finals.append(last)
        return finals

    fixes = one.iloc[usable]
    want = [det._result(row) for row in out]
    assert final_rows(Detector(confirm_dir), fixes) == want
    first = Detector(confirm_dir)
    half = len(fixes) // 2
    head = final_rows(first, fixes.iloc[:half])[:-1]  # the last one was not final yet
    second = Detector(confirm_dir).set_state(json.loads(json.dumps(first.get_state())))
    tail = final_rows(second, fixes.iloc[half:])
    assert second.settled is not None
    assert [*head, *tail] == want


def test_follow_and_batch_give_a_settling_model_the_same_rows(tmp_path):
    """A model whose verdicts settle one fix late: ``detect --follow`` writes each line
    once its verdict is final, so its result columns are the batch run's, row for row
    (detect-fleet and serve-redis: tests/test_fleet_dask.py, tests/test_fleet_redis.py)."""
    from click.testing import CliRunner

    from gradgps._cli import main
    from gradgps._data.simulator import simulate_fleet
    from gradgps._result import RESULT_COLUMNS

    confirm_dir = random_detector_model(tmp_path / "confirm", threshold=0.5, confirm_head=True)
    fixes = tmp_path / "fixes.csv"
    fleet = simulate_fleet(2, 1.0, 1.0, seed=5).sort_values(["t", "track"], kind="stable")
    fleet[["track", "t", "lat", "lon"]].to_csv(fixes, index=False)
    outputs = {}
    for name, extra in (("batch", []), ("follow", ["--follow"])):
        out = tmp_path / f"{name}.csv"
        run = CliRunner().invoke(
            main, ["detect", str(fixes), *extra, "--model", str(confirm_dir), "-o", str(out)]
        )
        assert run.exit_code == 0, run.output
        outputs[name] = pd.read_csv(out, keep_default_na=False)[list(RESULT_COLUMNS)]
    pd.testing.assert_frame_equal(outputs["follow"], outputs["batch"])


def test_a_threshold_given_moves_the_confirm_threshold_too(tmp_path):
    """``threshold`` is the threshold of the verdicts: where they settle one fix late it
    is the confirm head's too (else ``--threshold`` would move only the verdicts at once)."""
    confirm_dir = random_detector_model(tmp_path / "confirm", threshold=0.5, confirm_head=True)
    params = Detector(confirm_dir, threshold=0.3).model_.params
    assert (params.threshold, params.confirm_threshold) == (0.3, 0.3)
    plain = random_detector_model(tmp_path / "plain", threshold=0.5)
    assert Detector(plain, threshold=0.3).model_.params.confirm_threshold is None


def test_a_state_is_refused_under_another_confirm_threshold(tmp_path):
    """The confirm threshold decides the pending fix a settling state holds: a state saved
    under one is refused under another, as for any setting."""
    confirm_dir = random_detector_model(tmp_path / "a", threshold=0.5, confirm_head=True)
    other = tmp_path / "b"
    other.mkdir()
    (other / "weights.npz").write_bytes((confirm_dir / "weights.npz").read_bytes())
    cfg = json.loads((confirm_dir / "config.json").read_text())
    cfg["thresholds"]["confirm"] = 0.6
    (other / "config.json").write_text(json.dumps(cfg))
    det = Detector(confirm_dir)
    det.update(0.0, 41.0, -96.0)
    Detector(confirm_dir).set_state(det.get_state())
    with pytest.raises(ConfigError):
        Detector(other).set_state(det.get_state())


def test_follow_reads_a_speed_column_in_the_unit_its_name_says(tmp_path):
    """``speed_kmh`` is km/h in every mode: ``detect --follow`` took the values as m/s
    while the batch reader converted them, and on a clean 0.5 Hz drive with its speed
    and heading the shipped model then flagged a third of the fixes in follow mode
    alone."""
    from click.testing import CliRunner

    from gradgps._cli import main
    from gradgps._data.simulator import simulate_fleet
    from gradgps._result import RESULT_COLUMNS

    drive = simulate_fleet(1, 8.0, 0.5, seed=11, imu=False)
    table = pd.DataFrame(
        {
            "t": drive["t"],
            "lat": drive["lat"],
            "lon": drive["lon"],
            "speed_kmh": drive["speed"] * 3.6,
            "heading": drive["heading"],
        }
    )
    src = tmp_path / "kmh.csv"
    table.to_csv(src, index=False)
    outputs = {}
    for name, extra in (("batch", []), ("follow", ["--follow"])):
        out = tmp_path / f"{name}.csv"
        run = CliRunner().invoke(main, ["detect", str(src), *extra, "-o", str(out)])
        assert run.exit_code == 0, run.output
        outputs[name] = pd.read_csv(out, keep_default_na=False)[list(RESULT_COLUMNS)]
    pd.testing.assert_frame_equal(outputs["follow"], outputs["batch"])
    assert outputs["follow"]["anomaly"].mean() < 0.01
