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


def test_reach_kernel_matches_reference_and_keeps_what_is_plausible() -> None:
    """:func:`within_reach` == its readable reference; a fix within reach comes back as it
    is, one beyond it lands on the reach's edge, between the fix and the prediction."""
    from gradgps._grad.recovery import within_reach, within_reach_reference

    rng = np.random.default_rng(3)
    prm = RecoveryParams(reach_m=5.0, reach_accel_mps2=3.0)
    p = prm.reach_array()
    n = 500
    tau = rng.uniform(0.0, 12.0, n)
    pred = rng.normal(0.0, 100.0, (n, 2))
    fix = pred + rng.normal(0.0, 60.0, (n, 2))
    ref = within_reach_reference(prm, tau, fix, pred)
    got = np.array(
        [within_reach(p, tau[i], fix[i, 0], fix[i, 1], pred[i, 0], pred[i, 1]) for i in range(n)]
    )
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-9)
    reach = 5.0 + 1.5 * tau**2
    miss = np.linalg.norm(fix - pred, axis=1)
    inside = miss <= reach
    assert 0 < inside.sum() < n  # both cases are exercised
    np.testing.assert_array_equal(got[inside], fix[inside])
    np.testing.assert_allclose(np.linalg.norm(got - pred, axis=1)[~inside], reach[~inside])
    # On the segment from the prediction to the fix: never farther from either end.
    to_fix = np.linalg.norm(got - fix, axis=1) + np.linalg.norm(got - pred, axis=1)
    np.testing.assert_allclose(to_fix, miss, rtol=1e-9)
    # No reach: the prediction; a NaN fix is kept as it is.
    zero = RecoveryParams(reach_m=0.0, reach_accel_mps2=0.0).reach_array()
    assert within_reach(zero, 3.0, 10.0, 0.0, 1.0, 2.0) == (1.0, 2.0)
    e, n_ = within_reach(p, 1.0, np.nan, 0.0, 1.0, 2.0)
    assert np.isnan(e)
    assert n_ == 0.0


@pytest.mark.parametrize("bad", [-1.0, np.inf, np.nan])
def test_reach_settings_are_checked(bad: float) -> None:
    with pytest.raises(ConfigError, match="reach_m"):
        RecoveryParams(reach_m=bad).reach_array()
    with pytest.raises(ConfigError, match="reach_accel_mps2"):
        RecoveryParams(reach_accel_mps2=bad).reach_array()


def _flag_everything(reach_m: float, reach_accel: float) -> object:
    """The shipped model with every fix flagged (threshold ~0) and the reach given."""
    import dataclasses

    from gradgps import Detector

    det = Detector(threshold=1e-9)
    params = det.model_.params
    recovery = dataclasses.replace(params.recovery, reach_m=reach_m, reach_accel_mps2=reach_accel)
    det.model_ = dataclasses.replace(
        det.model_, params=dataclasses.replace(params, recovery=recovery)
    )
    return det


def test_flagged_fixes_a_car_could_have_driven_are_kept_in_every_mode() -> None:
    """A car pulling away at 4 m/s, every fix flagged (threshold ~0): the fixes stay
    within the reach of the recovery's prediction, so the detector keeps them as they
    are, in batch and streamed alike."""
    import pandas as pd

    t = np.arange(12.0)
    lat = 48.1 + 4.0 * t / 111_320.0
    fixes = pd.DataFrame({"t": t, "lat": lat, "lon": np.full(12, 11.5)})
    det = _flag_everything(5.0, 3.0)
    batch = det.detect(fixes)
    assert (batch["anomaly"] == 1).all()
    assert (batch["time_type"].iloc[1:4] == "transient").all()
    np.testing.assert_allclose(batch["lat_clean"], lat, rtol=0, atol=1e-12)
    streamed = [det.update(ti, la, 11.5).lat_clean for ti, la in zip(t, lat, strict=True)]
    np.testing.assert_allclose(streamed, lat, rtol=0, atol=1e-12)


