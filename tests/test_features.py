"""MS-SW features: kernel == NumPy reference, translation invariance, rate awareness, NaN safety."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps._exceptions import ConfigError
from gradgps._grad.features import (
    FeatureParams,
    feature_names,
    features_reference,
    segment_features,
)
from gradgps._grad.rema import RemaParams


def _track(n: int, period: float, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * period
    east = 200.0 + 12.0 * t + rng.normal(0, 0.5, n)
    north = -3000.0 + 4.0 * t + rng.normal(0, 0.5, n)
    return t, east, north


def _close(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, equal_nan=True)


def test_kernel_matches_reference_with_speed_and_heading() -> None:
    t, e, n = _track(300, 0.2)
    rng = np.random.default_rng(3)
    speed = rng.uniform(0, 20, t.size)
    heading = rng.uniform(0, 360, t.size)
    speed[10] = np.nan
    prm = FeatureParams(long_window_s=10.0, short_window_s=2.0)
    got = segment_features(t, e, n, prm, speed=speed, heading=heading)
    assert got.shape == (t.size, len(feature_names(prm)))
    _close(got, features_reference(t, e, n, prm, speed=speed, heading=heading))
    assert np.isnan(got[10, feature_names(prm).index("speed_gap")])


@settings(max_examples=25, deadline=None)
@given(
    steps=st.lists(st.tuples(st.floats(-30, 30), st.floats(-30, 30)), min_size=1, max_size=80),
    long_s=st.integers(3, 20),
    short_s=st.integers(1, 3),
)
def test_kernel_matches_reference_on_generated_tracks(
    steps: list[tuple[float, float]], long_s: int, short_s: int
) -> None:
    d = np.array(steps)
    e, n = 1.0e4 + np.cumsum(d[:, 0]), -2.0e4 + np.cumsum(d[:, 1])
    t = np.arange(e.size, dtype=np.float64)
    prm = FeatureParams(long_window_s=long_s, short_window_s=short_s, speed_heading=False)
    _close(segment_features(t, e, n, prm), features_reference(t, e, n, prm))


def test_features_do_not_depend_on_where_the_track_is() -> None:
    t, e, n = _track(200, 1.0)
    rp = RemaParams(mode="trend", min_margin=2.0)
    a = segment_features(t, e, n, rema_params=rp)
    b = segment_features(t, e + 5.0e4, n - 7.0e4, rema_params=rp)
    np.testing.assert_allclose(a, b, atol=1e-6, equal_nan=True)


def test_rates_are_per_second_so_1hz_and_5hz_agree() -> None:
    names = feature_names()
    t1, _e1, _n1 = _track(100, 1.0)
    t5 = np.arange(500) * 0.2
    f1 = segment_features(t1, 12.0 * t1, 4.0 * t1)
    f5 = segment_features(t5, 12.0 * t5, 4.0 * t5)
    for name in ("east_slope", "north_slope", "east_diff", "east_range"):
        k = names.index(name)
        assert f1[-1, k] == pytest.approx(f5[-1, k], rel=1e-9), name
    assert f1[-1, names.index("east_slope")] == pytest.approx(12.0)


def test_params_validation() -> None:
    with pytest.raises(ConfigError, match="short_window_s"):
        FeatureParams(long_window_s=2.0, short_window_s=5.0).points(1.0)
    with pytest.raises(ConfigError, match="period"):
        FeatureParams().points(0.0)
    assert "speed_gap" not in feature_names(FeatureParams(speed_heading=False))
