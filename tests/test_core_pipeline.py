"""Fused pipeline: streaming == batch (with a JSON state round trip), pieces agree, tuning, detector."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from _core_support import CorePipeline
from gradgps._baselines.rema_detector import RemaDetector
from gradgps._grad.core import CoreParams, core_batch
from gradgps._grad.features import FeatureParams, segment_features
from gradgps._grad.rema import RemaParams, rema_batch
from gradgps._grad.time_classifier import classify_time
from gradgps._train.tune_rema import f1_scores, tune_rema


def _signal(n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    east = np.cumsum(rng.normal(10, 0.4, n))
    north = np.cumsum(rng.normal(-3, 0.4, n))
    label = np.zeros(n, dtype=bool)
    for start, length in ((50, 2), (120, 1), (126, 2), (135, 1), (250, 50)):
        east[start : start + length] += 25.0
        label[start : start + length] = True
    return east, north, label


@pytest.mark.parametrize("mode", ["paper", "trend"])
def test_streaming_equals_batch_through_state_round_trip(mode: str) -> None:
    east, north, _ = _signal()
    speed = np.full(east.size, 10.0)
    heading = np.full(east.size, 100.0)
    prm = CoreParams(period=1.0, rema=RemaParams(mode=mode, min_margin=3.0))
    batch = core_batch(east, north, prm, speed=speed, heading=heading)
    pipe = CorePipeline(prm)
    rows, feats = [], []
    for i in range(east.size):
        if i in (1, 77, 251):
            pipe = CorePipeline().set_state(json.loads(json.dumps(pipe.get_state())))
        rows.append(pipe.update(east[i], north[i], speed[i], heading[i]))
        feats.append(pipe.features.copy())
    got = np.array(rows)
    np.testing.assert_array_equal(got[:, 0], batch.flag)
    np.testing.assert_array_equal(got[:, 1], batch.time_code)
    np.testing.assert_array_equal(got[:, 2], batch.east_clean)
    np.testing.assert_array_equal(got[:, 5], batch.score)
    np.testing.assert_array_equal(np.array(feats), batch.features)


def test_pipeline_pieces_agree_with_the_separate_kernels_when_not_feeding_back() -> None:
    east, north, _ = _signal()
    rp = RemaParams(mode="trend", min_margin=3.0)
    prm = CoreParams(
        period=1.0, rema=rp, feed_recovered=False, features=FeatureParams(speed_heading=False)
    )
    out = core_batch(east, north, prm)
    flag = rema_batch(east, rp).flag | rema_batch(north, rp).flag
    np.testing.assert_array_equal(out.flag, flag)
    np.testing.assert_array_equal(out.time_code, classify_time(flag))
    t = np.arange(east.size, dtype=np.float64)
    np.testing.assert_allclose(
        out.features, segment_features(t, east, north, prm.features, rp), rtol=1e-12, atol=1e-12
    )


def test_protocol_shapes_get_their_time_types() -> None:
    east, north, _ = _signal()
    out = core_batch(east, north, CoreParams(rema=RemaParams(mode="trend", min_margin=3.0)))
    assert out.time_code[50] == 1
    assert 2 in out.time_code[120:137]
    # A 25 m permanent offset: permanent from its 8th point until the widening
    # bounds re-acquire the offset track (documented trade-off of trend mode).
    assert out.time_code[250:257].tolist() == [1] * 7
    assert set(out.time_code[257:265]) == {3}
    assert out.alert[257:265].all()


def test_tune_rema_finds_parameters_that_beat_the_defaults() -> None:
    channels = []
    for seed in range(2):
        east, north, label = _signal(seed=seed)
        channels += [(east, label), (north, np.zeros_like(label))]
    grid = {"mode": ("paper", "trend"), "min_margin": (0.0, 3.0), "sensitivity": (3.0,)}
    best, table = tune_rema(channels, grid, progress=False)
    assert len(table) == 4
    assert table["score"].is_monotonic_decreasing
    assert best.mode == "trend"
    assert table.loc[0, "score"] == pytest.approx(
        0.5 * (table.loc[0, "f1_anomaly"] + table.loc[0, "f1_normal"])
    )
    assert table.loc[0, "score"] > 0.8


def test_f1_scores() -> None:
    assert f1_scores([1, 0, 0, 1], [1, 0, 1, 1]) == (pytest.approx(0.8), pytest.approx(2 / 3))
    # No anomaly predicted nor present: scikit-learn's convention, 0.0 (was 1.0 here).
    assert f1_scores([0, 0], [0, 0]) == (0.0, 1.0)


def test_detector_returns_one_row_per_input_row() -> None:
    rng = np.random.default_rng(4)
    n = 200
    lat = 41.25 + np.cumsum(np.full(n, 1e-4)) + rng.normal(0, 5e-6, n)
    lon = -95.98 + np.cumsum(np.full(n, 5e-5))
    lat[100] += 5e-4  # ~55 m jump
    fixes = pd.DataFrame({"track": "a", "t": np.arange(n, dtype=float), "lat": lat, "lon": lon})
    fixes.loc[7, "lat"] = np.nan
    result = RemaDetector().detect(fixes)
    assert len(result) == n
    assert (result.index == fixes.index).all()
    assert result.loc[100, "anomaly"] == 1
    assert result.loc[100, "time_type"] == "transient"
    assert abs(result.loc[100, "lat_clean"] - (lat[99] + lat[101]) / 2) < 2e-5
    assert result.loc[7, "invalid_reason"] == "latitude missing or not finite"
    assert result.loc[7, "anomaly"] == 1  # the one invalid-row policy (it was 0, score 0.0)
    assert np.isnan(result.loc[7, "score"])
    assert result["anomaly"].sum() <= 6  # the jump plus at most a few noise flags
