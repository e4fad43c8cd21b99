"""Fault injection protocols: determinism, exact labels, episode shapes, achieved rates."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, InputError, LocalFrame
from gradgps._data.datasets import load_dataset
from gradgps._data.inject import (
    GRAD_RATES,
    GRAVITY,
    SENSOR_CHANNELS,
    SENSOR_GRID_ROWS,
    grad_rates,
    inject_grad,
    inject_sensor_grid,
    sensor_grid_row,
    with_fix_speed,
)


def drives(lengths: list[int], *, rate_hz: float = 1.0) -> pd.DataFrame:
    """Clean synthetic drives (15 m/s east with a gentle weave), one per length."""
    frame = LocalFrame(52.5, 13.4)
    parts = []
    for k, n in enumerate(lengths):
        t = np.arange(n) / rate_hz
        lat, lon = frame.to_geodetic(15.0 * t + 1000.0 * k, 20.0 * np.sin(t / 30.0))
        parts.append(
            pd.DataFrame(
                {
                    "drive": k,
                    "t": 1.6e9 + t,
                    "lat": lat,
                    "lon": lon,
                    "speed_mps": 15.0 + np.sin(t),
                    "accel_x_g": 0.05 * np.cos(t),
                    "gyro_z_dps": 2.0 * np.sin(t / 7.0),
                    "note": "x",
                }
            )
        )
    return pd.concat(parts, ignore_index=True)


def runs(episode: np.ndarray) -> list[tuple[int, int, int]]:
    """(episode id, first index, last index) per episode, in order of first index."""
    out = []
    for e in np.unique(episode[episode >= 0]):
        idx = np.flatnonzero(episode == e)
        out.append((int(e), int(idx[0]), int(idx[-1])))
    return sorted(out, key=lambda r: r[1])


def channel_offsets_m(labelled: pd.DataFrame, channel: str) -> np.ndarray:
    """Injected offset in metres per row on one channel, measured back in each track's frame."""
    out = np.zeros(len(labelled))
    for _, rows in labelled.groupby("drive", sort=False).groups.items():
        r = np.asarray(rows)
        part = labelled.loc[r]
        frame = LocalFrame(float(part["lat_true"].iloc[0]), float(part["lon_true"].iloc[0]))
        e0, n0 = frame.to_local(part["lat_true"], part["lon_true"])
        if channel == "lat":
            e1, n1 = frame.to_local(part["lat"], part["lon_true"])
            out[r] = n1 - n0
        else:
            e1, n1 = frame.to_local(part["lat_true"], part["lon"])
            out[r] = e1 - e0
    return out


# ------------------------------------------------------------------- grad


def test_grad_same_seed_same_output_and_other_seed_differs() -> None:
    table = drives([900, 450])
    a = inject_grad(table, seed=7)
    b = inject_grad(table, seed=7)
    c = inject_grad(table, seed=8)
    assert a.to_csv(index=False) == b.to_csv(index=False)
    assert not a["label_lat"].equals(c["label_lat"])


def test_grad_keeps_input_columns_and_adds_labels() -> None:
    table = drives([500])
    out = inject_grad(table, seed=1)
    assert list(out.columns[: table.shape[1]]) == list(table.columns)
    for col in (
        "label_anomaly",
        "label_lat",
        "label_lon",
        "label_bias",
        "label_time",
        "lat_true",
        "lon_true",
    ):
        assert col in out.columns
    untouched = [c for c in table.columns if c not in ("lat", "lon")]
    pd.testing.assert_frame_equal(out[untouched], table[untouched])
    np.testing.assert_array_equal(out["lat_true"], table["lat"])


@settings(max_examples=25, deadline=None)
@given(
    lengths=st.lists(st.integers(1, 1300), min_size=1, max_size=3),
    seed=st.integers(0, 2**32 - 1),
    scale=st.sampled_from([0.3, 1.0, 4.0]),
)
def test_grad_labels_mark_exactly_the_changed_points_and_episodes_keep_apart(
    lengths: list[int], seed: int, scale: float
) -> None:
    out = inject_grad(drives(lengths), seed=seed, scale=scale)
    changed_lat = (out["lat"] != out["lat_true"]).to_numpy()
    changed_lon = (out["lon"] != out["lon_true"]).to_numpy()
    np.testing.assert_array_equal(out["label_lat"].to_numpy() == 1, changed_lat)
    np.testing.assert_array_equal(out["label_lon"].to_numpy() == 1, changed_lon)
    np.testing.assert_array_equal(out["label_anomaly"].to_numpy() == 1, changed_lat | changed_lon)
    for ch in ("lat", "lon"):
        for _, part in out.groupby("drive", sort=False):
            spans = runs(part[f"label_episode_{ch}"].to_numpy())
            for (_, _, end), (_, start, _) in itertools.pairwise(spans):
                assert start - end - 1 >= 10, "episodes on one channel keep 10 normal points apart"


