"""The speed-gate baseline: rules, streaming == batch, state round trip."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, LocalFrame
from gradgps._baselines.speed_gate import SpeedGate, _distance_m
from gradgps._tracks.geo import haversine_m

FRAME = LocalFrame(41.25, -95.98)


def track(
    east: np.ndarray, north: np.ndarray, t: np.ndarray | None = None, name: str = "a"
) -> pd.DataFrame:
    lat, lon = FRAME.to_geodetic(east, north)
    t = np.arange(east.size, dtype=float) if t is None else t
    return pd.DataFrame({"track": name, "t": t, "lat": lat, "lon": lon})


def driving(n: int, v: float = 20.0) -> tuple[np.ndarray, np.ndarray]:
    return v * np.arange(n, dtype=float), np.zeros(n)


def test_scalar_distance_matches_the_vectorised_one() -> None:
    rng = np.random.default_rng(0)
    a, b, c, d = rng.uniform(-60, 60, 4 * 50).reshape(4, 50)
    ours = [_distance_m(*x) for x in zip(a, b, c, d, strict=True)]
    np.testing.assert_allclose(ours, haversine_m(a, b, c, d), rtol=1e-12)


def test_single_outlier_is_flagged_and_the_next_fix_is_not() -> None:
    east, north = driving(20)
    north[7] += 100.0
    r = SpeedGate().detect(track(east, north))
    assert r["anomaly"].tolist() == [0] * 7 + [1] + [0] * 12
    assert r.loc[7, "lat_clean"] == pytest.approx(track(east, north).loc[6, "lat"])
    assert r.loc[8, "lat_clean"] == track(east, north).loc[8, "lat"]
    assert r["bias_type"].isna().all()
    assert 0.5 < r.loc[7, "score"] <= 1.0
    assert r.loc[3, "score"] == pytest.approx(20 / 70, rel=0.01)  # sphere vs ellipsoid


def test_lasting_shift_is_accepted_after_reanchoring_with_an_alert() -> None:
    east, north = driving(30)
    north[10:] += 300.0
    r = SpeedGate(reanchor_after=5).detect(track(east, north))
    assert r["anomaly"].tolist() == [0] * 10 + [1] * 5 + [0] * 15
    assert r["alert"].tolist() == [0] * 15 + [1] + [0] * 14


def test_bad_first_fix_does_not_flag_the_whole_drive() -> None:
    east, north = driving(20)
    north[0] += 5000.0
    r = SpeedGate(reanchor_after=3).detect(track(east, north))
    assert r["anomaly"].tolist() == [0, 1, 1, 1] + [0] * 16


def test_real_long_gap_starts_afresh() -> None:
    east, north = driving(10)
    t = np.arange(10, dtype=float)
    t[5:] += 120.0
    east[5:] += 20_000.0  # far away after a long silence (e.g. ferry, logger off)
    r = SpeedGate(max_gap_s=60.0).detect(track(east, north, t))
    assert r["anomaly"].sum() == 0


def test_equal_timestamps_need_equal_positions() -> None:
    gate = SpeedGate()
    assert gate.update(0.0, 41.0, -95.0).anomaly == 0
    assert gate.update(0.0, 41.0, -95.0).anomaly == 0
    r = gate.update(0.0, 41.0001, -95.0)
    assert r.anomaly == 1
    assert r.score == 1.0


def test_unusable_fixes_change_nothing() -> None:
    gate = SpeedGate()
    gate.update(0.0, 41.0, -95.0)
    before = gate.get_state()
    r = gate.update(1.0, math.nan, -95.0)
    assert r.anomaly == 1  # the one invalid-row policy: flagged, with its reason
    assert r.invalid_reason == "latitude missing or not finite"
    assert math.isnan(r.score)
    assert gate.get_state() == before
    fixes = track(*driving(5))
    fixes.loc[2, "lon"] = np.nan
    out = SpeedGate().detect(fixes)
    assert out.loc[2, "invalid_reason"] == "longitude missing or not finite"
    assert out["anomaly"].tolist() == [0, 0, 1, 0, 0]


def test_update_takes_none_and_set_state_returns_the_gate() -> None:
    gate = SpeedGate()
    r = gate.update(None, 41.0, -95.0)  # type: ignore[arg-type]
    assert r.anomaly == 1
    assert r.invalid_reason == "time missing or not finite"
    gate.update(0.0, 41.0, -95.0)
    assert gate.set_state(gate.get_state()) is gate


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 120), cut=st.floats(0, 1))
def test_streaming_matches_batch_and_state_survives_json(seed: int, n: int, cut: float) -> None:
    rng = np.random.default_rng(seed)
    east, north = driving(n, v=float(rng.uniform(0, 45)))
    faulty = rng.random(n) < 0.15
    north[faulty] += rng.choice([-1, 1], faulty.sum()) * rng.uniform(10, 400, faulty.sum())
    north[rng.random(n) < 0.05] += 1000.0
    t = np.cumsum(rng.choice([0.0, 1.0, 1.0, 1.0, 2.0, 90.0], n))
    fixes = pd.concat(
        [track(east, north, t, "a"), track(east[::-1], north, t, "b")], ignore_index=True
    )
    fixes = fixes.sample(frac=1.0, random_state=seed % 1000)  # batch must restore time order
    batch = SpeedGate(reanchor_after=3).detect(fixes)
    for name in ("a", "b"):
        part = fixes[fixes["track"] == name].sort_values("t", kind="stable")
        gate = SpeedGate(reanchor_after=3)
        k = int(cut * len(part))
        for j, (idx, row) in enumerate(part.iterrows()):
            if j == k:  # restart from saved state, as a service would
                state = json.loads(json.dumps(gate.get_state()))
                gate = SpeedGate(reanchor_after=3)
                gate.set_state(state)
            r = gate.update(row["t"], row["lat"], row["lon"])
            assert r.anomaly == batch.loc[idx, "anomaly"]
            assert r.alert == batch.loc[idx, "alert"]
            assert r.lat_clean == batch.loc[idx, "lat_clean"]
            assert r.score == pytest.approx(batch.loc[idx, "score"])


def test_bad_parameters_and_state_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="max_speed_mps"):
        SpeedGate(max_speed_mps=0)
    with pytest.raises(ConfigError, match="reanchor_after"):
        SpeedGate(reanchor_after=0)
    with pytest.raises(ConfigError, match="lacks"):
        SpeedGate().set_state({"anchor": None})
