"""pandas, GeoPandas and movingpandas users hand their data over and get the same type back."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import gradgps
from gradgps import Detector, InputError
from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet

RESULT = ["anomaly", "score", "bias_type", "time_type", "lat_clean", "lon_clean", "alert"]


def _drives(n: int = 2, minutes: float = 3.0) -> pd.DataFrame:
    frame = inject_grad(simulate_fleet(n, minutes, 1.0, seed=4), seed=3)
    return frame[["track", "t", "lat", "lon", "speed"]].reset_index(drop=True)


def test_columns_by_keyword_and_errors_name_python_arguments() -> None:
    drives = _drives(1).rename(columns={"t": "when", "lat": "north_deg", "lon": "east_deg"})
    with pytest.raises(InputError, match="time=") as err:
        gradgps.detect(drives)
    assert "--time-col" not in str(err.value)
    out = gradgps.detect(drives, time="when", lat="north_deg", lon="east_deg")
    assert list(out.columns[: drives.shape[1]]) == list(drives.columns)
    assert set(RESULT) <= set(out.columns)
    base = Detector().detect(_drives(1))
    np.testing.assert_array_equal(out["score"].to_numpy(), base["score"].to_numpy())


def test_datetime_index_is_the_time() -> None:
    drives = _drives(1)
    indexed = drives.drop(columns="t").set_index(pd.to_datetime(drives["t"], unit="s", utc=True))
    out = gradgps.detect(indexed)
    assert isinstance(out.index, pd.DatetimeIndex)
    assert out.index.equals(indexed.index)
    base = Detector().detect(drives)
    np.testing.assert_array_equal(out["anomaly"].to_numpy(), base["anomaly"].to_numpy())
    events = Detector().events(out)
    if len(events):
        assert isinstance(events["start"].iloc[0], pd.Timestamp)


def test_clean_replaces_positions_and_events_summarise_runs() -> None:
    drives = _drives(2)
    det = Detector(threshold=0.2)
    result = gradgps.detect(drives, threshold=0.2)
    cleaned = det.clean(drives)
    assert isinstance(cleaned, pd.DataFrame)
    assert len(cleaned) == len(drives)
    np.testing.assert_array_equal(cleaned["lat"].to_numpy(), result["lat_clean"].to_numpy())
    events = det.events(result)
    assert len(events) > 0
    flagged = result[(result["anomaly"] == 1) & (result["invalid_reason"] == "")]
    assert int(events["fixes"].sum()) == len(flagged)
    assert (events["end"] >= events["start"]).all()
    assert (events["duration_s"] == events["end"] - events["start"]).all()
    assert set(events["track"]) <= set(drives["track"])
    assert (events["peak_offset_m"] >= 0).all()


def test_geodataframe_in_any_crs_round_trips() -> None:
    gpd = pytest.importorskip("geopandas", reason="extra 'geo' (geopandas) not installed")
    drives = _drives(1)
    gdf = gpd.GeoDataFrame(
        drives.drop(columns=["lat", "lon"]),
        geometry=gpd.points_from_xy(drives["lon"], drives["lat"]),
        crs="EPSG:4326",
    ).to_crs("EPSG:3857")
    out = Detector().detect(gdf)
    assert isinstance(out, gpd.GeoDataFrame)
    assert out.crs == gdf.crs
    assert out.geometry.equals(gdf.geometry)
    base = Detector().detect(drives)
    np.testing.assert_array_equal(out["anomaly"].to_numpy(), base["anomaly"].to_numpy())
    np.testing.assert_allclose(out["lat_clean"], base["lat_clean"], atol=1e-9)
    cleaned = gradgps.clean(gdf)
    assert isinstance(cleaned, gpd.GeoDataFrame)
    assert cleaned.crs == gdf.crs
    back = cleaned.to_crs("EPSG:4326")
    np.testing.assert_allclose(back.geometry.y, base["lat_clean"], atol=1e-7)


def test_movingpandas_trajectory_collection_round_trips() -> None:
    mpd = pytest.importorskip("movingpandas", reason="extra 'geo' (movingpandas) not installed")
    gpd = pytest.importorskip("geopandas")
    drives = _drives(2)
    drives["time"] = pd.to_datetime(drives["t"], unit="s")
    gdf = gpd.GeoDataFrame(
        drives.drop(columns=["lat", "lon", "t"]),
        geometry=gpd.points_from_xy(drives["lon"], drives["lat"]),
        crs="EPSG:4326",
    )
    tc = mpd.TrajectoryCollection(gdf, traj_id_col="track", t="time")
    out = Detector().detect(tc)
    assert isinstance(out, mpd.TrajectoryCollection)
    assert [t.id for t in out.trajectories] == [t.id for t in tc.trajectories]
    base = Detector().detect(drives.drop(columns="time"))
    got = pd.concat([t.df for t in out.trajectories])
    assert sorted(got["anomaly"].tolist()) == sorted(base["anomaly"].tolist())
    one = Detector().detect(tc.trajectories[0])
    assert isinstance(one, mpd.Trajectory)
    assert "lat_clean" in one.df.columns
    cleaned = gradgps.clean(tc)
    assert isinstance(cleaned, mpd.TrajectoryCollection)
    events = Detector().events(out)
    assert set(events["track"]) <= {str(t.id) for t in tc.trajectories}


def test_unsupported_types_say_what_to_pass() -> None:
    with pytest.raises(gradgps.ConfigError, match="DataFrame"):
        gradgps.detect([1, 2, 3])
    with pytest.raises(TypeError, match="latitude"):
        gradgps.detect(_drives(1), latitude="lat")  # type: ignore[call-arg]
