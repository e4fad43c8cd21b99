"""The local tangent-plane frame: exact round trip and metric sanity."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, LocalFrame
from gradgps._tracks.geo import haversine_m

lat0s = st.floats(min_value=-84.0, max_value=84.0, allow_nan=False)
lon0s = st.floats(min_value=-180.0, max_value=180.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(lat0=lat0s, lon0=lon0s, bearing=st.floats(0, 2 * np.pi), dist=st.floats(0, 100_000.0))
def test_round_trip_under_a_millimetre_within_100_km(
    lat0: float, lon0: float, bearing: float, dist: float
) -> None:
    frame = LocalFrame(lat0, lon0)
    east, north = dist * np.sin(bearing), dist * np.cos(bearing)
    lat, lon = frame.to_geodetic(east, north)
    e2, n2 = frame.to_local(lat, lon)
    assert float(np.hypot(e2 - east, n2 - north)) < 1e-3
    # And degrees -> metres -> degrees.
    lat3, lon3 = frame.to_geodetic(e2, n2)
    e3, n3 = frame.to_local(lat3, lon3)
    assert float(np.hypot(e3 - e2, n3 - n2)) < 1e-3


def test_axes_point_east_and_north() -> None:
    frame = LocalFrame(41.25, -95.98)
    e, n = frame.to_local([41.25, 41.26, 41.25], [-95.98, -95.98, -95.97])
    assert e[0] == pytest.approx(0.0, abs=1e-9)
    assert n[0] == pytest.approx(0.0, abs=1e-9)
    assert n[1] == pytest.approx(1111.0, rel=2e-3)
    assert abs(e[1]) < 1e-6
    # 0.01 deg of longitude on the ellipsoid: prime-vertical radius x cos(lat).
    phi = np.radians(41.25)
    n_radius = 6378137.0 / np.sqrt(1 - 0.00669437999014 * np.sin(phi) ** 2)
    assert e[2] == pytest.approx(np.radians(0.01) * n_radius * np.cos(phi), rel=1e-4)


def test_local_distance_matches_haversine() -> None:
    frame = LocalFrame(52.5, 13.4)
    lat, lon = 52.55, 13.45
    e, n = frame.to_local(lat, lon)
    assert float(np.hypot(e, n)) == pytest.approx(
        float(haversine_m(52.5, 13.4, lat, lon)), rel=5e-3
    )


@pytest.mark.parametrize(("lat0", "lon0"), [(float("nan"), 0.0), (91.0, 0.0), (0.0, 181.0)])
def test_bad_origin_is_a_config_error(lat0: float, lon0: float) -> None:
    with pytest.raises(ConfigError):
        LocalFrame(lat0, lon0)


@settings(max_examples=100, deadline=None)
@given(lat0=lat0s, lon0=lon0s, de=st.floats(-1e5, 1e5), dn=st.floats(-1e5, 1e5))
def test_scalar_kernels_match_the_vectorised_frame(
    lat0: float, lon0: float, de: float, dn: float
) -> None:
    from gradgps._tracks.geo import to_geodetic_scalar, to_local_scalar

    frame = LocalFrame(lat0, lon0)
    c = frame.constants()
    lat, lon = frame.to_geodetic(de, dn)
    lat_s, lon_s = to_geodetic_scalar(c, de, dn)
    assert abs(lat_s - float(lat)) < 1e-11
    assert abs(((lon_s - float(lon)) + 180.0) % 360.0 - 180.0) < 1e-11
    e, n = frame.to_local(lat, lon)
    e_s, n_s = to_local_scalar(c, float(lat), float(lon))
    assert abs(e_s - float(e)) < 1e-6
    assert abs(n_s - float(n)) < 1e-6
