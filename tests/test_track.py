"""The track model: column detection, conversion to canonical fixes, errors that name rows."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gradgps import ColumnMap, InputError, Table, to_fixes
from gradgps._tracks.track import resolve_columns


@pytest.mark.parametrize(
    ("names", "expected"),
    [
        (["timestamp", "latitude", "longitude"], ("timestamp", "latitude", "longitude")),
        (["Time", "Latitude", "Longitude"], ("Time", "Latitude", "Longitude")),
        (["ts", "gps_lat", "gps_lon"], ("ts", "gps_lat", "gps_lon")),
        (
            ["GPS Time", "GPS Latitude", "GPS Longitude"],
            ("GPS Time", "GPS Latitude", "GPS Longitude"),
        ),
        (["t_rel", "lat", "lng"], ("t_rel", "lat", "lng")),
        (["time", "lat", "long"], ("time", "lat", "long")),
    ],
)
def test_common_column_names_are_detected(names: list[str], expected: tuple[str, str, str]) -> None:
    cmap = resolve_columns(names)
    assert (cmap.time, cmap.lat, cmap.lon) == expected


def test_overrides_win_and_missing_names_are_reported() -> None:
    cmap = resolve_columns(["a", "b", "c", "lat"], ColumnMap(time="a", lat="b", lon="c"))
    assert (cmap.time, cmap.lat, cmap.lon) == ("a", "b", "c")
    with pytest.raises(InputError, match="no column named 'zz' for lat"):
        resolve_columns(["t", "lat", "lon"], ColumnMap(lat="zz"))
    with pytest.raises(InputError, match=r"cannot find the lon column.*--lon-col"):
        resolve_columns(["t", "lat", "b"])


def test_non_numeric_latitude_names_row_line_and_column() -> None:
    lat = ["41.0"] * 60
    lat[56] = "41.2x"
    frame = pd.DataFrame({"t": range(60), "latitude": lat, "longitude": ["-95.0"] * 60})
    with pytest.raises(InputError) as err:
        to_fixes(Table(frame, source="drive.csv", first_line=2))
    msg = str(err.value)
    assert "drive.csv" in msg
    assert "row 57 (line 58)" in msg
    assert "'latitude'" in msg
    assert "'41.2x'" in msg


def test_iso_times_blank_values_and_heading_wrap() -> None:
    frame = pd.DataFrame(
        {
            "time": ["2024-05-01T10:00:00Z", "2024-05-01T10:00:01.5Z", ""],
            "lat": ["41.0", "", "41.1"],
            "lon": [-95.0, -95.1, -95.2],
            "course": [370.0, -10.0, 5.0],
        }
    )
    fx = to_fixes(frame)
    assert fx["t"].iloc[1] - fx["t"].iloc[0] == pytest.approx(1.5)
    assert fx["t"].iloc[0] == pytest.approx(1714557600.0)
    assert np.isnan(fx["t"].iloc[2])
    assert np.isnan(fx["lat"].iloc[1])
    assert fx["heading"].tolist() == [10.0, 350.0, 5.0]
    assert fx["track"].tolist() == ["0", "0", "0"]


def test_millisecond_epochs_are_scaled() -> None:
    fx = to_fixes(
        pd.DataFrame(
            {
                "timestamp": [1_700_000_000_000, 1_700_000_001_000],
                "lat": [1.0, 1.0],
                "lon": [2.0, 2.0],
            }
        )
    )
    assert fx["t"].tolist() == [1_700_000_000.0, 1_700_000_001.0]


def test_bad_time_names_the_row() -> None:
    frame = pd.DataFrame(
        {"time": ["2024-05-01T10:00:00Z", "yesterday"], "lat": [1, 1], "lon": [2, 2]}
    )
    with pytest.raises(InputError, match=r"row 2.*'time'.*not a time"):
        to_fixes(frame)


def test_extra_channels_are_carried() -> None:
    frame = pd.DataFrame({"t": [0, 1], "lat": [1, 1], "lon": [2, 2], "gyro_z_dps": ["0.5", "x"]})
    with pytest.raises(InputError, match="row 2"):
        to_fixes(frame, channels=["gyro_z_dps"])
    frame.loc[1, "gyro_z_dps"] = "0.25"
    assert to_fixes(frame, channels=["gyro_z_dps"])["gyro_z_dps"].tolist() == [0.5, 0.25]
    with pytest.raises(InputError, match="no channel column"):
        to_fixes(frame, channels=["nope"])


def test_iso_year_outside_nanosecond_range_is_an_input_error() -> None:
    """Found by make fuzz: '-1' next to ISO times parses as year -1, beyond datetime64[ns]."""
    frame = pd.DataFrame(
        {"t": ["-1", "", "2024-01-01T00:00:00Z"], "lat": [0.0] * 3, "lon": [0.0] * 3}
    )
    with pytest.raises(InputError, match=r"row 1 \(line 2\), column 't': time out of range"):
        to_fixes(Table(frame, source="x.csv", first_line=2))


@pytest.mark.parametrize(
    ("names", "track"),
    [
        (["device_id", "time", "lat", "lon"], "device_id"),
        (["IMEI", "timestamp", "latitude", "longitude"], "IMEI"),
        (["taxi_id", "t", "lat", "lon"], "taxi_id"),
        (["id", "asset_id", "t", "lat", "lon"], "asset_id"),
        (["trip", "vehicle", "t", "lat", "lon"], "trip"),
    ],
)
def test_fleet_exports_name_the_vehicle_by_device_or_asset(names: list[str], track: str) -> None:
    """A fleet export's vehicle column under its usual names is the track (each vehicle
    read on its own, not merged into one path that leaps between them); a device or asset
    id wins over a bare ``id`` (often a row number), a trip over a vehicle."""
    assert resolve_columns(names).track == track
