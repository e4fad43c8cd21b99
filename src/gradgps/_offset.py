"""Offset tracker: how far the current fix sits from an unbroken continuation of the track.

Why it exists: a *jump* fault (one offset shared by many points) shows as one
big step where it starts and one where it ends; in between, the corrupted
track moves exactly like the real one. Window features and REMA see the two
steps and then re-acquire the shifted track within seconds, yet protocol
``grad`` keeps such a fault up for 20-100 points (permanent) or across
several bursts (intermittent). A detector with a short memory misses most of
it. The tracker gives the model that memory explicitly.

Per channel (east, north: the two are tracked separately, because faults
hit them separately and a prediction error in one must not leak into the
other) and per point:

* the *predicted step* is what the vehicle should have moved since the last
  point: from the reported speed and heading when both ends have them
  (trapezoid rule), else from a constant-velocity estimate (an EMA of the
  *explained* steps' velocities);
* the *residual* is the observed step minus the predicted one;
* a residual larger than ``threshold_m`` is *unexplained* (a fault starts,
  changes or ends) and is added to the offset; while a fault is suspected
  (offset beyond ``threshold_m``), a step that brings the offset within
  ``threshold_m`` of zero or to under a quarter of what it was ends it: the
  offset snaps to zero, what is left being prediction error;
* a smaller residual is explained: the offset leaks towards zero, slowly
  (``leak_per_s``) while a fault is suspected, so a real unexplained
  manoeuvre is forgotten in minutes while a 100 s jump fault stays visible,
  and fast (``fast_leak_per_s``) otherwise; the constant-velocity estimate
  learns from the step.

So ``offset`` is approximately the current fault offset: it jumps to ``d``
when a jump of ``d`` starts and back to about zero when it ends. Outputs per
point: offset east/north (m), its norm (m), the change of the norm at this
point (m; negative when the step took the track back towards where it should
be, which is what tells the *end* of a fault from the start of one, both
being big unexplained steps), and the residual east/north (m).

Everything is causal and translation-invariant (only differences enter).
:func:`offset_features_reference` is the readable version; the numba kernel
:func:`offset_step` (state in a small array) is what pipelines use, and a test
keeps them equal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._exceptions import ConfigError

__all__ = [
    "OFFSET_FEATURES",
    "OffsetParams",
    "offset_features",
    "offset_features_reference",
    "offset_step",
]

FloatArray = NDArray[np.float64]

OFFSET_FEATURES = ("offset_east", "offset_north", "offset_norm", "offset_change", "residual_east",
                   "residual_north")
N_OFFSET_FEATURES = len(OFFSET_FEATURES)
N_OFFSET_PARAMS = 4
SNAP_FRACTION = 0.25
# State: count, last east, last north, last ve, last vn (reported, NaN if none),
# cv ve, cv vn, offset east, offset north.
S_COUNT, S_E, S_N, S_VE, S_VN, S_CVE, S_CVN, S_OE, S_ON = range(9)
N_OFFSET_STATE = 9


@dataclass(frozen=True)
class OffsetParams:
    """``threshold_m``: residual norm above which a step is unexplained; ``leak_per_s``:
    fraction of the offset forgotten per second of explained motion; ``cv_alpha``: EMA
    weight of the constant-velocity estimate."""

    threshold_m: float = 6.0
    leak_per_s: float = 0.002
    cv_alpha: float = 0.5
    fast_leak_per_s: float = 0.1

    def to_array(self) -> FloatArray:
        if not (self.threshold_m > 0 and 0 <= self.leak_per_s < 1 and 0 < self.cv_alpha <= 1
                and 0 <= self.fast_leak_per_s < 1):
            raise ConfigError(
                "offset tracker needs threshold_m > 0, 0 <= leak_per_s < 1, 0 < cv_alpha <= 1, "
                f"0 <= fast_leak_per_s < 1; got {self.threshold_m}, {self.leak_per_s}, "
                f"{self.cv_alpha}, {self.fast_leak_per_s}"
            )
        return np.array([self.threshold_m, self.leak_per_s, self.cv_alpha, self.fast_leak_per_s])


def _velocity(speed: float, heading: float) -> tuple[float, float]:
    if math.isfinite(speed) and math.isfinite(heading):
        h = math.radians(heading)
        return speed * math.sin(h), speed * math.cos(h)
    return math.nan, math.nan


def offset_features_reference(
    dt: ArrayLike, east: ArrayLike, north: ArrayLike, speed: ArrayLike, heading: ArrayLike,
    params: OffsetParams | None = None,
) -> FloatArray:
    """Readable version of the tracker over one segment; ``dt[i]`` = t[i] - t[i-1] (dt[0] unused)."""
    prm = params or OffsetParams()
    threshold, leak, alpha, fast_leak = (float(v) for v in prm.to_array())
    d = np.asarray(dt, dtype=np.float64)
    e = np.asarray(east, dtype=np.float64)
    n = np.asarray(north, dtype=np.float64)
    sp = np.asarray(speed, dtype=np.float64)
    hd = np.asarray(heading, dtype=np.float64)
    out = np.zeros((e.size, N_OFFSET_FEATURES))
    offset = [0.0, 0.0]
    cv = [0.0, 0.0]
    for i in range(e.size):
        if i == 0:
            continue
        step = (e[i] - e[i - 1], n[i] - n[i - 1])
        v_prev = _velocity(float(sp[i - 1]), float(hd[i - 1]))
        v_now = _velocity(float(sp[i]), float(hd[i]))
        if all(math.isfinite(v) for v in (*v_prev, *v_now)):
            predicted = (0.5 * (v_prev[0] + v_now[0]) * d[i], 0.5 * (v_prev[1] + v_now[1]) * d[i])
        elif i == 1:
            predicted = step  # no history yet: the first step explains itself
        else:
            predicted = (cv[0] * d[i], cv[1] * d[i])
        residual = (step[0] - predicted[0], step[1] - predicted[1])
        if i == 1:
            cv = [step[0] / d[i], step[1] / d[i]]  # the velocity estimate starts from it too
            out[i] = (0.0, 0.0, 0.0, 0.0, residual[0], residual[1])
            continue
        norm_before = math.hypot(*offset)
        for c in range(2):
            before = offset[c]
            in_fault = abs(before) > threshold
            if abs(residual[c]) > threshold:  # a fault starts, changes or ends
                offset[c] = before + residual[c]
                if in_fault and abs(offset[c]) < max(threshold, SNAP_FRACTION * abs(before)):
                    offset[c] = 0.0  # it ended: what is left is prediction error
            else:
                offset[c] = before * max(0.0, 1.0 - (leak if in_fault else fast_leak) * d[i])
                cv[c] = alpha * step[c] / d[i] + (1 - alpha) * cv[c]
        out[i] = (offset[0], offset[1], math.hypot(*offset), math.hypot(*offset) - norm_before,
                  residual[0], residual[1])
    return out


@numba.njit(cache=True)
def _channel(p: FloatArray, state: FloatArray, o: int, cv: int, residual: float, step: float,
             dt: float) -> None:
    before = state[o]
    in_fault = abs(before) > p[0]
    if abs(residual) > p[0]:
        state[o] = before + residual
        if in_fault and abs(state[o]) < max(p[0], SNAP_FRACTION * abs(before)):
            state[o] = 0.0
    else:
        state[o] = before * max(0.0, 1.0 - (p[1] if in_fault else p[3]) * dt)
        state[cv] = p[2] * step / dt + (1.0 - p[2]) * state[cv]


@numba.njit(cache=True)
def offset_step(p: FloatArray, state: FloatArray, dt: float, east: float, north: float,
                speed: float, heading: float, out: FloatArray) -> None:
    """One point of the tracker: advance ``state`` and write the 5 features into ``out``."""
    count = state[S_COUNT]
    if np.isfinite(speed) and np.isfinite(heading):
        h = np.radians(heading)
        ve = speed * np.sin(h)
        vn = speed * np.cos(h)
    else:
        ve = np.nan
        vn = np.nan
    if count == 0.0:
        for k in range(N_OFFSET_FEATURES):
            out[k] = 0.0
    else:
        step_e = east - state[S_E]
        step_n = north - state[S_N]
        if np.isfinite(ve) and np.isfinite(state[S_VE]):
            res_e = step_e - 0.5 * (state[S_VE] + ve) * dt
            res_n = step_n - 0.5 * (state[S_VN] + vn) * dt
        elif count == 1.0:
            res_e = 0.0
            res_n = 0.0
        else:
            res_e = step_e - state[S_CVE] * dt
            res_n = step_n - state[S_CVN] * dt
        norm_before = np.hypot(state[S_OE], state[S_ON])
        if count == 1.0:
            state[S_CVE] = step_e / dt
            state[S_CVN] = step_n / dt
        else:
            _channel(p, state, S_OE, S_CVE, res_e, step_e, dt)
            _channel(p, state, S_ON, S_CVN, res_n, step_n, dt)
        out[0] = state[S_OE]
        out[1] = state[S_ON]
        out[2] = np.hypot(state[S_OE], state[S_ON])
        out[3] = out[2] - norm_before
        out[4] = res_e
        out[5] = res_n
    state[S_COUNT] = count + 1.0
    state[S_E] = east
    state[S_N] = north
    state[S_VE] = ve
    state[S_VN] = vn


@numba.njit(cache=True)
def _offset_kernel(p: FloatArray, dt: FloatArray, east: FloatArray, north: FloatArray,
                   speed: FloatArray, heading: FloatArray) -> FloatArray:
    state = np.zeros(N_OFFSET_STATE)
    out = np.empty((east.size, N_OFFSET_FEATURES))
    for i in range(east.size):
        offset_step(p, state, dt[i], east[i], north[i], speed[i], heading[i], out[i])
    return out


def offset_features(
    dt: ArrayLike, east: ArrayLike, north: ArrayLike, speed: ArrayLike | None = None,
    heading: ArrayLike | None = None, params: OffsetParams | None = None,
) -> FloatArray:
    """The tracker over one segment (numba); ``speed``/``heading`` may be None or contain NaN."""
    e = np.ascontiguousarray(east, dtype=np.float64)
    nan = np.full(e.size, np.nan)
    return np.asarray(_offset_kernel(
        (params or OffsetParams()).to_array(), np.ascontiguousarray(dt, dtype=np.float64), e,
        np.ascontiguousarray(north, dtype=np.float64),
        nan if speed is None else np.ascontiguousarray(speed, dtype=np.float64),
        nan if heading is None else np.ascontiguousarray(heading, dtype=np.float64),
    ))
