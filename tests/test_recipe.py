"""The shipped model's training recipe and the frozen-fix faults it adds."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gradgps import inject_grad, simulate_fleet
from gradgps._data.inject import inject_freeze
from gradgps._exceptions import ConfigError
from gradgps._train.recipe import DefaultRecipe, decimate_tracks, recipe_tables

SIM_ONLY = DefaultRecipe(
    sim_rates_hz=(0.5, 1.0, 10.0), sim_tracks=(3, 3, 2), sim_minutes=2.0, real_datasets=()
)


def _labelled(seed: int = 0) -> pd.DataFrame:
    sim = simulate_fleet(4, 6.0, 1.0, 5, imu=False)
    return inject_grad(sim[["track", "t", "lat", "lon"]], seed=seed)


def test_freeze_holds_only_clean_moving_fixes_and_is_seeded() -> None:
    labelled = _labelled()
    frozen = inject_freeze(labelled, seed=3, share=0.05, stale_start=1.0)
    again = inject_freeze(labelled, seed=3, share=0.05, stale_start=1.0)
    pd.testing.assert_frame_equal(frozen, again)
    held = frozen["label_bias"].to_numpy() == "freeze"
    assert held.sum() > 0
    # Only rows the grad protocol left clean are frozen.
    assert (labelled["label_anomaly"].to_numpy()[held] == 0).all()
    assert (frozen["label_anomaly"].to_numpy()[held] == 1).all()
    # Every other row is untouched.
    for col in ("lat", "lon", "label_anomaly"):
        np.testing.assert_array_equal(
            frozen[col].to_numpy()[~held], labelled[col].to_numpy()[~held]
        )
    # A hold repeats one position: within a run of held rows the fix does not move.
    for _, g in frozen.groupby("track"):
        h = g["label_bias"].to_numpy() == "freeze"
        lat = g["lat"].to_numpy()
        same = np.r_[False, np.diff(lat) == 0]
        inner = h & np.r_[False, h[:-1]]
        assert same[inner].all()


def test_freeze_jump_back_is_not_labelled() -> None:
    labelled = _labelled(1)
    frozen = inject_freeze(labelled, seed=0, share=0.05, stale_start=0.0)
    held = (frozen["label_bias"].to_numpy() == "freeze").astype(int)
    ends = np.flatnonzero(np.diff(held) == -1) + 1  # first fix after a hold
    assert ends.size > 0
    assert (
        frozen["label_anomaly"].to_numpy()[ends] == labelled["label_anomaly"].to_numpy()[ends]
    ).all()


def test_freeze_rejects_bad_shares() -> None:
    with pytest.raises(ConfigError):
        inject_freeze(_labelled(), seed=0, share=1.5)


def test_decimate_keeps_order_and_spacing() -> None:
    table = pd.DataFrame(
        {
            "track": ["a"] * 6 + ["b"] * 3,
            "t": [0, 1, 2, 3, 4, 5, 0, 0.5, 2.1],
            "lat": 0.0,
            "lon": 0.0,
        }
    )
    out = decimate_tracks(table, 2.0)
    assert out["t"].tolist() == [0, 2, 4, 0, 2.1]
    assert out["track"].tolist() == ["a", "a", "a", "b", "b"]


def test_recipe_mixes_rates_and_column_sets() -> None:
    tables = recipe_tables("train", SIM_ONLY)
    columns = {tuple(sorted(t.columns)) for t in tables}
    assert ("lat", "lon", "t", "track") in columns
    assert ("heading", "lat", "lon", "speed", "t", "track") in columns
    periods = set()
    for t in tables:
        for _, g in t.groupby("track"):
            periods.add(round(float(np.median(np.diff(g["t"].to_numpy()))), 1))
    assert {0.1, 1.0, 2.0} <= periods
    # Same settings, same tables (seeded).
    again = recipe_tables("train", SIM_ONLY)
    assert len(again) == len(tables)
    for a, b in zip(tables, again, strict=True):
        pd.testing.assert_frame_equal(a, b)
    # Validation drives are other drives.
    val = recipe_tables("validation", SIM_ONLY)
    train_first = {float(t["lat"].iloc[0]) for t in tables}
    assert not train_first & {float(t["lat"].iloc[0]) for t in val}


def test_recipe_has_no_test_split() -> None:
    with pytest.raises(ConfigError, match="train and validation"):
        recipe_tables("test", SIM_ONLY)


def test_real_glitches_are_cut_out_and_split_the_track() -> None:
    from gradgps._train.recipe import _canonical

    table = pd.DataFrame(
        {
            "track": ["x"] * 8,
            "t": np.arange(8.0),
            "lat": 48.0 + np.arange(8) * 1e-4,
            "lon": 11.0,
            "glitch": [0, 0, 0, 1, 1, 0, 0, 0],
        }
    )
    out = _canonical(table, "d-")
    assert len(out) == 6
    assert out["track"].tolist() == ["d-x~0"] * 3 + ["d-x~2"] * 3


def test_thinning_tolerates_jittered_stamps() -> None:
    """A 1 Hz receiver with +-5 % jitter thinned to 1 Hz keeps every fix; to 2 s, every other."""
    from gradgps._tracks.thin import thin_mask

    t = np.arange(20.0) + np.tile([0.0, -0.05, 0.04, -0.03], 5)
    tracks = np.full(20, "a", dtype=object)
    assert thin_mask(tracks, t, 1.0).all()
    assert thin_mask(tracks, t, 2.0).sum() == 10
    assert not thin_mask(tracks, np.full(3, np.nan), 1.0).any()


def test_freeze_holds_start_on_a_moving_vehicle() -> None:
    """A hold that starts as the car brakes to a stop is a real stop, not a fault:
    every hold starts after a step of at least 10 m/s."""
    from gradgps._tracks.geo import haversine_m

    labelled = _labelled(3)
    frozen = inject_freeze(labelled, seed=0, share=0.05, stale_start=0.0)
    held = frozen["label_bias"].to_numpy() == "freeze"
    starts = np.flatnonzero(np.diff(held.astype(int)) == 1) + 1  # first held fix
    assert starts.size > 0
    lat = labelled["lat"].to_numpy()
    lon = labelled["lon"].to_numpy()
    t = labelled["t"].to_numpy()
    # The true step into the first held fix (the car's speed when the fix froze).
    speed = haversine_m(lat[starts - 1], lon[starts - 1], lat[starts], lon[starts]) / (
        t[starts] - t[starts - 1]
    )
    assert (speed >= 9.0).all()


def test_stale_start_fixes_teach_nothing_and_the_fixes_after_the_jump_teach_normal() -> None:
    """A stale start's held fixes cannot be told from a parked car until the jump:
    they carry the ignore label (their loss does not count), every other point
    keeps its label, and the first fix after the jump is normal (a cold start's
    jump to the truth ends a fault; Austin validation: a real one)."""
    from gradgps._grad.pipeline import PipelineParams
    from gradgps._train.grad import labelled_sequences
    from gradgps._train.labels import IGNORE_LABEL

    labelled = _labelled(2)
    # A stale start needs its track's first fixes free of grad's faults.
    frozen = next(
        f
        for f in (inject_freeze(labelled, seed=s, share=0.0, stale_start=1.0) for s in range(50))
        if f["label_stale"].sum() > 0
    )
    stale = frozen["label_stale"].to_numpy()
    assert (frozen["label_anomaly"].to_numpy()[stale == 1] == 1).all()
    sequences = labelled_sequences(frozen, PipelineParams())
    anomaly = np.concatenate([s[1] for s in sequences])
    bias = np.concatenate([s[2] for s in sequences])
    assert anomaly.size == len(frozen)  # one point per row in this table
    np.testing.assert_array_equal(anomaly == IGNORE_LABEL, stale == 1)
    np.testing.assert_array_equal(bias == IGNORE_LABEL, stale == 1)
    kept = stale == 0
    np.testing.assert_array_equal(anomaly[kept], frozen["label_anomaly"].to_numpy()[kept])
    after = np.flatnonzero(np.diff(stale) == -1) + 1
    assert (anomaly[after] == labelled["label_anomaly"].to_numpy()[after]).all()
