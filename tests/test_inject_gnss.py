"""Protocol ``gnss``: reproducible, every documented bound holds, labels consistent, ``grad`` unchanged."""

from __future__ import annotations

import hashlib
import itertools

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, LocalFrame
from gradgps._data import inject as inj
from gradgps._data.inject import GNSS_RATES, GNSS_TYPES, gnss_rates, inject_gnss, inject_grad
from test_inject import drives, runs


def test_grad_is_what_it_was() -> None:
    """Protocol grad as it was before protocol gnss existed (main at 00a7e55): the same
    labels, episodes and kinds, byte for byte, and the same offsets on the fixes.

    The float columns are compared to 1e-9 of their sums, not by their bytes: the test's
    drives and the local frame go through ``np.sin``/``np.cos``, whose last bit depends on
    the CPU's vector unit (the bytes' digest, taken on one machine, failed on another with
    00a7e55's own code; 2026-12-02)."""
    clean = drives([900, 450, 30])
    out = inject_grad(clean, seed=7, scale=1.5)
    exact = out.select_dtypes(exclude="float").to_csv(index=False)
    digest = hashlib.sha256(exact.encode()).hexdigest()
    assert digest == "48b3a88297c0fffb046d4099f3d547d8732a312b5e9ad8aed3cf239670fa60ac"
    for column, abs_sum, square_sum in (
        ("lat", 0.08688747331602542, 0.00010537920911746256),
        ("lon", 0.17250617809834168, 0.00040916304381055776),
    ):
        offset = out[column].to_numpy() - clean[column].to_numpy()
        assert np.sum(np.abs(offset)) == pytest.approx(abs_sum, rel=1e-9)
        assert np.sum(offset * offset) == pytest.approx(square_sum, rel=1e-9)
        np.testing.assert_array_equal(out[f"{column}_true"], clean[column])
    untouched = ["t", "speed_mps", "accel_x_g", "gyro_z_dps"]
    pd.testing.assert_frame_equal(out[untouched], clean[untouched])


def test_same_seed_same_bytes_other_seed_differs() -> None:
    table = drives([1500, 700])
    a = inject_gnss(table, seed=3).to_csv(index=False)
    assert a == inject_gnss(table, seed=3).to_csv(index=False)
    assert a != inject_gnss(table, seed=4).to_csv(index=False)


def test_every_added_type_appears_with_both_time_ends_of_a_drift() -> None:
    out = inject_gnss(drives([4000] * 6), seed=0)
    kinds = set(out["label_bias"])
    assert {"noise", "jump", *GNSS_TYPES} <= kinds
    drift = out[out["label_bias"] == "drift"]
    assert set(drift["label_time"]) == {"transient", "permanent"}


