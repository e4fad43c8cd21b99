"""Preprocessing: nothing lost, order restored, duplicates merged, gaps filled or split."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, preprocess, to_fixes


def _fixes(t: list[float], track: list[str] | None = None, **cols: list[float]) -> pd.DataFrame:
    n = len(t)
    lat = cols.pop("lat", [41.25 + 1e-4 * i for i in range(n)])
    lon = cols.pop("lon", [-95.98 + 1e-4 * i for i in range(n)])
    data = {"track": track or ["a"] * n, "t": t, "lat": lat, "lon": lon, **cols}
    return to_fixes(pd.DataFrame(data))


def test_sorts_merges_and_maps_rows_back() -> None:
    fx = _fixes([3.0, 1.0, 2.0, 2.0, 4.0], speed=[3.0, 1.0, 2.0, 4.0, 5.0])
    p = preprocess(fx)
    assert p.points["t"].tolist() == [1.0, 2.0, 3.0, 4.0]
    assert p.row_point.tolist() == [2, 0, 1, 1, 3]
    assert p.points["speed"].tolist() == [1.0, 3.0, 3.0, 5.0]  # duplicates averaged
    assert p.points["n_rows"].tolist() == [1, 2, 1, 1]
    assert p.to_rows(p.points["t"].to_numpy()).tolist() == fx["t"].tolist()


def test_short_gap_interpolated_long_gap_split() -> None:
    t = [0.0, 1.0, 2.0, 5.0, 6.0, 20.0, 21.0, 22.0]
    p = preprocess(_fixes(t), max_gap_s=5.0)
    pts = p.points
    assert pts["t"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 20.0, 21.0, 22.0]
    assert pts["interpolated"].tolist() == [False] * 3 + [True] * 2 + [False] * 5
    assert pts["segment"].tolist() == [0] * 7 + [1] * 3
    assert pts["n_rows"].tolist() == [1, 1, 1, 0, 0, 1, 1, 1, 1, 1]
    # Interpolated positions lie between their neighbours.
    north = pts["north"].to_numpy()
    assert north[2] < north[3] < north[4] < north[5]


def test_heading_merged_and_interpolated_on_the_circle() -> None:
    p = preprocess(_fixes([0.0, 0.0, 1.0, 2.0, 4.0], heading=[350.0, 10.0, 350.0, 350.0, 10.0]))
    assert p.points["t"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    h = p.points["heading"].to_numpy()
    assert min(h[0], 360 - h[0]) == pytest.approx(0.0, abs=1e-9)  # merged 350 and 10
    assert min(h[3], 360 - h[3]) == pytest.approx(0.0, abs=1e-6)  # between 350 and 10


def test_invalid_rows_set_aside_with_reason() -> None:
    fx = _fixes(
        [0.0, 1.0, np.nan, 3.0, 4.0],
        lat=[41.0, np.nan, 41.0, 95.0, 41.0],
        lon=[-95.0, -95.0, -95.0, -95.0, 200.0],
    )
    p = preprocess(fx)
    assert p.row_point.tolist()[0] == 0
    assert (p.row_point[1:] == -1).all()
    assert list(p.row_reason) == [
        "",
        "latitude missing or not finite",
        "time missing or not finite",
        "latitude outside +-90",
        "longitude outside +-180",
    ]


def test_tracks_get_their_own_frames_and_segments() -> None:
    fx = _fixes(
        [0.0, 1.0, 0.0, 1.0],
        track=["x", "x", "y", "y"],
        lat=[10.0, 10.0001, 50.0, 50.0001],
        lon=[20.0, 20.0, 30.0, 30.0],
    )
    p = preprocess(fx)
    assert set(p.frames) == {"x", "y"}
    assert p.points["segment"].tolist() == [0, 0, 1, 1]
    assert p.points["east"].abs().max() < 1e-6
    assert [s for s, _ in p.segment_slices()] == [0, 1]


def test_empty_input_and_bad_parameters() -> None:
    p = preprocess(_fixes([]))
    assert len(p.points) == 0
    assert p.row_point.size == 0
    with pytest.raises(ConfigError):
        preprocess(_fixes([0.0]), max_gap_s=0)
    with pytest.raises(ConfigError):
        preprocess(pd.DataFrame({"t": [0.0]}))


@st.composite
def messy_tracks(draw: st.DrawFn) -> pd.DataFrame:
    n = draw(st.integers(0, 60))
    t = draw(
        st.lists(st.sampled_from([float(x) for x in range(40)] + [np.nan]), min_size=n, max_size=n)
    )
    track = draw(st.lists(st.sampled_from(["a", "b", "c"]), min_size=n, max_size=n))
    lat = draw(st.lists(st.floats(-0.01, 0.01), min_size=n, max_size=n))
    lon = draw(st.lists(st.floats(-0.01, 0.01), min_size=n, max_size=n))
    return to_fixes(
        pd.DataFrame({"track": track, "t": t, "lat": np.add(lat, 45.0), "lon": np.add(lon, 7.0)})
    )


@settings(max_examples=150, deadline=None)
@given(fx=messy_tracks(), max_gap=st.sampled_from([1.0, 2.5, 5.0, 100.0]))
def test_every_row_accounted_for_and_order_restored(fx: pd.DataFrame, max_gap: float) -> None:
    p = preprocess(fx, max_gap_s=max_gap)
    pts = p.points
    valid = p.row_reason == ""
    assert ((p.row_point >= 0) == valid).all()
    assert (p.row_point < len(pts)).all()
    # Each valid row maps to a point of its own track and time.
    rp = p.row_point[valid]
    assert (pts["t"].to_numpy()[rp] == fx["t"].to_numpy()[valid]).all()
    assert (pts["track"].to_numpy()[rp] == fx["track"].to_numpy()[valid]).all()
    # Every non-interpolated point stands for at least one row; counts add up.
    assert int(pts["n_rows"].sum()) == int(valid.sum())
    assert ((pts["n_rows"] == 0) == pts["interpolated"]).all()
    # Strictly increasing time within a segment, steps bounded by the gap limit.
    for _, sl in p.segment_slices():
        t = pts["t"].to_numpy()[sl]
        assert (np.diff(t) > 0).all()
        assert (np.diff(t) <= max_gap).all()
        assert pts["track"].to_numpy()[sl].tolist().count(pts["track"].iloc[sl.start]) == t.size