def test_grad_episode_shapes_and_magnitudes() -> None:
    scale = 2.0
    out = inject_grad(drives([4000, 1200, 80]), seed=3, scale=scale)
    for ch in ("lat", "lon"):
        offset = channel_offsets_m(out, ch)
        for _, part in out.groupby("drive", sort=False):
            pos = np.arange(len(part))
            ep = part[f"label_episode_{ch}"].to_numpy()
            kinds = part[f"label_time_{ch}"].to_numpy()
            biases = part[f"label_bias_{ch}"].to_numpy()
            off = offset[part.index.to_numpy()]
            for e, first, last in runs(ep):
                idx = pos[ep == e]
                kind = set(kinds[idx])
                bias = set(biases[idx])
                assert len(kind) == 1
                assert len(bias) == 1
                kind_s, bias_s = kind.pop(), bias.pop()
                span = last - first + 1
                if kind_s == "transient":
                    assert 1 <= span <= 5
                    assert idx.size == span
                elif kind_s == "permanent":
                    assert 20 <= span <= 100
                    assert idx.size == span
                    assert (last + 1) % 400 == 0 or last == len(part) - 1
                    assert first // 400 == last // 400, "a permanent fault ends its segment"
                else:
                    assert 20 <= span <= 60
                    steps = np.diff(idx)
                    bursts = np.split(idx, np.flatnonzero(steps > 1) + 1)
                    assert 3 <= len(bursts) <= 6
                    assert all(1 <= b.size <= 3 for b in bursts)
                    pauses = steps[steps > 1] - 1
                    assert np.all((pauses >= 3) & (pauses <= 15))
                assert first // 400 == last // 400, "episodes stay inside their segment"
                mag = np.abs(off[idx])
                if bias_s == "noise":
                    assert np.all((mag > 10 * scale - 0.01) & (mag < 50 * scale + 0.01))
                else:
                    assert np.all((mag > 20 * scale - 0.01) & (mag < 200 * scale + 0.01))
                    np.testing.assert_allclose(off[idx], off[idx[0]], atol=0.01)


def test_grad_combined_labels_follow_the_documented_priority() -> None:
    out = inject_grad(drives([6000]), seed=11)
    both = (out["label_lat"] == 1) & (out["label_lon"] == 1)
    assert both.any()
    rank = {"none": 0, "transient": 1, "intermittent": 2, "permanent": 3}
    for _, r in out[both].iterrows():
        lat_key = (rank[r["label_time_lat"]], r["label_bias_lat"] == "jump")
        lon_key = (rank[r["label_time_lon"]], r["label_bias_lon"] == "jump")
        winner = "lon" if lon_key > lat_key else "lat"
        assert r["label_time"] == r[f"label_time_{winner}"]
        assert r["label_bias"] == r[f"label_bias_{winner}"]
    only_lat = (out["label_lat"] == 1) & (out["label_lon"] == 0)
    assert (out.loc[only_lat, "label_time"] == out.loc[only_lat, "label_time_lat"]).all()
    assert (out.loc[out["label_anomaly"] == 0, "label_time"] == "none").all()


def test_grad_leaves_unusable_rows_alone() -> None:
    table = drives([600])
    table.loc[[5, 300], "lat"] = np.nan
    out = inject_grad(table, seed=0)
    assert out.loc[[5, 300], "label_anomaly"].eq(0).all()
    assert out.loc[[5, 300], "lat"].isna().all()


def test_grad_rejects_a_non_positive_scale() -> None:
    with pytest.raises(ConfigError, match="scale"):
        inject_grad(drives([50]), seed=0, scale=0.0)


@pytest.mark.shared
@pytest.mark.parametrize("seed", [0, 1])
def test_grad_rates_on_driveplotr_train_are_within_half_a_point(
    shared_data: Path, seed: int
) -> None:
    out = inject_grad(load_dataset("driveplotr", "train", data_dir=shared_data), seed=seed)
    rates = grad_rates(out)
    for kind, target in GRAD_RATES.items():
        for ch in ("lat", "lon"):
            assert abs(rates.loc[kind, ch] - 100 * target) <= 0.5, (kind, ch, rates.loc[kind, ch])
    noise_share = rates.loc["total", "noise"] / (
        rates.loc["total", "noise"] + rates.loc["total", "jump"]
    )
    assert 0.5 < noise_share < 0.7


# ------------------------------------------------------------ sensor-grid


def test_sensor_grid_has_the_19_rows_of_the_table() -> None:
    names = [r.name for r in SENSOR_GRID_ROWS]
    assert len(names) == 19
    assert names[:2] == ["instant-25", "instant-100"]
    assert {"constant-1-10", "bias-5-3", "drift-4-20", "drift-2-10"} <= set(names)
    assert sensor_grid_row("mixed") is None
    with pytest.raises(ConfigError, match="known rows"):
        sensor_grid_row("bias-9-9")


def test_sensor_grid_same_seed_same_output() -> None:
    table = drives([700, 300])
    a = inject_sensor_grid(table, row="mixed", seed=5).to_csv(index=False)
    assert a == inject_sensor_grid(table, row="mixed", seed=5).to_csv(index=False)
    assert a != inject_sensor_grid(table, row="mixed", seed=6).to_csv(index=False)