def _frame_offsets(part: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    frame = LocalFrame(float(part["lat_true"].iloc[0]), float(part["lon_true"].iloc[0]))
    e0, n0 = frame.to_local(part["lat_true"].to_numpy(), part["lon_true"].to_numpy())
    e1, n1 = frame.to_local(part["lat"].to_numpy(), part["lon"].to_numpy())
    return e0, n0, e1 - e0, n1 - n0


def check_gnss(out: pd.DataFrame, scale: float) -> int:
    """Assert every bound and label rule of the protocol on ``out``; the episodes checked."""
    bias = out["label_bias"].to_numpy(dtype=object)
    anomaly = out["label_anomaly"].to_numpy() == 1
    np.testing.assert_array_equal(anomaly, bias != "none")
    np.testing.assert_array_equal(anomaly, (out["label_time"] != "none").to_numpy())
    np.testing.assert_array_equal(
        anomaly, (out["label_lat"].to_numpy() == 1) | (out["label_lon"].to_numpy() == 1)
    )
    added = np.isin(bias, GNSS_TYPES)
    for ch in ("lat", "lon"):
        # The added types move both channels: the same episode, the same labels on both.
        np.testing.assert_array_equal(out.loc[added, f"label_bias_{ch}"], bias[added])
        np.testing.assert_array_equal(
            out.loc[added, f"label_episode_{ch}"], out.loc[added, "label_episode"]
        )
    # Rows without a label are exactly the truth, and the receiver says nothing new there.
    clean = ~anomaly
    np.testing.assert_array_equal(out.loc[clean, "lat"], out.loc[clean, "lat_true"])
    np.testing.assert_array_equal(out.loc[clean, "lon"], out.loc[clean, "lon_true"])
    assert (out.loc[clean, "label_offset_m"] == 0).all()
    outage = bias == "outage"
    assert (out.loc[outage, "fix_quality"] == 0).all()
    assert (out.loc[outage, "satellites"] == 0).all()
    assert (out.loc[outage, "hdop"] == 99.99).all()
    assert not (out.loc[~outage, "fix_quality"] == 0).any()
    # grad's own rows: one channel moved at a time, the other bit-identical.
    for ch, other in (("lat", "lon"), ("lon", "lat")):
        only = (out[f"label_{ch}"] == 1) & (out[f"label_{other}"] == 0)
        np.testing.assert_array_equal(out.loc[only, other], out.loc[only, f"{other}_true"])
    checked = 0
    for _, part in out.groupby("drive", sort=False):
        t = part["t"].to_numpy()
        e0, n0, de, dn = _frame_offsets(part)
        size = np.hypot(de, dn)
        for ch in ("lat", "lon"):
            spans = runs(part[f"label_episode_{ch}"].to_numpy())
            for (_, _, end), (_, start, _) in itertools.pairwise(spans):
                assert start - end - 1 >= 10, "10 normal fixes between episodes of a channel"
        for e, first, last in runs(part["label_episode"].to_numpy()):
            kinds = set(part["label_bias"].iloc[first : last + 1])
            kind = kinds.pop()
            if kind not in GNSS_TYPES:
                continue
            assert not kinds, "an added episode is contiguous and of one type"
            idx = np.arange(first, last + 1)
            assert (part["label_episode"].to_numpy()[idx] == e).all()
            np.testing.assert_allclose(part["label_offset_m"].to_numpy()[idx], size[idx], atol=0.01)
            ref = first - 1
            ended = last + 1 < len(part)
            if kind in ("freeze", "outage") or (kind == "drift" and ended):
                assert ended, "a true fix follows"
                assert part["label_anomaly"].iloc[last + 1] == 0
            if kind == "freeze":
                assert (part["lat"].to_numpy()[idx] == part["lat"].iloc[ref]).all()
                assert (part["lon"].to_numpy()[idx] == part["lon"].iloc[ref]).all()
                assert (size[idx] > 0).all(), "the vehicle moves away from the frozen fix"
                onset = np.hypot(e0[first] - e0[ref], n0[first] - n0[ref]) / (t[first] - t[ref])
                assert onset >= 10.0
                assert t[last] - t[ref] < 60.0
                assert t[last + 1] - t[ref] >= 3.0
            elif kind == "outage":
                lat = part["lat"].to_numpy()[idx]
                assert np.isnan(lat).all() or (lat == part["lat"].iloc[ref]).all()
                assert t[last] - t[first] < 30.0
                assert t[last + 1] - t[first] >= 1.0
            elif kind == "multipath":
                assert (size[idx] >= 10 * scale - 0.01).all()
                assert (size[idx] <= 80 * scale + 0.01).all()
                assert t[last] - t[first] < 20.0
                assert not ended or t[last + 1] - t[first] >= 2.0
                assert part["label_time"].iloc[first] == "transient"
            else:
                grown = t[idx] - t[ref]
                rate = size[idx] / np.minimum(grown, grown.max())
                held = part["label_time"].iloc[first] == "permanent"
                assert held == (not ended), "a held drift lasts to the end of its track"
                ramp = np.diff(size[idx]) > 1e-6
                if held:
                    flat = np.flatnonzero(~ramp)
                    if flat.size:  # the final offset held for up to 120 s
                        np.testing.assert_allclose(size[idx][flat[0] :], size[last], atol=0.01)
                        assert t[last] - t[first + flat[0]] <= 120.0
                    ramp_s = size[last] / (size[first] / (t[first] - t[ref]))
                    assert 20.0 - 0.01 <= ramp_s <= 300.0 + 0.01
                else:
                    assert ramp.all(), "a drift grows until it snaps back"
                    assert t[last] - t[ref] < 300.0
                    assert t[last + 1] - t[ref] >= 20.0
                first_rate = size[first] / (t[first] - t[ref])
                assert 0.2 * scale - 1e-6 <= first_rate <= 3.0 * scale + 1e-6
                np.testing.assert_allclose(
                    rate[: max(int(ramp.sum()), 1)], first_rate, rtol=1e-5, atol=1e-6
                )
                angle = np.arctan2(de[idx], dn[idx])
                np.testing.assert_allclose(np.cos(angle - angle[0]), 1.0, atol=1e-6)
            checked += 1
    return checked


def test_bounds_and_labels_on_long_drives() -> None:
    out = inject_gnss(drives([5000, 3000, 900, 40]), seed=1, scale=1.0)
    assert check_gnss(out, 1.0) > 20


@settings(max_examples=20, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 1500), min_size=1, max_size=3),
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from([0.5, 1.0, 2.0]),
    rate_hz=st.sampled_from([0.5, 1.0, 4.0]),
)
def test_bounds_and_labels_hold_for_any_drive(
    lengths: list[int], seed: int, scale: float, rate_hz: float
) -> None:
    check_gnss(inject_gnss(drives(lengths, rate_hz=rate_hz), seed=seed, scale=scale), scale)


