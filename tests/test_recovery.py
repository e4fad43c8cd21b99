"""Recovery: kernel == reference; both estimators reduce the error of an injected fault."""

from __future__ import annotations

import numpy as np
import pytest

from gradgps._exceptions import ConfigError
from gradgps._grad.core import CoreParams, core_batch
from gradgps._grad.recovery import RecoveryParams, recover, recover_reference, rmse
from gradgps._grad.rema import RemaParams
from gradgps._grad.time_classifier import classify_time


def _injected(seed: int = 0) -> tuple[np.ndarray, ...]:
    """A 1 Hz drive with 1 m noise, three transient jumps and one intermittent episode."""
    rng = np.random.default_rng(seed)
    n = 400
    speed = np.clip(12 + np.cumsum(rng.normal(0, 0.2, n)), 2, 25)
    heading = (90 + np.cumsum(rng.normal(0, 1.0, n))) % 360
    h = np.radians(heading)
    e_true = np.cumsum(speed * np.sin(h))
    n_true = np.cumsum(speed * np.cos(h))
    east = e_true + rng.normal(0, 1.0, n)
    north = n_true + rng.normal(0, 1.0, n)
    label = np.zeros(n, dtype=bool)
    for start, length, dx in (
        (60, 2, 40.0),
        (130, 4, -35.0),
        (210, 1, 50.0),
        (290, 2, 30.0),
        (297, 1, 30.0),
        (305, 3, -30.0),
    ):
        east[start : start + length] += dx
        north[start : start + length] += 0.5 * dx
        label[start : start + length] = True
    return east, north, e_true, n_true, speed, heading, label


@pytest.mark.parametrize("method", ["ema", "velocity"])
def test_kernel_matches_reference(method: str) -> None:
    east, north, _, _, speed, heading, label = _injected()
    codes = classify_time(label)
    ema_e, ema_n = east + 1.0, north - 1.0
    prm = RecoveryParams(method=method)
    speed = speed.copy()
    speed[::7] = np.nan  # falls back to the velocity EMA there
    got = recover(codes, 1.0, east, north, ema_e, ema_n, prm, speed=speed, heading=heading)
    ref = recover_reference(
        codes, 1.0, east, north, ema_e, ema_n, prm, speed=speed, heading=heading
    )
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_permanent_points_pass_through_with_an_alert() -> None:
    codes = np.r_[np.zeros(10), np.full(5, 3)].astype(np.int8)
    x = np.arange(15.0)
    e, _, alert = recover(codes, 1.0, x, x, x + 5, x + 5)
    np.testing.assert_array_equal(e, x)
    assert alert.tolist() == [0] * 10 + [1] * 5


def test_pipeline_recovery_lowers_the_error_of_injected_faults() -> None:
    east, north, e_true, n_true, speed, heading, label = _injected()
    corrupted = rmse(east, north, e_true, n_true, label)
    errors = {}
    for method in ("ema", "velocity"):
        prm = CoreParams(
            rema=RemaParams(mode="trend", min_margin=4.0), recovery=RecoveryParams(method=method)
        )
        out = core_batch(east, north, prm, speed=speed, heading=heading)
        assert out.flag[label].mean() > 0.8
        errors[method] = rmse(out.east_clean, out.north_clean, e_true, n_true, label)
    assert errors["velocity"] < errors["ema"] < corrupted
    assert errors["velocity"] < 0.2 * corrupted


def test_unknown_method_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="recovery method"):
        recover([0], 1.0, [0.0], [0.0], [0.0], [0.0], RecoveryParams(method="kalman"))
