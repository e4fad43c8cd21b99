"""The maximum-speed filter: the baseline that trajectory libraries ship today.

A fix is rejected when the speed implied by the distance from the last
*accepted* fix over the time since it exceeds a bound (50 m/s = 180 km/h by
default, above any legal car speed, so real driving is never rejected).
Comparing with the last accepted fix rather than the previous fix matters: a
single bad fix then cannot make the good fix after it look fast.

Two rules keep one mistake from flagging the rest of a drive:

* **Re-anchoring.** If more than ``reanchor_after`` fixes in a row are
  rejected and each is reachable from the one before at legal speed, the
  stream has moved for good (the anchor was the bad fix, e.g. a bad first
  fix, or a lasting shift): the next such fix is accepted as the new anchor
  and ``alert`` is raised on it, because the gate cannot tell which side of a
  lasting shift is right.
* **Long gaps.** The first fix after more than ``max_gap_s`` without any fix
  starts afresh (accepted), as a new segment does in preprocessing.

The first fix of a track is accepted (there is nothing to compare with).
Equal timestamps imply an infinite speed unless the positions are equal.
``score`` is ``v / (v + bound)`` (0.5 at the bound). The gate does not
classify: ``bias_type``/``time_type`` are missing. ``lat_clean``/``lon_clean``
hold the last accepted fix for a rejected one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError
from .._result import PointResult, decode_floats, invalid_reasons, results_frame
from .._tracks.geo import EARTH_MEAN_RADIUS_M
from .._tracks.track import track_rows
from .base import Reading, StreamingBaseline, load_time, state_error

__all__ = ["SpeedGate"]

_STATE_KEYS = ("anchor", "rejected", "streak", "last_t")


def _distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Haversine distance, the scalar twin of :func:`gradgps._tracks.geo.haversine_m`."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    h = (
        math.sin((p2 - p1) / 2) ** 2
        + math.cos(p1) * math.cos(p2) * math.sin(math.radians(lon2 - lon1) / 2) ** 2
    )
    return 2.0 * EARTH_MEAN_RADIUS_M * math.asin(math.sqrt(min(max(h, 0.0), 1.0)))


def _speed(a: list[float], t: float, lat: float, lon: float) -> float:
    """Implied speed (m/s) from fix ``a = [t, lat, lon]`` to ``(t, lat, lon)``."""
    dist = _distance_m(a[1], a[2], lat, lon)
    dt = t - a[0]
    if dt > 0:
        return dist / dt
    return 0.0 if dist == 0.0 else math.inf


def _fix(value: Any) -> list[float] | None:
    """A stored ``[t, lat, lon]`` (or None), checked."""
    out = decode_floats(value)
    if out is not None and (len(out) != 3 or not all(math.isfinite(v) for v in out)):
        raise ValueError(f"a fix is [t, lat, lon] of finite numbers, got {value!r}")
    return out


class SpeedGate(StreamingBaseline):
    """Streaming and batch maximum-speed filter for one vehicle's fixes.

    Parameters: ``max_speed_mps`` the bound (default 50 m/s for cars; use
    about 15 for bicycles); ``reanchor_after`` how many consecutive,
    mutually consistent rejections make the gate accept the stream as moved;
    ``max_gap_s`` the silence after which the next fix starts afresh.
    """

    def __init__(
        self, max_speed_mps: float = 50.0, reanchor_after: int = 5, max_gap_s: float = 60.0
    ) -> None:
        if not (math.isfinite(max_speed_mps) and max_speed_mps > 0):
            raise ConfigError(f"max_speed_mps must be a positive number, got {max_speed_mps}")
        if reanchor_after < 1:
            raise ConfigError(f"reanchor_after must be at least 1, got {reanchor_after}")
        if not (max_gap_s > 0):
            raise ConfigError(f"max_gap_s must be positive seconds, got {max_gap_s}")
        self.max_speed_mps = float(max_speed_mps)
        self.reanchor_after = int(reanchor_after)
        self.max_gap_s = float(max_gap_s)
        self._anchor: list[float] | None = None  # [t, lat, lon] of the last accepted fix
        self._rejected: list[float] | None = None  # the last rejected fix
        self._streak = 0
        self._last_t: float | None = None

    def _update_valid(self, fix: Reading) -> PointResult:
        """Judge one usable fix (time order)."""
        t, lat, lon = fix.t, fix.lat, fix.lon
        point = [t, lat, lon]
        gap = self._last_t is not None and t - self._last_t > self.max_gap_s
        self._last_t = t
        if self._anchor is None or gap:
            return self._accept(point, 0.0, alert=0)
        v = _speed(self._anchor, t, lat, lon)
        if v <= self.max_speed_mps:
            return self._accept(point, v, alert=0)
        consistent = (
            self._rejected is not None and _speed(self._rejected, t, lat, lon) <= self.max_speed_mps
        )
        self._streak = self._streak + 1 if consistent else 1
        self._rejected = point
        if self._streak > self.reanchor_after:
            return self._accept(point, v, alert=1)
        return PointResult(1, self._score(v), None, None, self._anchor[1], self._anchor[2], 0)

    def _score(self, v: float) -> float:
        return 1.0 if math.isinf(v) else v / (v + self.max_speed_mps)

    def _accept(self, fix: list[float], v: float, *, alert: int) -> PointResult:
        self._anchor = fix
        self._rejected = None
        self._streak = 0
        return PointResult(0, self._score(v), None, None, fix[1], fix[2], alert)

    def get_state(self) -> dict[str, Any]:
        """The gate's memory as plain JSON-able data (parameters are not state)."""
        return {
            "anchor": None if self._anchor is None else list(self._anchor),
            "rejected": None if self._rejected is None else list(self._rejected),
            "streak": self._streak,
            "last_t": self._last_t,
        }

    def set_state(self, state: Mapping[str, Any]) -> SpeedGate:
        """Restore what :meth:`get_state` returned (e.g. after a restart); returns self."""
        try:
            missing = [k for k in _STATE_KEYS if k not in state]
            if missing:
                raise KeyError(f"lacks {missing}")
            anchor, rejected = _fix(state["anchor"]), _fix(state["rejected"])
            streak = state["streak"]
            if isinstance(streak, bool) or not isinstance(streak, int) or streak < 0:
                raise ValueError(f"streak must be a count, got {streak!r}")
            last_t = load_time(state["last_t"])
        except (KeyError, TypeError, ValueError) as exc:
            raise state_error("speed-gate", exc) from exc
        self._anchor, self._rejected, self._streak = anchor, rejected, streak
        self._last_t = last_t
        return self

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """Each track runs through a fresh gate in time order, exactly as :meth:`update` would see it;
        this object's own state is not touched."""
        reason = invalid_reasons(fixes)
        results = [PointResult.invalid(str(r), classifies=False) if r else None for r in reason]
        t = fixes["t"].to_numpy(dtype=np.float64)
        lat = fixes["lat"].to_numpy(dtype=np.float64)
        lon = fixes["lon"].to_numpy(dtype=np.float64)
        for rows in track_rows(fixes, reason == ""):
            gate = SpeedGate(self.max_speed_mps, self.reanchor_after, self.max_gap_s)
            for i in rows.tolist():
                results[i] = gate._update_valid(Reading(float(t[i]), float(lat[i]), float(lon[i])))
        return results_frame(results, fixes.index)  # type: ignore[arg-type]
