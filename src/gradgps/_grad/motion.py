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
  cross-track components, and normalised by a scale: a running mean of
  accepted squared innovations (floored by ``noise_floor`` metres), plus, in
  quadrature, what a car's routine unpredicted acceleration moves it over
  the step (``maneuver_accel * dt**2 / 2``). The first part adapts to the
  receiver and the driving, so a phone on a motorway and an RTK receiver in
  town read alike; the second gives a 0.5 Hz file's 2 s steps the slack a
  braking car needs, and costs a 10 Hz file nothing.
  The running mean is robust: each accepted innovation enters it clipped at
  :data:`SCALE_CLIP` times the current noise scale (a winsorised scale, as
  Huber's). Unclipped, a fix accepted near the gate (4 scales) grew the mean
  by up to 80 % at once, so a run of noise fixes opened the gate a little
  wider at every fix; and a fix the gate accepts only through the manoeuvre
  term (after a gap, where a car's routine acceleration explains hundreds
  of metres) says nothing about the receiver's noise: over a DrivePlotR
  validation drive taken as one segment across a gap, one 860 m innovation
  took the scale from 2 m to 190 m, and for more than a hundred fixes the
  gate let 50 m jumps through and pulled the velocity after them.
* **Gate**: a fix whose normalised innovation exceeds ``gate`` is not used to
  update; the filter dead-reckons through it (``run_s`` counts the seconds).
* **No state stays diverged.** A gated fix is re-acquired when its own step
  from the previous *observed* fix agrees with the motion, or with the
  previous observed step while that one agreed with the step before it
  (three fixes moving consistently: each pair within the gate plus what
  ``max_accel`` explains; two steps of a noise run agree by chance), at a
  speed a car could have reached from the model's since it last followed
  the fixes (a fault whose offset grows step by step is no track):
  the track goes on from a new place (the end of a jump, or a jump that was
  the truth), or the vehicle braked or turned harder than the model
  followed. It is re-acquired unconditionally once ``max_run_s`` seconds
  have passed. On re-acquisition along the predicted motion the velocity
  is kept (the step may come from a fault's fix and teaches nothing); on
  re-acquisition against it the velocity follows the fix's own step four
  times faster than usual and the turn rate is measured afresh from the
  last two steps (a course change across a jump is no turn); the turn rate
  is always capped at ``max_accel`` over the speed, so dead reckoning cannot
  draw circles, and the speed at what a car drives (``CAR_MAX_SPEED``). Whatever the input, the filter follows the fixes again
  within ``max_run_s`` of the last one it rejected. (The memory of a lasting
  offset is the offset tracker's job, :mod:`gradgps._grad.offset`; this
  model only says how surprising each step is.)
* **Standing still**: ``still_s`` counts the seconds the fixes have moved
  slower than :data:`STILL_SPEED` (or by less than :data:`STILL_STEP_M`,
  whichever is more), and ``stop_decel`` is the deceleration the stop
  implied: the speed of the step before the first still fix over the still
  step's time (at least 1 s; the observed step, not the model's velocity,
  which lags a braking car by a second or two). A car brakes to a stop at a
  few m/s²; a receiver that freezes its fix while the car drives on "stops"
  from full speed within one step (10-30 m/s²). While the fixes stand still
  the two look the same; this is what tells them apart.

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
from .vehicle import CAR_MAX_ACCEL, CAR_MAX_SPEED

__all__ = [
    "MOTION_FEATURES",
    "N_MOTION_FEATURES",
    "N_MOTION_PARAMS",
    "N_MOTION_STATE",
    "SCALE_CLIP",
    "STILL_SPEED",
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
    "still_s",
    "stop_decel",
)
N_MOTION_FEATURES = len(MOTION_FEATURES)

(
    P_GATE,
    P_FLOOR,
    P_MEMORY,
    P_VEL_TAU,
    P_TURN_TAU,
    P_MAX_RUN,
    P_MAX_TURN,
    P_PERIOD,
    P_INIT,
    P_MAX_ACCEL,
    P_MANEUVER,
) = range(11)
N_MOTION_PARAMS = 11
# State: count, p east/north, v east/north, turn rate, m2, run seconds,
# previous observed east/north, and the velocity predicted for the newest fix
# (before it was seen; NaN until two fixes have set a velocity), and the
# velocity of the previous observed step (previous fix minus the one before),
# the seconds the fixes have stood still and the deceleration their stop implied,
# and whether the previous observed step agreed with the one before it (1.0).
(
    S_COUNT,
    S_PE,
    S_PN,
    S_VE,
    S_VN,
    S_W,
    S_M2,
    S_RUN,
    S_ZE,
    S_ZN,
    S_PVE,
    S_PVN,
    S_OVE,
    S_OVN,
    S_STILL,
    S_STOP_DECEL,
    S_AGREED,
) = range(17)
N_MOTION_STATE = 17
#: Accepted innovations enter the running scale clipped at this many times the
#: current noise scale (without the manoeuvre term): clean driving's innovations
#: sit near one scale and pass unchanged; an outlier can grow the running mean
#: of squares by at most ``memory * (SCALE_CLIP**2 - 1)`` (40 % with the
#: defaults) per fix.
SCALE_CLIP = 3.0
#: m/s: fixes moving slower than this stand still (a stopped car's receiver
#: noise, or one fix repeated) ...
STILL_SPEED = 0.5
#: ... or by less than this many metres a step (at 10 Hz a stopped receiver's
#: centimetres of noise are more than 0.5 m/s over 0.1 s).
STILL_STEP_M = 0.25


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
    ``max_accel``: m/s², the most a car accelerates, sideways or along
    (about 0.6 g): the turn rate is capped at this over the speed (a car at
    30 m/s turning at 0.5 rad/s would pull 1.5 g), and two observed steps
    "agree" when they differ by no more than ``gate`` sigmas plus what this
    acceleration explains over the step; ``maneuver_accel``: m/s², the
    acceleration a car pulls routinely and the model does not predict
    (braking, speeding up): ``maneuver_accel * dt**2 / 2`` adds to the
    innovation scale in quadrature, so a 0.5 Hz file's 2 s steps get the
    slack a braking car needs and a 10 Hz file keeps its tight gate;
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
    max_accel: float = CAR_MAX_ACCEL
    maneuver_accel: float = 2.0

    def checked(self) -> MotionParams:
        for name in (
            "gate",
            "noise_floor",
            "max_run_s",
            "max_turn",
            "initial_scale",
            "velocity_tau_s",
            "turn_tau_s",
            "max_accel",
            "maneuver_accel",
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
                self.max_accel,
                self.maneuver_accel,
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
    if count == 1.0 and (
        math.hypot(east - state[S_PE], north - state[S_PN]) > CAR_MAX_SPEED * step_dt
    ):
        # No car drives the segment's first step: one of its two fixes is off, and
        # which one the next steps tell. The segment starts afresh here (a noise fix
        # second in a 10 Hz segment started the velocity at 364 m/s).
        count = 0.0
        state[S_OVE] = np.nan  # marks the restart for the next first step
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
        restarted = np.isnan(state[S_OVE])
        state[S_OVE] = (east - state[S_PE]) / step_dt
        state[S_OVN] = (north - state[S_PN]) / step_dt
        # After a restart the first drivable step may end on the odd fix as well as
        # start from it: the model starts still and re-acquires from the steps after.
        state[S_VE] = 0.0 if restarted else state[S_OVE]
        state[S_VN] = 0.0 if restarted else state[S_OVN]
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
    maneuver = 0.5 * p[P_MANEUVER] * step_dt * step_dt
    scale = math.sqrt(max(m2, p[P_FLOOR] * p[P_FLOOR]) + maneuver * maneuver)
    nis = innov / scale
    # Re-acquisition: this fix's own step from the previous observed fix
    # agrees with the predicted motion, or with the previous observed step
    # (the track continues from elsewhere, or the vehicle braked or turned
    # harder than the model followed: the fixes agree among themselves).
    step_e = east - state[S_ZE]
    step_n = north - state[S_ZN]
    limit = p[P_GATE] * scale
    ove = state[S_OVE]
    ovn = state[S_OVN]
    run = state[S_RUN]
    # Two steps that agree among themselves are only a track to follow if a
    # car could have reached their speed from the model's since it last
    # followed the fixes: a fault whose offset grows by the same amount twice
    # (0, -24, -47 m) has steps that agree with each other at 120 m/s.
    # And it takes three fixes moving consistently, two steps in a row that
    # agree with the step before them: the steps of a noise run agree with
    # each other by chance one time in a few, and a model that re-acquired on
    # two of them took a velocity 13 m/s wrong and rejected the real track
    # for seconds after the noise had ended.
    pair_agrees = math.hypot(step_e - ove * step_dt, step_n - ovn * step_dt) <= (
        limit + p[P_MAX_ACCEL] * step_dt * step_dt
    )
    steps_agree = (
        pair_agrees
        and state[S_AGREED] != 0.0
        and math.hypot(step_e / step_dt - pve, step_n / step_dt - pvn)
        <= (p[P_MAX_ACCEL] * (run + step_dt) + limit / step_dt)
    )
    follows_motion = math.hypot(step_e - pve * step_dt, step_n - pvn * step_dt) <= limit
    consistent = steps_agree or follows_motion
    gated = nis > p[P_GATE]
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
            clipped = min(innov, SCALE_CLIP * math.sqrt(max(m2, p[P_FLOOR] * p[P_FLOOR])))
            m2 = (1.0 - p[P_MEMORY]) * m2 + p[P_MEMORY] * clipped * clipped
        # Re-acquired on a step that disagrees with the predicted motion (the
        # fixes agree among themselves): the model's velocity has just been
        # proven wrong, and the fixes' own step takes over four times faster.
        # Re-acquired on a step that follows the predicted motion (the track
        # goes on from elsewhere): the velocity was right, and a step from a
        # fix that may be one of a fault's teaches it nothing.
        tau = p[P_VEL_TAU] / 4.0 if gated and not follows_motion else p[P_VEL_TAU]
        g = 1.0 - math.exp(-step_dt / tau)
        new_ve = g * obs_e + (1.0 - g) * pve
        new_vn = g * obs_n + (1.0 - g) * pvn
        new_speed = math.hypot(new_ve, new_vn)
        if new_speed > CAR_MAX_SPEED:
            # No faster than a car drives: re-acquired on a long fault's fix
            # (max_run_s), the step between two noise fixes read 100 m/s.
            new_ve *= CAR_MAX_SPEED / new_speed
            new_vn *= CAR_MAX_SPEED / new_speed
            new_speed = CAR_MAX_SPEED
        old_speed = math.hypot(ve, vn)
        w_new = w
        if gated:
            # Re-acquired: the turn is measured afresh from the last two
            # observed steps when they agree (both on the new track), else
            # the old one is kept. A course change across a jump is no turn.
            if steps_agree and math.hypot(ove, ovn) > 1.0 and math.hypot(step_e, step_n) > step_dt:
                w_new = _wrap(math.atan2(step_e, step_n) - math.atan2(ove, ovn)) / step_dt
        else:
            # Course (clockwise from north) change per second.
            w_obs = 0.0
            if old_speed > 1.0 and new_speed > 1.0:
                w_obs = _wrap(math.atan2(new_ve, new_vn) - math.atan2(ve, vn)) / step_dt
            gw = 1.0 - math.exp(-step_dt / p[P_TURN_TAU])
            w_new = gw * w_obs + (1.0 - gw) * w
        w_cap = min(p[P_MAX_TURN], p[P_MAX_ACCEL] / max(new_speed, 1e-9))
        state[S_W] = min(max(w_new, -w_cap), w_cap)
        state[S_VE] = new_ve
        state[S_VN] = new_vn
        state[S_PE] = east
        state[S_PN] = north
        state[S_M2] = m2
        state[S_RUN] = 0.0
    if math.hypot(step_e, step_n) < max(STILL_SPEED * step_dt, STILL_STEP_M):
        if state[S_STILL] == 0.0:
            state[S_STOP_DECEL] = math.hypot(state[S_OVE], state[S_OVN]) / max(step_dt, 1.0)
        state[S_STILL] += step_dt
    else:
        state[S_STILL] = 0.0
        state[S_STOP_DECEL] = 0.0
    state[S_OVE] = step_e / step_dt
    state[S_OVN] = step_n / step_dt
    state[S_AGREED] = 1.0 if pair_agrees else 0.0
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
    out[8] = state[S_STILL]
    out[9] = state[S_STOP_DECEL]


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
    """The :data:`MOTION_FEATURES` of one segment (times in s, positions in metres): ``(n, 10)``."""
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
    pos = vel = last_obs = last_step_vel = np.zeros(2)
    turn = 0.0
    m2 = prm.initial_scale**2
    run = 0.0
    still = stop_decel = 0.0
    agreed = False  # the previous observed step agreed with the one before it
    first = 0  # the segment's first fix, as far as the model knows
    restarted = False
    for i in range(len(t)):
        z = np.array([east[i], north[i]], dtype=np.float64)
        dt = t[i] - t[i - 1] if i > 0 else math.nan
        dt = dt if (math.isfinite(dt) and dt > 0) else period
        row = np.zeros(N_MOTION_FEATURES)
        row[7] = dt / period
        if i == 0 or (i == first + 1 and math.hypot(*(z - pos)) > CAR_MAX_SPEED * dt):
            restarted = i > 0
            first = i  # a first step no car drives: start afresh here
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
        if i == first + 1:
            last_step_vel = (z - pos) / dt
            vel = np.zeros(2) if restarted else last_step_vel.copy()
            pos, last_obs = z.copy(), z.copy()
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
        scale = math.sqrt(max(m2, prm.noise_floor**2) + (0.5 * prm.maneuver_accel * dt * dt) ** 2)
        nis = innov / scale
        step = z - last_obs
        # ... three fixes in a row move consistently, and a car could have reached
        # their speed since the model last followed.
        pair_agrees = bool(
            np.hypot(*(step - last_step_vel * dt)) <= prm.gate * scale + prm.max_accel * dt * dt
        )
        steps_agree = (
            pair_agrees
            and agreed
            and bool(
                np.hypot(*(step / dt - v_pred))
                <= prm.max_accel * (run + dt) + prm.gate * scale / dt
            )
        )
        follows_motion = bool(np.hypot(*(step - v_pred * dt)) <= prm.gate * scale)
        consistent = steps_agree or follows_motion
        gated = nis > prm.gate
        if gated and not (run > 0 and consistent) and run + dt <= prm.max_run_s:
            pos, vel, run = pred, v_pred, run + dt
        else:
            if gated:
                obs = (z - last_obs) / dt
            else:
                obs = (z - pos) / dt
                clipped = min(innov, SCALE_CLIP * math.sqrt(max(m2, prm.noise_floor**2)))
                m2 = (1 - prm.memory) * m2 + prm.memory * clipped**2
            # Proven wrong (fast), or re-acquired along the predicted motion (kept).
            tau = prm.velocity_tau_s / 4 if gated and not follows_motion else prm.velocity_tau_s
            g = 1 - math.exp(-dt / tau)
            new_vel = g * obs + (1 - g) * v_pred
            if np.hypot(*new_vel) > CAR_MAX_SPEED:  # no faster than a car drives
                new_vel = new_vel * (CAR_MAX_SPEED / np.hypot(*new_vel))
            if gated:
                # Re-acquired: the turn afresh from the last two observed steps
                # when they agree; a course change across a jump is no turn.
                if steps_agree and np.hypot(*last_step_vel) > 1.0 and np.hypot(*step) > dt:
                    change = math.atan2(step[0], step[1]) - math.atan2(*last_step_vel)
                    turn = ((change + math.pi) % (2 * math.pi) - math.pi) / dt
            else:
                w_obs = 0.0
                if math.hypot(*vel) > 1.0 and math.hypot(*new_vel) > 1.0:
                    change = math.atan2(new_vel[0], new_vel[1]) - math.atan2(vel[0], vel[1])
                    w_obs = ((change + math.pi) % (2 * math.pi) - math.pi) / dt
                gw = 1 - math.exp(-dt / prm.turn_tau_s)
                turn = gw * w_obs + (1 - gw) * turn
            cap = min(prm.max_turn, prm.max_accel / max(math.hypot(*new_vel), 1e-9))
            turn = min(max(turn, -cap), cap)
            vel, pos, run = new_vel, z.copy(), 0.0
        if math.hypot(*step) < max(STILL_SPEED * dt, STILL_STEP_M):
            if still == 0.0:
                stop_decel = math.hypot(*last_step_vel) / max(dt, 1.0)
            still += dt
        else:
            still = stop_decel = 0.0
        last_obs, last_step_vel, agreed = z.copy(), step / dt, pair_agrees
        row[:7] = [innov, along, cross, nis, run, speed, abs(turn_before) * speed]
        row[8:10] = [still, stop_decel]
        rows.append(row)
    return np.array(rows).reshape(-1, N_MOTION_FEATURES)
