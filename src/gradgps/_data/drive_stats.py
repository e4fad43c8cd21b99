"""Statistics that describe how a set of drives moves and how noisy its fixes are.

Used to check that simulated drives (:mod:`gradgps._data.simulator`) look like real
ones: ``benchmarks/simulator_stats.py`` prints them side by side and
``tests/test_simulator.py`` holds the simulator to bands around the real
values. Every quantity is computed per *step* between consecutive fixes of a
track that are exactly one nominal period apart (the track's median time
step), so logging gaps do not count as long steps.

Quantities (units):

- ``step_m``: distance between consecutive fixes, metres.
- ``speed_mps``: reported speed, m/s.
- ``accel_mps2``: absolute change of reported speed per second, m/s^2.
- ``heading_change_deg``: absolute change of reported heading per step,
  degrees in [0, 180].
- ``position_residual_m``: absolute residual of each coordinate (east and
  north, pooled) from a least-squares quadratic in time over the 5 fixes
  centred on it. A car's path is smooth over 4 s, so this measures the
  epoch-to-epoch position noise (and, a little, hard manoeuvres).
- ``stop_fraction``: share of fixes with reported speed under 0.5 m/s (one
  number, not a distribution).
- ``zero_step_fraction``: share of steps of exactly 0 m (a receiver holding
  its position while stopped).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from .._tracks.geo import LocalFrame

__all__ = ["DISTRIBUTIONS", "STOP_SPEED", "drive_statistics", "summarize"]

FloatArray = NDArray[np.float64]

DISTRIBUTIONS = ("step_m", "speed_mps", "accel_mps2", "heading_change_deg", "position_residual_m")
STOP_SPEED = 0.5  # m/s
_WINDOW = 5


def _quadratic_residual(t: FloatArray, x: FloatArray) -> FloatArray:
    """|x - fit| at the centre of every 5-sample window with a centred quadratic fit."""
    if x.size < _WINDOW:
        return np.empty(0)
    u = np.arange(_WINDOW) - _WINDOW // 2
    design = np.vander(u.astype(np.float64), 3)
    centre_weights = (design @ np.linalg.pinv(design))[_WINDOW // 2]
    windows = sliding_window_view(x, _WINDOW)
    residual = np.abs(windows @ centre_weights - windows[:, _WINDOW // 2])
    t_windows = sliding_window_view(t, _WINDOW)
    period = float(np.median(np.diff(t)))
    even = np.all(np.isclose(np.diff(t_windows, axis=1), period), axis=1)
    return np.asarray(residual[even], dtype=np.float64)


def drive_statistics(fixes: pd.DataFrame) -> dict[str, FloatArray]:
    """Samples of every quantity in the module docstring, pooled over tracks.

    ``fixes`` is a canonical fixes frame (``track, t, lat, lon, speed,
    heading``). Returns ``{name: samples}``; the two fractions are returned
    as one-element arrays.
    """
    parts: dict[str, list[FloatArray]] = {name: [] for name in DISTRIBUTIONS}
    zero_steps: list[FloatArray] = []
    for _, track in fixes.sort_values(["track", "t"], kind="stable").groupby("track", sort=False):
        t = track["t"].to_numpy(dtype=np.float64)
        if t.size < 2:
            continue
        lat = track["lat"].to_numpy(dtype=np.float64)
        lon = track["lon"].to_numpy(dtype=np.float64)
        east, north = LocalFrame(float(lat[0]), float(lon[0])).to_local(lat, lon)
        speed = track["speed"].to_numpy(dtype=np.float64)
        heading = track["heading"].to_numpy(dtype=np.float64)
        dt = np.diff(t)
        period = float(np.median(dt))
        one = np.isclose(dt, period)
        step = np.hypot(np.diff(east), np.diff(north))[one]
        parts["step_m"].append(step)
        zero_steps.append((step == 0.0).astype(np.float64))
        parts["speed_mps"].append(speed)
        parts["accel_mps2"].append(np.abs(np.diff(speed))[one] / period)
        turn = np.abs((np.diff(heading) + 180.0) % 360.0 - 180.0)
        parts["heading_change_deg"].append(turn[one])
        parts["position_residual_m"].append(_quadratic_residual(t, east))
        parts["position_residual_m"].append(_quadratic_residual(t, north))
    out = {
        name: np.concatenate(values) if values else np.empty(0) for name, values in parts.items()
    }
    for name, values in out.items():
        out[name] = values[np.isfinite(values)]
    speed_all = out["speed_mps"]
    out["stop_fraction"] = np.array([float(np.mean(speed_all < STOP_SPEED))])
    out["zero_step_fraction"] = np.array([float(np.mean(np.concatenate(zero_steps)))])
    return out


def summarize(samples: dict[str, FloatArray]) -> dict[str, tuple[float, float, float]]:
    """(median, p90, p99) of each distribution; (value, value, value) for the fractions."""
    summary: dict[str, tuple[float, float, float]] = {}
    for name, values in samples.items():
        if values.size == 1 and name not in DISTRIBUTIONS:
            v = float(values[0])
            summary[name] = (v, v, v)
        else:
            q = np.percentile(values, [50.0, 90.0, 99.0])
            summary[name] = (float(q[0]), float(q[1]), float(q[2]))
    return summary