@pytest.mark.parametrize("row", [*(r.name for r in SENSOR_GRID_ROWS), "mixed"])
def test_sensor_grid_episodes_follow_their_row(row: str) -> None:
    table = drives([1500, 400])
    scale = 1.5
    out = inject_sensor_grid(table, row=row, seed=2, scale=scale)
    spec = sensor_grid_row(row)
    assert "accel_x_mps2" in out.columns
    np.testing.assert_allclose(out["accel_x_g"] * GRAVITY, out["accel_x_mps2"])
    per_channel = np.stack([out[f"label_{c}"].to_numpy() for c in SENSOR_CHANNELS])
    assert per_channel.sum(axis=0).max() == 1, "one faulty channel at a time"
    np.testing.assert_array_equal(per_channel.sum(axis=0), out["label_anomaly"])
    assert out["label_anomaly"].mean() > 0.01
    for c in SENSOR_CHANNELS:
        clean = out[f"label_{c}"] == 0
        np.testing.assert_array_equal(out.loc[clean, c], out.loc[clean, f"{c}_true"])
    for _, part in out.groupby("drive", sort=False):
        ep = part["label_episode"].to_numpy()
        for e, first, last in runs(ep):
            idx = np.arange(first, last + 1)
            assert np.all(ep[idx] == e), "an episode is contiguous"
            kind = part["label_type"].iloc[first]
            of_kind = [r for r in SENSOR_GRID_ROWS if r.kind == kind] if spec is None else [spec]
            assert kind == of_kind[0].kind
            at_end = last == len(part) - 1
            assert at_end or idx.size in {r.duration for r in of_kind}
            a = max(r.magnitude for r in of_kind) * scale
            ch = next(c for c in SENSOR_CHANNELS if part[f"label_{c}"].iloc[first] == 1)
            x = part[ch].to_numpy()[idx]
            truth = part[f"{ch}_true"].to_numpy()[idx]
            if kind == "constant":
                assert np.all(x == x[0])
                assert 0 <= x[0] - truth[0] <= a
            elif kind == "bias":
                d = x - truth
                np.testing.assert_allclose(d, d[0], atol=1e-9)
                assert 0 <= d[0] <= a
            elif kind == "drift":
                d = x - truth
                assert abs(d[0]) < 1e-9, "a drift starts at zero offset, still labelled"
                assert np.all(np.diff(d) > 0)
                if spec is not None:
                    np.testing.assert_allclose(
                        d, np.linspace(0, a, spec.duration)[: idx.size], atol=1e-9
                    )
            elif kind == "instant":
                assert abs(x[0] - truth[0]) < a * 0.1 * 6  # six sigma


def test_sensor_grid_needs_its_channels() -> None:
    with pytest.raises(InputError, match="gyro_z_dps"):
        inject_sensor_grid(drives([50]).drop(columns=["gyro_z_dps"]), row="bias-5-3", seed=0)
    with pytest.raises(InputError, match="speed"):
        inject_sensor_grid(drives([50]).drop(columns=["speed_mps"]), row="bias-5-3", seed=0)


def test_constant_offset_mode_adds_one_offset_and_stuck_mode_holds_the_value() -> None:
    table = drives([800])
    stuck = inject_sensor_grid(table, row="constant-5-10", seed=3)
    offset = inject_sensor_grid(table, row="constant-5-10", seed=3, constant="offset")
    # Same draws: the same episodes, only how the value is written differs.
    np.testing.assert_array_equal(stuck["label_episode"], offset["label_episode"])
    found = 0
    for e, first, last in runs(offset["label_episode"].to_numpy()):
        idx = np.arange(first, last + 1)
        ch = next(c for c in SENSOR_CHANNELS if offset[f"label_{c}"].iloc[first] == 1)
        d = offset[ch].to_numpy()[idx] - offset[f"{ch}_true"].to_numpy()[idx]
        np.testing.assert_allclose(d, d[0], atol=1e-9)
        assert 0 <= d[0] <= 5.0
        held = stuck[ch].to_numpy()[idx]
        assert np.all(held == held[0])
        assert held[0] - offset[f"{ch}_true"].to_numpy()[first] == pytest.approx(d[0])
        found += e >= 0
    assert found > 5
    with pytest.raises(ConfigError, match="stuck, offset"):
        inject_sensor_grid(table, row="constant-5-10", seed=3, constant="frozen")


def test_fix_speed_is_the_distance_over_the_time_step_and_is_never_corrupted() -> None:
    table = drives([300, 50])
    with_fix = with_fix_speed(table)
    v = with_fix["speed_fix_mps"].to_numpy()
    first = with_fix.groupby("drive").head(1).index
    assert np.isnan(v[first]).all()
    # 15 m/s east plus the weave's north speed: within a few cm/s of the truth.
    rest = np.setdiff1d(np.arange(len(v)), first)
    t = (with_fix["t"].to_numpy() - 1.6e9)[rest]
    expected = np.hypot(15.0, 20.0 / 30.0 * np.cos((t - 0.5) / 30.0))
    np.testing.assert_allclose(v[rest], expected, atol=0.05)
    out = inject_sensor_grid(with_fix, row="mixed", seed=1)
    np.testing.assert_array_equal(out["speed_fix_mps"].to_numpy(), v)
