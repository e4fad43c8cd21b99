"""A positions-only motion model: constant velocity and turn rate, driven by the real time step.

Why: most users' files hold time, latitude and longitude and nothing else,
at whatever rate their receiver wrote (0.5-10 Hz, with dropped fixes). The
REMA and MS-SW features look at each channel (east, north) on its own and
count in points; a car on a motorway curve at 0.5 Hz, or a logger that skips
a fix, then looks like a fault. A GNSS engineer would ask the question a
navigation filter asks: *where should this fix be, given where the vehicle
was, how fast it went and how it was turning, and how long ago that was?*
This module answers it with the smallest such filter, built for speed and
for never staying lost:

* **Prediction** over the actual time step ``dt``: velocity ``v`` rotated by
  the turn rate ``w`` times ``dt`` (constant turn rate and velocity, CTRV),
  then ``pred = p + v_rotated * dt``.
* **Innovation** ``r = z - pred`` (metres), reported whole, as along-track and
  cross-track components, and normalised by a running scale ``sqrt(m2)``
  (an exponential mean of accepted squared innovations, floored by
  ``noise_floor`` metres): the scale adapts to the receiver and the driving,
  so a phone on a motorway and an RTK receiver in town read alike.
* **Gate**: a fix whose normalised innovation exceeds ``gate`` is not used to
  update; the filter dead-reckons through it (``run_s`` counts the seconds).
* **No state stays diverged.** A gated fix is re-acquired when its own step
  from the previous *observed* fix agrees with the motion (the track goes on
  from a new place: the end of a jump, or a jump that was the truth), and
  unconditionally once ``max_run_s`` seconds have passed. Whatever the input,
  the filter follows the fixes again within ``max_run_s`` of the last one
  it rejected. (The memory of a lasting offset is the offset tracker's job,
  :mod:`gradgps._grad.offset`; this model only says how surprising each step is.)

Speed and heading are not used: this is the witness that exists in every
file. ``dt_ratio`` (the step over the segment's nominal period) is emitted
too, so the network knows a dropped fix from a fast one.

:func:`motion_step` (numba) advances one fix given the state array;
:func:`motion_reference` is the readable full-array version the tests hold
it to.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from .._exceptions import ConfigError

__all__ = [
    "MOTION_FEATURES",
    "N_MOTION_FEATURES",
    "N_MOTION_PARAMS",
    "N_MOTION_STATE",
    "MotionParams",
    "motion_batch",
    "motion_new_state",
    "motion_reference",
    "motion_step",
    "motion_velocity",
]

FloatArray = NDArray[np.float64]

MOTION_FEATURES = (
    "motion_innovation",
    "motion_along",
    "motion_cross",
    "motion_nis",
    "motion_run_s",
    "motion_speed",
    "motion_lateral_accel",
    "dt_ratio",
)
N_MOTION_FEATURES = len(MOTION_FEATURES)

P_GATE, P_FLOOR, P_MEMORY, P_VEL_TAU, P_TURN_TAU, P_MAX_RUN, P_MAX_TURN, P_PERIOD, P_INIT = range(9)
N_MOTION_PARAMS = 9
# State: count, p east/north, v east/north, turn rate, m2, run seconds,
# previous observed east/north, and the velocity predicted for the newest fix
# (before it was seen; NaN until two fixes have set a velocity).
S_COUNT, S_PE, S_PN, S_VE, S_VN, S_W, S_M2, S_RUN, S_ZE, S_ZN, S_PVE, S_PVN = range(12)
N_MOTION_STATE = 12


@dataclass(frozen=True)
class MotionParams:
    """Settings of the motion model (units in the names' docs).

    ``gate``: normalised innovation above which a fix is not used (sigmas);
    ``noise_floor``: metres, the smallest innovation scale (a stationary
    receiver's jitter must not make every metre a surprise);
    ``memory``: weight of the newest squared innovation in the running scale;
    ``velocity_tau_s`` / ``turn_tau_s``: time constants (s) with which the
    velocity and turn rate follow the observed steps (a step of ``dt`` moves
    them by ``1 - exp(-dt / tau)`` of the way: the same smoothing in seconds at
    0.5 Hz and at 10 Hz, where a step is mostly receiver noise); ``max_run_s``: seconds after which a
    rejected track is re-acquired whatever the fixes do; ``max_turn``: rad/s
    cap on the turn rate (a car does not turn faster than about 1 rad/s);
    ``initial_scale``: metres, the innovation scale before any has been
    measured. The second fix of a segment only starts the velocity (it is
    never gated: nothing is known yet to judge it by).
    """

    gate: float = 4.0
    noise_floor: float = 1.0
    memory: float = 0.05
    velocity_tau_s: float = 1.5
    turn_tau_s: float = 2.0
    max_run_s: float = 10.0
    max_turn: float = 1.0
    initial_scale: float = 5.0

    def checked(self) -> MotionParams:
        for name in (
            "gate",
            "noise_floor",
            "max_run_s",
            "max_turn",
            "initial_scale",
            "velocity_tau_s",
            "turn_tau_s",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"motion {name} must be a positive number, got {value!r}")
        for name in ("memory",):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 < value <= 1):
                raise ConfigError(f"motion {name} must be in (0, 1], got {value!r}")
        return self

    def to_array(self, period: float) -> FloatArray:
        self.checked()
        return np.array(
            [
                self.gate,
                self.noise_floor,
                self.memory,
                self.velocity_tau_s,
                self.turn_tau_s,
                self.max_run_s,
                self.max_turn,
                period,
                self.initial_scale,
            ],
            dtype=np.float64,
        )


def motion_new_state() -> FloatArray:
    """A fresh state (no fix seen)."""
    state = np.zeros(N_MOTION_STATE)
    state[S_PVE] = state[S_PVN] = np.nan
    return state


@numba.njit(cache=True, error_model="numpy")
def motion_velocity(state: FloatArray) -> tuple[float, float]:
    """(speed m/s, course degrees clockwise from north) the model predicted for the newest
    fix, before seeing it; NaN while it knows no velocity yet.

    This is what the pipeline uses in place of a reported speed and heading
    when a file has none: a turn-aware velocity from the positions alone,
    which does not follow a fix it rejected.
    """
    ve = state[S_PVE]
    vn = state[S_PVN]
    if not (np.isfinite(ve) and np.isfinite(vn)):
        return np.nan, np.nan
    return math.hypot(ve, vn), math.degrees(math.atan2(ve, vn)) % 360.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@numba.njit(cache=True, error_model="numpy")
def motion_step(
    p: FloatArray, state: FloatArray, dt: float, east: float, north: float, out: FloatArray
) -> None:
    """Advance the model by one fix at ``(east, north)`` metres, ``dt`` s after the previous one.

    Writes the :data:`MOTION_FEATURES` into ``out``. ``dt`` that is not
    finite or not positive (the first fix of a segment) counts as one period.
    """
    period = p[P_PERIOD]
    step_dt = dt if (np.isfinite(dt) and dt > 0.0) else period
    count = state[S_COUNT]
    for k in range(N_MOTION_FEATURES):
        out[k] = 0.0
    out[7] = step_dt / period
    state[S_PVE] = np.nan
    state[S_PVN] = np.nan
    if count == 0.0:
        state[S_PE] = east
        state[S_PN] = north
        state[S_VE] = 0.0
        state[S_VN] = 0.0
        state[S_W] = 0.0
        state[S_M2] = p[P_INIT] * p[P_INIT]
        state[S_RUN] = 0.0
        state[S_ZE] = east
        state[S_ZN] = north
        state[S_COUNT] = 1.0
        return
    if count == 1.0:
        state[S_VE] = (east - state[S_PE]) / step_dt
        state[S_VN] = (north - state[S_PN]) / step_dt
        state[S_PE] = east
        state[S_PN] = north
        state[S_ZE] = east
        state[S_ZN] = north
        state[S_COUNT] = 2.0
        return
    ve = state[S_VE]
    vn = state[S_VN]
    w = state[S_W]
    angle = w * step_dt
    c = math.cos(angle)
    s = math.sin(angle)
    # Heading measured clockwise from north: a positive turn rate turns right.
    pve = c * ve + s * vn
    pvn = -s * ve + c * vn
    state[S_PVE] = pve
    state[S_PVN] = pvn
    pred_e = state[S_PE] + pve * step_dt
    pred_n = state[S_PN] + pvn * step_dt
    re = east - pred_e
    rn = north - pred_n
    innov = math.hypot(re, rn)
    speed = math.hypot(pve, pvn)
    if speed > 0.5:
        ue = pve / speed
        un = pvn / speed
        along = re * ue + rn * un
        cross = re * un - rn * ue
    else:
        along = innov
        cross = 0.0
    m2 = state[S_M2]
    scale = math.sqrt(max(m2, p[P_FLOOR] * p[P_FLOOR]))
    nis = innov / scale
    # Re-acquisition: this fix's own step from the previous observed fix
    # agrees with the predicted motion (the track continues from elsewhere).
    own_e = east - state[S_ZE] - pve * step_dt
    own_n = north - state[S_ZN] - pvn * step_dt
    consistent = math.hypot(own_e, own_n) <= p[P_GATE] * scale
    gated = nis > p[P_GATE]
    run = state[S_RUN]
    if gated and not (run > 0.0 and consistent) and run + step_dt <= p[P_MAX_RUN]:
        # Dead-reckon through the fix.
        state[S_PE] = pred_e
        state[S_PN] = pred_n
        state[S_VE] = pve
        state[S_VN] = pvn
        state[S_RUN] = run + step_dt
    else:
        if gated:
            # Re-acquired: the velocity comes from the fix's own step, not the jump.
            obs_e = (east - state[S_ZE]) / step_dt
            obs_n = (north - state[S_ZN]) / step_dt
        else:
            obs_e = (east - state[S_PE]) / step_dt
            obs_n = (north - state[S_PN]) / step_dt
            m2 = (1.0 - p[P_MEMORY]) * m2 + p[P_MEMORY] * innov * innov
        g = 1.0 - math.exp(-step_dt / p[P_VEL_TAU])
        new_ve = g * obs_e + (1.0 - g) * pve
        new_vn = g * obs_n + (1.0 - g) * pvn
        old_speed = math.hypot(ve, vn)
        new_speed = math.hypot(new_ve, new_vn)
        w_obs = 0.0
        if old_speed > 1.0 and new_speed > 1.0:
            # Course (clockwise from north) change per second.
            w_obs = _wrap(math.atan2(new_ve, new_vn) - math.atan2(ve, vn)) / step_dt
        gw = 1.0 - math.exp(-step_dt / p[P_TURN_TAU])
        w_new = gw * w_obs + (1.0 - gw) * w
        state[S_W] = min(max(w_new, -p[P_MAX_TURN]), p[P_MAX_TURN])
        state[S_VE] = new_ve
        state[S_VN] = new_vn
        state[S_PE] = east
        state[S_PN] = north
        state[S_M2] = m2
        state[S_RUN] = 0.0
    state[S_ZE] = east
    state[S_ZN] = north
    state[S_COUNT] = count + 1.0
    out[0] = innov
    out[1] = along
    out[2] = cross
    out[3] = nis
    out[4] = state[S_RUN]
    out[5] = speed
    out[6] = abs(w) * speed


@numba.njit(cache=True, error_model="numpy")
def _motion_batch_kernel(
    p: FloatArray, dt: FloatArray, east: FloatArray, north: FloatArray
) -> FloatArray:
    state = np.zeros(N_MOTION_STATE)
    state[S_PVE] = state[S_PVN] = np.nan
    out = np.empty((east.size, N_MOTION_FEATURES))
    for i in range(east.size):
        motion_step(p, state, dt[i], east[i], north[i], out[i])
    return out


def motion_batch(
    t: FloatArray,
    east: FloatArray,
    north: FloatArray,
    period: float,
    params: MotionParams | None = None,
) -> FloatArray:
    """The features of one segment (times in s, positions in metres): ``(n, 8)``."""
    p = (params or MotionParams()).to_array(period)
    tt = np.ascontiguousarray(t, dtype=np.float64)
    dt = np.empty_like(tt)
    if tt.size:
        dt[0] = np.nan
        dt[1:] = np.diff(tt)
    return _motion_batch_kernel(
        p,
        dt,
        np.ascontiguousarray(east, dtype=np.float64),
        np.ascontiguousarray(north, dtype=np.float64),
    )


def motion_reference(
    t: FloatArray,
    east: FloatArray,
    north: FloatArray,
    period: float,
    params: MotionParams | None = None,
) -> FloatArray:
    """Readable version of :func:`motion_batch`, one fix at a time in plain Python."""
    prm = (params or MotionParams()).checked()
    rows = []
    pos = vel = last_obs = np.zeros(2)
    turn = 0.0
    m2 = prm.initial_scale**2
    run = 0.0
    for i in range(len(t)):
        z = np.array([east[i], north[i]], dtype=np.float64)
        dt = t[i] - t[i - 1] if i > 0 else math.nan
        dt = dt if (math.isfinite(dt) and dt > 0) else period
        row = np.zeros(N_MOTION_FEATURES)
        row[7] = dt / period
        if i == 0:
            pos, vel, last_obs, turn, m2, run = (
                z.copy(),
                np.zeros(2),
                z.copy(),
                0.0,
                prm.initial_scale**2,
                0.0,
            )
            rows.append(row)
            continue
        if i == 1:
            vel, pos, last_obs = (z - pos) / dt, z.copy(), z.copy()
            rows.append(row)
            continue
        turn_before = turn
        a = turn * dt
        rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
        v_pred = rot @ vel
        pred = pos + v_pred * dt
        r = z - pred
        innov = float(math.hypot(r[0], r[1]))
        speed = float(math.hypot(v_pred[0], v_pred[1]))
        if speed > 0.5:
            u = v_pred / speed
            along, cross = float(r @ u), float(r[0] * u[1] - r[1] * u[0])
        else:
            along, cross = innov, 0.0
        scale = math.sqrt(max(m2, prm.noise_floor**2))
        nis = innov / scale
        own = z - last_obs - v_pred * dt
        consistent = math.hypot(own[0], own[1]) <= prm.gate * scale
        gated = nis > prm.gate
        if gated and not (run > 0 and consistent) and run + dt <= prm.max_run_s:
            pos, vel, run = pred, v_pred, run + dt
        else:
            if gated:
                obs = (z - last_obs) / dt
            else:
                obs = (z - pos) / dt
                m2 = (1 - prm.memory) * m2 + prm.memory * innov**2
            g = 1 - math.exp(-dt / prm.velocity_tau_s)
            new_vel = g * obs + (1 - g) * v_pred
            w_obs = 0.0
            if math.hypot(*vel) > 1.0 and math.hypot(*new_vel) > 1.0:
                change = math.atan2(new_vel[0], new_vel[1]) - math.atan2(vel[0], vel[1])
                w_obs = ((change + math.pi) % (2 * math.pi) - math.pi) / dt
            gw = 1 - math.exp(-dt / prm.turn_tau_s)
            turn = min(max(gw * w_obs + (1 - gw) * turn, -prm.max_turn), prm.max_turn)
            vel, pos, run = new_vel, z.copy(), 0.0
        last_obs = z.copy()
        row[:7] = [innov, along, cross, nis, run, speed, abs(turn_before) * speed]
        rows.append(row)
    return np.array(rows).reshape(-1, N_MOTION_FEATURES)
