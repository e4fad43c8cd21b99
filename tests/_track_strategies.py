"""hypothesis strategies for messy tracks: every kind of bad fix a real log can hold.

A drawn track is a canonical fixes frame (``track``, ``t``, ``lat``,
``lon``, maybe ``speed``/``heading``) built from a plausible drive (a random
walk in metres from a random origin) and then damaged: NaN and infinite
values, latitudes beyond +-90 and longitudes beyond +-180, repeated and
backward timestamps, gaps from seconds to days, interleaved tracks, tracks of
a single fix, missing optional columns. ``expected_reasons`` says which rows
are invalid whatever their order (the per-value checks).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from hypothesis import strategies as st

INF = math.inf
NAN = math.nan

# Time steps: mostly regular, sometimes repeated, backward, a short or a huge gap.
_STEPS = st.one_of(
    st.sampled_from([1.0] * 6 + [0.2, 0.0, -1.0, -30.0, 3.0, 7.0, 86_400.0]),
    st.floats(-1e3, 1e5, allow_nan=False),
)
_BAD_TIME = st.sampled_from([NAN, INF, -INF])
_BAD_LAT = st.sampled_from([NAN, INF, -INF, 90.000001, -91.0, 1e308, -1e308])
_BAD_LON = st.sampled_from([NAN, INF, -INF, 180.000001, -181.0, 540.0, 1e308])
_READING = st.one_of(st.floats(-1e3, 1e3, allow_nan=False), st.sampled_from([NAN, INF, -INF]))


@st.composite
def messy_tracks(draw: st.DrawFn, max_rows: int = 40) -> pd.DataFrame:
    n = draw(st.integers(0, max_rows))
    n_tracks = draw(st.integers(1, 3))
    lat0 = draw(st.floats(-89.0, 89.0))
    lon0 = draw(st.floats(-179.5, 179.5))
    t0 = draw(st.sampled_from([0.0, 1_700_000_000.0, -50.0]))
    rows = []
    clocks = [t0] * n_tracks
    walk = [(0.0, 0.0)] * n_tracks
    for _ in range(n):
        k = draw(st.integers(0, n_tracks - 1))
        clocks[k] += draw(_STEPS)
        step = draw(st.sampled_from([10.0, 10.0, 10.0, 0.0, 500.0, 50_000.0]))
        east, north = walk[k]
        walk[k] = (east + step * draw(st.floats(-1, 1)), north + step * draw(st.floats(-1, 1)))
        lat = float(np.clip(lat0 + walk[k][1] / 111_000.0, -90.0, 90.0))
        lon = float((lon0 + walk[k][0] / 80_000.0 + 180.0) % 360.0 - 180.0)
        t = clocks[k]
        damage = draw(st.sampled_from(["none"] * 5 + ["t", "lat", "lon", "all"]))
        if damage in ("t", "all"):
            t = draw(_BAD_TIME)
        if damage in ("lat", "all"):
            lat = draw(_BAD_LAT)
        if damage in ("lon", "all"):
            lon = draw(_BAD_LON)
        rows.append((str(k), t, lat, lon, draw(_READING), draw(_READING)))
    frame = pd.DataFrame(rows, columns=["track", "t", "lat", "lon", "speed", "heading"])
    frame = frame.astype(
        {"track": object, "t": float, "lat": float, "lon": float, "speed": float, "heading": float}
    )
    keep = draw(st.sampled_from([("speed", "heading"), ("speed",), ("heading",), ()]))
    return frame.drop(columns=[c for c in ("speed", "heading") if c not in keep])


def expected_reasons(fixes: pd.DataFrame) -> np.ndarray:
    """True where a row is invalid by its own values (time/lat/lon missing, infinite or out of
    range, or the position exactly (0, 0))."""
    t = fixes["t"].to_numpy(float)
    lat = fixes["lat"].to_numpy(float)
    lon = fixes["lon"].to_numpy(float)
    null_island = (lat == 0.0) & (lon == 0.0)
    return np.asarray(
        ~np.isfinite(t) | ~(np.abs(lat) <= 90.0) | ~(np.abs(lon) <= 180.0) | null_island
    )