def test_a_jump_is_repaired_to_the_edge_of_the_reach() -> None:
    """A 200 m jump for 3 fixes of a straight 15 m/s drive, positions only, shipped model:
    the prediction is the true track, so the repaired fixes lie on the reach's edge
    towards the jump, reach(tau) = 5 m + 3 m/s^2 * tau^2 / 2 after tau = 1, 2, 3 s of
    flags (the time classifier's run times the period); without the reach, on the track."""
    import dataclasses

    import pandas as pd

    from gradgps import Detector

    t = np.arange(200.0)
    lat = 48.1 + 15.0 * t / 111_320.0
    m_per_deg_lon = 111_320.0 * np.cos(np.radians(48.1))
    lon = np.full(200, 11.5)
    lon[100:103] += 200.0 / m_per_deg_lon
    fixes = pd.DataFrame({"t": t, "lat": lat, "lon": lon})
    det = Detector()
    res = det.detect(fixes)
    assert (res["anomaly"].iloc[100:103] == 1).all()
    assert (res["time_type"].iloc[100:103] != "permanent").all()
    east = (res["lon_clean"].to_numpy() - 11.5) * m_per_deg_lon
    north_miss = (res["lat_clean"].to_numpy() - lat) * 111_320.0
    np.testing.assert_allclose(east[100:103], [6.5, 11.0, 18.5], atol=0.5)
    np.testing.assert_allclose(north_miss[100:103], 0.0, atol=0.5)
    recovery = dataclasses.replace(det.model_.params.recovery, reach_m=0.0, reach_accel_mps2=0.0)
    det.model_ = dataclasses.replace(
        det.model_, params=dataclasses.replace(det.model_.params, recovery=recovery)
    )
    plain = det.detect(fixes)
    east0 = (plain["lon_clean"].to_numpy() - 11.5) * m_per_deg_lon
    np.testing.assert_allclose(east0[100:103], 0.0, atol=0.5)


def test_a_reported_velocity_leaves_only_the_constant_reach() -> None:
    """With speed and heading reported the prediction moves with them, so a flagged fix
    10 m beside it is held 5 m (``reach_m``) from it, however long the run of flags."""
    import pandas as pd

    t = np.arange(8.0)
    north = 10.0 * t
    lat = 48.1 + north / 111_320.0
    lon = np.full(8, 11.5)
    lon[2:5] += 10.0 / (111_320.0 * np.cos(np.radians(48.1)))
    fixes = pd.DataFrame(
        {"t": t, "lat": lat, "lon": lon, "speed": np.full(8, 10.0), "heading": np.zeros(8)}
    )
    res = _flag_everything(5.0, 3.0).detect(fixes)
    east_off = (res["lon_clean"] - 11.5) * 111_320.0 * np.cos(np.radians(48.1))
    assert (res["time_type"].iloc[2:5] == "transient").all()
    np.testing.assert_allclose(east_off.iloc[2:5], 5.0, atol=0.05)


def test_a_measured_velocity_repairs_a_permanent_fault_too() -> None:
    """Speed and heading reported: a 10 m offset that outlasts the time classifier's
    permanent run is still held 5 m from the dead-reckoned track (alert raised);
    positions only, the permanent fixes pass through as they are (the paper)."""
    import pandas as pd

    n = 12
    t = np.arange(float(n))
    lat = 48.1 + 10.0 * t / 111_320.0
    m_per_deg_lon = 111_320.0 * np.cos(np.radians(48.1))
    lon = np.full(n, 11.5)
    lon[2:] += 10.0 / m_per_deg_lon
    measured = pd.DataFrame(
        {"t": t, "lat": lat, "lon": lon, "speed": np.full(n, 10.0), "heading": np.zeros(n)}
    )
    det = _flag_everything(5.0, 3.0)
    res = det.detect(measured)
    permanent = (res["time_type"] == "permanent").to_numpy()
    assert permanent[2:].sum() >= 4
    np.testing.assert_array_equal(res["alert"].to_numpy(dtype=bool), permanent)
    east = (res["lon_clean"].to_numpy() - 11.5) * m_per_deg_lon
    np.testing.assert_allclose(east[2:], 5.0, atol=0.05)
    positions = det.detect(measured[["t", "lat", "lon"]])
    kept = (positions["time_type"] == "permanent").to_numpy()
    assert kept.sum() >= 4
    np.testing.assert_allclose(
        positions["lon_clean"].to_numpy()[kept], lon[kept], rtol=0, atol=1e-12
    )