def test_achieved_shares_follow_the_targets() -> None:
    out = inject_gnss(drives([3000] * 10), seed=2)
    rates = gnss_rates(out)
    for kind, target in GNSS_RATES.items():
        assert abs(rates.loc[kind, "rows"] - 100 * target) <= 0.6, (kind, rates.loc[kind])
    # grad's noise and jump still come at its own rates, placed around the added types.
    grad_share = rates.loc["noise", "rows"] + rates.loc["jump", "rows"]
    assert 15.0 < grad_share < 22.0


def test_outage_writes_into_the_inputs_own_quality_columns() -> None:
    table = drives([3000, 3000]).assign(sats=8, fix=1, hdop=1.1)
    out = inject_gnss(table, seed=5)
    outage = out["label_bias"] == "outage"
    assert outage.any()
    assert not {"fix_quality", "satellites"} & set(out.columns)
    assert (out.loc[outage, ["sats", "fix"]] == 0).all().all()
    assert (out.loc[outage, "hdop"] == 99.99).all()
    assert (out.loc[~outage, ["sats", "fix", "hdop"]] == [8, 1, 1.1]).all().all()
    pd.testing.assert_series_equal(out["speed_mps"], table["speed_mps"])


def test_added_quality_columns_are_missing_outside_outages() -> None:
    out = inject_gnss(drives([3000]), seed=5)
    outage = (out["label_bias"] == "outage").to_numpy()
    for col in ("fix_quality", "satellites", "hdop"):
        assert out.loc[~outage, col].isna().all()


def test_unusable_rows_are_left_alone_and_scale_is_checked() -> None:
    table = drives([2000])
    table.loc[[5, 300, 1200], "lat"] = np.nan
    out = inject_gnss(table, seed=0)
    assert out.loc[[5, 300, 1200], "label_anomaly"].eq(0).all()
    with pytest.raises(ConfigError, match="scale"):
        inject_gnss(table, seed=0, scale=-1.0)


def test_rates_and_ranges_are_the_documented_ones() -> None:
    """docs/protocols.md states these numbers; a change must change the page too."""
    from pathlib import Path

    page = (Path(__file__).parents[1] / "docs" / "protocols.md").read_text()
    assert inj.FREEZE_S == (3.0, 60.0)
    assert "3-60 s" in page
    assert inj.DRIFT_S == (20.0, 300.0)
    assert "20-300 s" in page
    assert inj.DRIFT_RATE_MPS == (0.2, 3.0)
    assert "0.2-3 m/s" in page
    assert inj.DRIFT_HOLD_S == (10.0, 120.0)
    assert "10-120 s" in page
    assert inj.MULTIPATH_M == (10.0, 80.0)
    assert "10-80 m" in page
    assert inj.MULTIPATH_S == (2.0, 20.0)
    assert inj.MULTIPATH_TAU_S == (2.0, 20.0)
    assert inj.OUTAGE_S == (1.0, 30.0)
    assert "1-30 s" in page
    for kind, rate in GNSS_RATES.items():
        assert f"| {kind} | {100 * rate:g} %" in page, kind
