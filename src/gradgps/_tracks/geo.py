"""Local metric frame: WGS84 latitude/longitude <-> east/north metres.

Detection works in metres so that thresholds and features mean the same thing
in Omaha and in Berlin. Each track gets its own tangent plane (east-north-up
frame at its first fix, on the WGS84 ellipsoid, height 0) and points are
projected orthographically onto it: ``east``/``north`` are the first two ENU
coordinates of the point on the ellipsoid surface.

The inverse is exact, not iterative: the point on the ellipsoid whose tangent
plane coordinates are ``(east, north)`` lies on the line through the plane
point along the local "up" axis, which meets the ellipsoid at the root of a
quadratic; the latitude of a point *on* the ellipsoid is then closed form.
Round-trip error is around 1e-9 m within 100 km (tested), far under the 1 mm
the project promises. Altitude is carried through untouched, not projected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError

__all__ = [
    "EARTH_MEAN_RADIUS_M",
    "N_FRAME_CONSTANTS",
    "WGS84_A",
    "WGS84_F",
    "LocalFrame",
    "far_apart_scalar",
    "haversine_m",
    "to_geodetic_scalar",
    "to_local_scalar",
]

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
_B = WGS84_A * (1.0 - WGS84_F)
_E2 = WGS84_F * (2.0 - WGS84_F)
#: m: the WGS84 mean radius, (2a + b) / 3 rounded to 0.1 m: the sphere of the distances
#: that need no local frame (summaries, the speed gate, the input checks).
EARTH_MEAN_RADIUS_M = 6371008.8

FloatArray = NDArray[np.float64]


def _ecef(lat_deg: FloatArray, lon_deg: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    lat = np.radians(lat_deg)
    lon = np.radians(lon_deg)
    sin_lat = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - _E2 * sin_lat * sin_lat)
    x = n * np.cos(lat) * np.cos(lon)
    y = n * np.cos(lat) * np.sin(lon)
    z = n * (1.0 - _E2) * sin_lat
    return x, y, z


@dataclass(frozen=True)
class LocalFrame:
    """The tangent plane at ``(lat0, lon0)``; converts both ways, vectorised.

    Valid within a hemisphere of the origin; the promise (1 mm round trip) is
    for points within 100 km, which covers any single drive.
    """

    lat0: float
    lon0: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.lat0) and np.isfinite(self.lon0)):
            raise ConfigError(f"frame origin must be finite, got ({self.lat0}, {self.lon0})")
        if abs(self.lat0) > 90.0 or abs(self.lon0) > 180.0:
            raise ConfigError(f"frame origin outside WGS84 range: ({self.lat0}, {self.lon0})")

    @property
    def _axes(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        lat = np.radians(self.lat0)
        lon = np.radians(self.lon0)
        sl, cl = np.sin(lat), np.cos(lat)
        so, co = np.sin(lon), np.cos(lon)
        east = np.array([-so, co, 0.0])
        north = np.array([-sl * co, -sl * so, cl])
        up = np.array([cl * co, cl * so, sl])
        x0, y0, z0 = _ecef(np.array(self.lat0), np.array(self.lon0))
        origin = np.array([float(x0), float(y0), float(z0)])
        return origin, east, north, up

    def constants(self) -> FloatArray:
        """The frame as 12 numbers (origin, east, north, up axes in ECEF) for the scalar kernels."""
        origin, e_ax, n_ax, u_ax = self._axes
        return np.concatenate([origin, e_ax, n_ax, u_ax])

    def to_local(self, lat: ArrayLike, lon: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Degrees -> (east, north) metres in this frame."""
        lat_a = np.asarray(lat, dtype=np.float64)
        lon_a = np.asarray(lon, dtype=np.float64)
        origin, e_ax, n_ax, _ = self._axes
        x, y, z = _ecef(lat_a, lon_a)
        dx, dy, dz = x - origin[0], y - origin[1], z - origin[2]
        east = dx * e_ax[0] + dy * e_ax[1]
        north = dx * n_ax[0] + dy * n_ax[1] + dz * n_ax[2]
        return east, north

    def to_geodetic(self, east: ArrayLike, north: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(east, north) metres in this frame -> degrees (latitude, longitude)."""
        e = np.asarray(east, dtype=np.float64)
        n = np.asarray(north, dtype=np.float64)
        origin, e_ax, n_ax, u_ax = self._axes
        px = origin[0] + e * e_ax[0] + n * n_ax[0]
        py = origin[1] + e * e_ax[1] + n * n_ax[1]
        pz = origin[2] + n * n_ax[2]
        a2 = WGS84_A * WGS84_A
        b2 = _B * _B
        qa = (u_ax[0] ** 2 + u_ax[1] ** 2) / a2 + u_ax[2] ** 2 / b2
        qb = 2.0 * ((px * u_ax[0] + py * u_ax[1]) / a2 + pz * u_ax[2] / b2)
        qc = (px * px + py * py) / a2 + pz * pz / b2 - 1.0
        disc = np.sqrt(np.maximum(qb * qb - 4.0 * qa * qc, 0.0))
        # The root nearest the plane, in the cancellation-free form C / q.
        q = -0.5 * (qb + np.copysign(disc, qb))
        u = np.where(q != 0.0, qc / np.where(q != 0.0, q, 1.0), 0.0)
        x = px + u * u_ax[0]
        y = py + u * u_ax[1]
        z = pz + u * u_ax[2]
        lon = np.degrees(np.arctan2(y, x))
        lat = np.degrees(np.arctan2(z, np.hypot(x, y) * (1.0 - _E2)))
        return lat, lon


def haversine_m(lat1: ArrayLike, lon1: ArrayLike, lat2: ArrayLike, lon2: ArrayLike) -> FloatArray:
    """Great-circle distance in metres on a sphere of the WGS84 mean radius.

    Good to about 0.5 %; used for summaries (gaps, speeds), not for detection.
    """
    r = EARTH_MEAN_RADIUS_M
    p1 = np.radians(np.asarray(lat1, dtype=np.float64))
    p2 = np.radians(np.asarray(lat2, dtype=np.float64))
    dp = p2 - p1
    dl = np.radians(np.asarray(lon2, dtype=np.float64) - np.asarray(lon1, dtype=np.float64))
    h = np.sin(dp / 2.0) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2.0) ** 2
    return np.asarray(2.0 * r * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0))), dtype=np.float64)


# Scalar kernels for per-point pipelines: the same formulas as LocalFrame (the
# readable, vectorised reference; a test keeps them equal), one fix at a time
# inside compiled code, where a NumPy call per fix would cost microseconds.
N_FRAME_CONSTANTS = 12


@numba.njit(cache=True)
def to_local_scalar(c: FloatArray, lat: float, lon: float) -> tuple[float, float]:
    """Degrees -> (east, north) metres, ``c`` from :meth:`LocalFrame.constants`."""
    phi = math.radians(lat)
    lam = math.radians(lon)
    sin_phi = math.sin(phi)
    n = WGS84_A / math.sqrt(1.0 - _E2 * sin_phi * sin_phi)
    dx = n * math.cos(phi) * math.cos(lam) - c[0]
    dy = n * math.cos(phi) * math.sin(lam) - c[1]
    dz = n * (1.0 - _E2) * sin_phi - c[2]
    east = dx * c[3] + dy * c[4]
    north = dx * c[6] + dy * c[7] + dz * c[8]
    return east, north


@numba.njit(cache=True)
def to_geodetic_scalar(c: FloatArray, east: float, north: float) -> tuple[float, float]:
    """(east, north) metres -> degrees (latitude, longitude), ``c`` from :meth:`LocalFrame.constants`."""
    px = c[0] + east * c[3] + north * c[6]
    py = c[1] + east * c[4] + north * c[7]
    pz = c[2] + north * c[8]
    a2 = WGS84_A * WGS84_A
    b2 = _B * _B
    qa = (c[9] * c[9] + c[10] * c[10]) / a2 + c[11] * c[11] / b2
    qb = 2.0 * ((px * c[9] + py * c[10]) / a2 + pz * c[11] / b2)
    qc = (px * px + py * py) / a2 + pz * pz / b2 - 1.0
    disc = math.sqrt(max(qb * qb - 4.0 * qa * qc, 0.0))
    q = -0.5 * (qb + math.copysign(disc, qb))
    u = qc / q if q != 0.0 else 0.0
    x = px + u * c[9]
    y = py + u * c[10]
    z = pz + u * c[11]
    return math.degrees(math.atan2(z, math.hypot(x, y) * (1.0 - _E2))), math.degrees(
        math.atan2(y, x)
    )


@numba.njit(cache=True)
def far_apart_scalar(lat0: float, lon0: float, lat: float, lon: float, radius_m: float) -> bool:
    """Whether two positions are more than ``radius_m`` apart on the sphere of
    :func:`haversine_m` (one compiled function, so a stream and a batch decide alike)."""
    p1 = math.radians(lat0)
    p2 = math.radians(lat)
    s_dp = math.sin(0.5 * (p2 - p1))
    s_dl = math.sin(0.5 * math.radians(lon - lon0))
    h = s_dp * s_dp + math.cos(p1) * math.cos(p2) * s_dl * s_dl
    h = min(max(h, 0.0), 1.0)
    return 2.0 * EARTH_MEAN_RADIUS_M * math.asin(math.sqrt(h)) > radius_m


@numba.njit(cache=True)
def radius_splits(
    lat: FloatArray, lon: FloatArray, gap: NDArray[np.bool_], radius_m: float
) -> NDArray[np.bool_]:
    """Where a track (points in time order; ``gap[i]``: a new segment starts at point
    ``i + 1``) also starts a new segment because point ``i + 1`` is more than ``radius_m``
    from its segment's first point, which then becomes the next segment's first point."""
    out = gap.copy()
    centre = 0
    for i in range(1, lat.size):
        if gap[i - 1]:
            centre = i
        elif far_apart_scalar(lat[centre], lon[centre], lat[i], lon[i], radius_m):
            out[i - 1] = True
            centre = i
    return out
