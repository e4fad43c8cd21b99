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
  (trapezoid rule) plus a learnt velocity bias (an EMA, weight
  ``bias_alpha``, of the explained steps' disagreement with the reported
  velocity: real receivers report speed and heading that disagree with their
  own position steps by a steady few m/s over whole stretches, through
  latency, scale errors or filtering, and unexplained steps there would pile
  up into a phantom offset), else from a constant-velocity estimate (an EMA of the
  *explained* steps' velocities);
* the *residual* is the observed step minus the predicted one;
* a residual larger than ``threshold_m`` (plus what a car's acceleration
  explains over the step, ``accel_allowance``) is *unexplained* (a fault
  starts, changes or ends). There are then two estimates of the offset, the old
  offset plus the residual and the fix's distance to the clean-track
  estimate (below), and the smaller one is taken: the first goes wrong when
  one step of a noise run is misread, the second when dead reckoning drifts
  during a long fault, and a fault that has ended is near zero by whichever
  is right. A smaller residual is explained: the offset leaks towards zero,
  slowly (``leak_per_s``) inside a suspected fault (offset beyond
  ``threshold_m``), so a 100 s jump fault stays visible, and fast
  (``fast_leak_per_s``) otherwise; the constant-velocity estimate learns
  from the step (a jump's points move like the real track), the velocity
  bias only outside a suspected fault;
* three unexplained steps in a row that miss the prediction by the same
  amount (within ``threshold_m``), at a speed a car can drive, are a
  *velocity error*, not a fault: a jump is one step off, after which its
  points move like the real track, while a wrong predicted velocity (the
  estimate a segment's first step set from a fix that was off, or one
  learnt from noise steps that happened to look explained) misses every
  step by the same amount. The third step undoes what the run did to the
  offset and corrects the constant-velocity estimate by the miss; without
  this, the tracker added the same miss to the offset every step and held
  the sum on clean fixes for ``max_fault_s``. Only where the tracker
  predicts with its own estimate: a reported velocity (or the motion
  model's, which the pipeline passes only for fixes that model predicted)
  has the bias for its steady errors, and a bias pushed by a whole miss
  stayed wrong once that velocity was right again (the bias learns outside
  faults only) and held a phantom offset at the next stop (fresh simulated
  drives at 0.5 Hz);
* the *clean-track estimate* is dead-reckoned with the predicted steps and
  re-anchored on the fix after every explained step outside a suspected
  fault (not on the unexplained step that seems to end one: that fix may be
  one more noise point that happens to look right). A suspected fault ends
  when the offset falls back within ``threshold_m`` *or* when the fix comes
  back within a gate of the clean-track estimate; the gate grows with the
  fault's age (``drift_per_s``, dead reckoning drifts) but stays below half
  the offset, so a real jump cannot end by drift. ``max_fault_s`` bounds how
  long any suspicion lives, so a stretch where the reported velocity
  disagrees with the fixes (real drives have them), or a segment that
  starts inside a fault, cannot leave an offset behind for ever. A fault
  that outlives ``max_fault_s`` is released, but remembered for as long
  again: a later unexplained step that undoes the released offset (within
  ``threshold_m`` plus a quarter of it: a held offset leaks a little) is that fault's *end*, a return to the track, not the
  start of a new one. The same holds for a fault whose end was read from the
  drift gate rather than from a step back, if its offset had been held
  through the step before (an offset the last step set is one noise fix's,
  and a later jump's first step that happened to undo it would read as that
  old fault's end). A released fault's end clears only the channels it held. Without that memory a long fault at a low rate (200 s
  at 0.5 Hz) would be followed by as long a phantom fault once it ended.

So ``offset`` is approximately the current fault offset: it jumps to ``d``
when a jump of ``d`` starts and back to zero when it ends. Outputs per point:
offset east/north (m), its norm (m), the change of the norm at this point
(m; negative when the step took the track back towards where it should be,
which is what tells the *end* of a fault from the start of one, both being
big unexplained steps), the residual east/north (m), the distance from the
fix to the clean-track estimate (m) and the
age of the suspected fault (s, 0 while none is).

A segment's first step starts the constant-velocity estimate (it explains
itself), unless no car drives it (faster than ``CAR_MAX_SPEED``): then one of
its two fixes is off, and the segment starts afresh at the second (again if
the next step is no car's either); after such a restart the first drivable
step starts the estimate still, since it may end on the odd fix as well as
start from it. The motion model does the same.

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

from .._exceptions import ConfigError
from .vehicle import CAR_MAX_ACCEL, CAR_MAX_SPEED

__all__ = [
    "OFFSET_FEATURES",
    "OffsetParams",
    "offset_features",
    "offset_features_reference",
    "offset_step",
]

FloatArray = NDArray[np.float64]

OFFSET_FEATURES = (
    "offset_east",
    "offset_north",
    "offset_norm",
    "offset_change",
    "residual_east",
    "residual_north",
    "clean_distance",
    "fault_age_s",
)
N_OFFSET_FEATURES = len(OFFSET_FEATURES)
N_OFFSET_PARAMS = 9
(
    P_THRESHOLD,
    P_LEAK,
    P_ALPHA,
    P_FAST_LEAK,
    P_DRIFT,
    P_MAX_FAULT,
    P_BIAS_ALPHA,
    P_TRUST,
    P_ACCEL,
) = range(N_OFFSET_PARAMS)
# State: count, last east, last north, last ve, last vn (reported, NaN if none),
# cv ve, cv vn, offset east, offset north, clean-track east, north, fault age (s),
# velocity bias east, north (m/s), the offset released by ``max_fault_s`` east,
# north (m) and the seconds since that release; then, per channel (east, north),
# the previous step's residual (m), the offset before the current run of
# unexplained steps that miss the prediction by the same amount (m), and that
# run's length (see :func:`_channel`: three such steps are a velocity error).
(
    S_COUNT,
    S_E,
    S_N,
    S_VE,
    S_VN,
    S_CVE,
    S_CVN,
    S_OE,
    S_ON,
    S_CE,
    S_CN,
    S_AGE,
    S_BE,
    S_BN,
    S_RE,
    S_RN,
    S_RAGE,
    S_QRE,
    S_QRN,
    S_QOE,
    S_QON,
    S_QUE,
    S_QUN,
) = range(23)
N_OFFSET_STATE = 23
# Unexplained steps in a row, each missing the prediction by the same amount, that
# make a velocity error: three fixes after the last explained one moving
# consistently among themselves (two steps of a noise run agree by chance). Each
# step must be one a car can drive (CAR_MAX_SPEED): a stationary receiver's noise
# run of 0, +23, +47 m at 5 Hz agrees with itself at 120 m/s, no velocity to learn.
_VELOCITY_ERROR_STEPS = 3
# How far (a fraction of the released offset) a step may miss undoing it and still
# count as the released fault's end: the held offset has leaked by up to
# 1 - (1 - leak_per_s) ** max_fault_s (18 % with the defaults) before release.
_RETURN_SLACK = 0.25


@dataclass(frozen=True)
class OffsetParams:
    """``threshold_m``: residual norm above which a step is unexplained; ``leak_per_s``:
    fraction of the offset forgotten per second of explained motion while a fault is
    suspected (``fast_leak_per_s`` otherwise); ``cv_alpha``: EMA weight of the
    constant-velocity estimate; ``drift_per_s``: growth of the gate around the
    dead-reckoned clean track; ``max_fault_s``: longest a suspected fault is held;
    ``bias_alpha``: EMA weight of the reported velocity's bias; ``trust_clean_s``: fault
    age up to which the dead-reckoned clean track alone measures the offset;
    ``accel_allowance``: m/s², what a car's braking or speeding up moves it off
    the predicted step: a residual within ``threshold_m + accel_allowance *
    dt**2 / 2`` is explained. 6 m/s² (about 0.6 g, the most a car pulls):
    at 0.5 Hz a car braking at 3-6 m/s² misses a constant-velocity step by
    6-12 m from the deceleration alone (more with the velocity estimate's
    lag), and that is no jump; at 1 Hz the allowance is 3 m, at 10 Hz 3 cm."""

    threshold_m: float = 8.0
    leak_per_s: float = 0.002
    cv_alpha: float = 0.5
    fast_leak_per_s: float = 0.1
    drift_per_s: float = 0.2
    max_fault_s: float = 100.0
    bias_alpha: float = 0.1
    trust_clean_s: float = 10.0
    accel_allowance: float = CAR_MAX_ACCEL

    def to_array(self) -> FloatArray:
        if not (
            self.threshold_m > 0
            and 0 <= self.leak_per_s < 1
            and 0 < self.cv_alpha <= 1
            and 0 <= self.fast_leak_per_s < 1
            and self.drift_per_s >= 0
            and self.max_fault_s > 0
            and 0 <= self.bias_alpha <= 1
            and self.trust_clean_s >= 0
            and math.isfinite(self.accel_allowance)
            and self.accel_allowance >= 0
        ):
            raise ConfigError(
                "offset tracker needs threshold_m > 0, 0 <= leak_per_s < 1, 0 < cv_alpha <= 1, "
                "0 <= fast_leak_per_s < 1, drift_per_s >= 0, max_fault_s > 0, "
                f"0 <= bias_alpha <= 1, trust_clean_s >= 0, accel_allowance >= 0; got {self.threshold_m}, {self.leak_per_s}, "
                f"{self.cv_alpha}, {self.fast_leak_per_s}, {self.drift_per_s}, {self.max_fault_s}, "
                f"{self.bias_alpha}, {self.trust_clean_s}, {self.accel_allowance}"
            )
        return np.array(
            [
                self.threshold_m,
                self.leak_per_s,
                self.cv_alpha,
                self.fast_leak_per_s,
                self.drift_per_s,
                self.max_fault_s,
                self.bias_alpha,
                self.trust_clean_s,
                self.accel_allowance,
            ]
        )


def _velocity(speed: float, heading: float) -> tuple[float, float]:
    if math.isfinite(speed) and math.isfinite(heading):
        h = math.radians(heading)
        return speed * math.sin(h), speed * math.cos(h)
    return math.nan, math.nan


def offset_features_reference(
    dt: ArrayLike,
    east: ArrayLike,
    north: ArrayLike,
    speed: ArrayLike,
    heading: ArrayLike,
    params: OffsetParams | None = None,
) -> FloatArray:
    """Readable version of the tracker over one segment; ``dt[i]`` = t[i] - t[i-1] (dt[0] unused)."""
    prm = params or OffsetParams()
    d = np.asarray(dt, dtype=np.float64)
    fix = np.stack([np.asarray(east, dtype=np.float64), np.asarray(north, dtype=np.float64)], 1)
    sp = np.asarray(speed, dtype=np.float64)
    hd = np.asarray(heading, dtype=np.float64)
    out = np.zeros((len(fix), N_OFFSET_FEATURES))
    offset = [0.0, 0.0]
    cv = [0.0, 0.0]
    clean = [0.0, 0.0]
    bias = [0.0, 0.0]
    age = 0.0
    released = [0.0, 0.0]
    release_age = 0.0
    # Per channel: the previous step's residual, how many unexplained steps in a row
    # have missed the prediction by the same amount, and the offset before them.
    last_residual = [0.0, 0.0]
    run = [0, 0]
    before_run = [0.0, 0.0]
    first = 0  # the segment's first fix, as far as the tracker knows
    restarted = False
    for i in range(len(fix)):
        if i == 0:
            clean = [fix[0, 0], fix[0, 1]]
            continue
        step = fix[i] - fix[i - 1]
        v_prev = _velocity(float(sp[i - 1]), float(hd[i - 1]))
        v_now = _velocity(float(sp[i]), float(hd[i]))
        reported = all(math.isfinite(v) for v in (*v_prev, *v_now))
        if reported:
            predicted = [(0.5 * (v_prev[c] + v_now[c]) + bias[c]) * d[i] for c in range(2)]
        elif i == first + 1:
            predicted = [step[0], step[1]]  # no history yet: the first step explains itself
        else:
            predicted = [cv[c] * d[i] for c in range(2)]
        residual = [step[c] - predicted[c] for c in range(2)]
        if i == first + 1:
            if math.hypot(step[0], step[1]) > CAR_MAX_SPEED * d[i]:
                first, restarted = i, True  # no car drives it: a fix is off, start afresh
            elif restarted:
                cv = [0.0, 0.0]  # after a restart its fix may be the odd one: no velocity
            else:
                cv = [step[0] / d[i], step[1] / d[i]]  # the velocity estimate starts from it too
            clean = [fix[i, 0], fix[i, 1]]
            out[i, 4:6] = residual
            continue
        norm_before = math.hypot(*offset)
        offset_before = [offset[0], offset[1]]
        # The offset was held through the step into the last fix (that step explained
        # in both channels), not set by it: only such an offset is worth remembering.
        allowed = prm.threshold_m + 0.5 * prm.accel_allowance * d[i] ** 2
        held = all(abs(last_residual[c]) <= allowed for c in range(2))
        for c in range(2):
            before = offset[c]
            in_fault = abs(before) > prm.threshold_m
            clean[c] += predicted[c]
            explained = abs(residual[c]) <= allowed
            undone = (
                not explained
                and in_fault
                and abs(before + residual[c]) <= prm.threshold_m + _RETURN_SLACK * abs(before)
            )
            if explained or undone:
                run[c] = 0
            elif (
                not reported
                and run[c] > 0
                and abs(residual[c] - last_residual[c]) <= prm.threshold_m
                and math.hypot(*step) <= CAR_MAX_SPEED * d[i]
            ):
                run[c] += 1  # the fixes move consistently; the prediction misses them
            else:
                run[c], before_run[c] = 1, before
            if undone:
                offset[c] = 0.0  # the step undid the offset: back on the track
            elif run[c] >= _VELOCITY_ERROR_STEPS:  # a wrong velocity, not a fault: undo
                # what those steps did to the offset, correct the velocity
                offset[c] = before_run[c]
                cv[c] += residual[c] / d[i]
                clean[c] = fix[i, c] - offset[c]
                run[c] = 0
            elif not explained:  # a fault starts, changes or ends: two estimates of the
                # offset; the smaller one is right when either is
                offset[c] = min(before + residual[c], fix[i, c] - clean[c], key=abs)
                if in_fault and age < prm.trust_clean_s:  # dead reckoning is still exact
                    offset[c] = fix[i, c] - clean[c]
            else:  # explained: a jump's points move like the real track
                rate = prm.leak_per_s if in_fault else prm.fast_leak_per_s
                offset[c] = before * max(0.0, 1.0 - rate * d[i])
                # ... no faster than a car changes its velocity (accel_allowance)
                change = prm.cv_alpha * (step[c] / d[i] - cv[c])
                limit = prm.accel_allowance * d[i]
                cv[c] += min(max(change, -limit), limit)
                if reported and not in_fault:  # bias + residual / dt: the step's disagreement
                    bias[c] += prm.bias_alpha * residual[c] / d[i]
            gate = min(
                prm.threshold_m + prm.drift_per_s * age, 0.5 * max(abs(offset[c]), abs(before))
            )
            if in_fault and (abs(offset[c]) <= prm.threshold_m or abs(fix[i, c] - clean[c]) < gate):
                offset[c] = 0.0  # it ended: what is left is prediction error
            if explained and abs(offset[c]) <= prm.threshold_m:
                clean[c] = fix[i, c]  # a clean step from a clean fix: re-anchor
            last_residual[c] = residual[c]
        suspected = max(abs(offset[0]), abs(offset[1])) > prm.threshold_m
        age = age + d[i] if suspected else 0.0
        slack = prm.threshold_m + _RETURN_SLACK * math.hypot(*offset_before)
        if (
            norm_before > prm.threshold_m
            and held
            and offset == [0.0, 0.0]
            and math.hypot(residual[0] + offset_before[0], residual[1] + offset_before[1]) > slack
        ):
            # Ended by the drift gate, not by a step back: remember it as released.
            released, release_age = offset_before, 0.0
        elif released != [0.0, 0.0]:
            release_age += d[i]
            undone = math.hypot(residual[0] + released[0], residual[1] + released[1])
            tolerance = prm.threshold_m + _RETURN_SLACK * math.hypot(*released)
            if undone <= tolerance:  # the released fault ends: back on the track in
                # the channels it held; a fault still held in the other goes on
                for c in range(2):
                    if abs(released[c]) > prm.threshold_m or abs(offset[c]) <= prm.threshold_m:
                        offset[c], clean[c] = 0.0, fix[i, c]
                if max(abs(offset[0]), abs(offset[1])) <= prm.threshold_m:
                    age = 0.0
                released = [0.0, 0.0]
            elif release_age > prm.max_fault_s:
                released = [0.0, 0.0]
        if age > prm.max_fault_s:  # held too long to be a fault: start afresh here
            released, release_age = [offset[0], offset[1]], 0.0
            offset, clean, age = [0.0, 0.0], [fix[i, 0], fix[i, 1]], 0.0
        distance = math.hypot(fix[i, 0] - clean[0], fix[i, 1] - clean[1])
        out[i] = (
            offset[0],
            offset[1],
            math.hypot(*offset),
            math.hypot(*offset) - norm_before,
            residual[0],
            residual[1],
            distance,
            age,
        )
    return out


@numba.njit(cache=True)
def _explained_limit(p: FloatArray, dt: float) -> float:
    """The largest residual a step of ``dt`` seconds explains: ``threshold_m`` plus what a
    car's braking or speeding up moves it off the predicted step."""
    return float(p[P_THRESHOLD] + 0.5 * p[P_ACCEL] * dt * dt)


@numba.njit(cache=True)
def _channel(
    p: FloatArray,
    state: FloatArray,
    c: int,
    fix: float,
    predicted: float,
    residual: float,
    step: float,
    dt: float,
    reported: bool,
    drivable: bool,
) -> None:
    """One channel's offset, velocity estimates and clean track (c = 0 east, 1 north);
    ``drivable``: the observed step's speed is one a car can have."""
    o, cv, ce, b = S_OE + c, S_CVE + c, S_CE + c, S_BE + c
    qr, qo, qu = S_QRE + c, S_QOE + c, S_QUE + c
    before = state[o]
    in_fault = abs(before) > p[P_THRESHOLD]
    state[ce] += predicted
    explained = abs(residual) <= _explained_limit(p, dt)
    summed = before + residual
    undone = (
        not explained and in_fault and abs(summed) <= p[P_THRESHOLD] + _RETURN_SLACK * abs(before)
    )
    # Unexplained steps in a row that miss the prediction by the same amount
    # (the fixes move consistently among themselves) count up; the offset
    # before the first of them is kept.
    run = 0.0
    if not explained and not undone:
        if (
            not reported
            and drivable
            and state[qu] > 0.0
            and abs(residual - state[qr]) <= p[P_THRESHOLD]
        ):
            run = state[qu] + 1.0
        else:
            run = 1.0
            state[qo] = before
    velocity_error = run >= _VELOCITY_ERROR_STEPS
    if undone:
        # The step undid the offset: the fault's end, whatever dead reckoning says
        # (the clean-track estimate drifts metres a second in curves and took
        # the end of a noise run for a new 20 m offset, held for 100 s).
        state[o] = 0.0
    elif velocity_error:
        # The third unexplained step in a row off the prediction by the same
        # amount: the predicted velocity is wrong, not the fixes (a jump is one
        # step off, then its points move like the track). What those steps did
        # to the offset is undone and the velocity corrected, instead of adding
        # the same miss to the offset every step and holding it for max_fault_s.
        state[o] = state[qo]
        state[cv] += residual / dt
        state[ce] = fix - state[o]
        run = 0.0
    elif not explained:
        state[o] = summed if abs(summed) <= abs(fix - state[ce]) else fix - state[ce]
        if in_fault and state[S_AGE] < p[P_TRUST]:
            state[o] = fix - state[ce]
    else:
        state[o] = before * max(0.0, 1.0 - (p[P_LEAK] if in_fault else p[P_FAST_LEAK]) * dt)
        # The velocity follows the step, but no faster than a car can change its
        # own: a residual within threshold_m is a few metres, which at 5 Hz is
        # 25 m/s (a noise fix's step taught a parked car -14 m/s, and the next
        # noise step read as a fault's end held a phantom 35 m for 100 s).
        change = p[P_ALPHA] * (step / dt - state[cv])
        limit = p[P_ACCEL] * dt
        state[cv] += min(max(change, -limit), limit)
        if reported and not in_fault:
            state[b] += p[P_BIAS_ALPHA] * residual / dt
    gate = min(p[P_THRESHOLD] + p[P_DRIFT] * state[S_AGE], 0.5 * max(abs(state[o]), abs(before)))
    if in_fault and (abs(state[o]) <= p[P_THRESHOLD] or abs(fix - state[ce]) < gate):
        state[o] = 0.0
    if explained and abs(state[o]) <= p[P_THRESHOLD]:
        state[ce] = fix
    state[qr] = residual
    state[qu] = run


@numba.njit(cache=True)
def _return(p: FloatArray, state: FloatArray, c: int, fix: float) -> None:
    """A released fault's end in channel ``c``: where the release held an offset, or no
    fault is held now, the offset is zero and the clean track re-anchors on the fix."""
    if abs(state[S_RE + c]) > p[P_THRESHOLD] or abs(state[S_OE + c]) <= p[P_THRESHOLD]:
        state[S_OE + c] = 0.0
        state[S_CE + c] = fix


@numba.njit(cache=True)
def offset_step(
    p: FloatArray,
    state: FloatArray,
    dt: float,
    east: float,
    north: float,
    speed: float,
    heading: float,
    out: FloatArray,
) -> None:
    """One point of the tracker: advance ``state`` and write the features into ``out``."""
    count = state[S_COUNT]
    restart = False
    if np.isfinite(speed) and np.isfinite(heading):
        h = np.radians(heading)
        ve = speed * np.sin(h)
        vn = speed * np.cos(h)
    else:
        ve = np.nan
        vn = np.nan
    for k in range(N_OFFSET_FEATURES):
        out[k] = 0.0
    if count > 0.0:
        step_e = east - state[S_E]
        step_n = north - state[S_N]
        reported = np.isfinite(ve) and np.isfinite(state[S_VE])
        if reported:
            pred_e = (0.5 * (state[S_VE] + ve) + state[S_BE]) * dt
            pred_n = (0.5 * (state[S_VN] + vn) + state[S_BN]) * dt
        elif count == 1.0:
            pred_e = step_e
            pred_n = step_n
        else:
            pred_e = state[S_CVE] * dt
            pred_n = state[S_CVN] * dt
        out[4] = step_e - pred_e
        out[5] = step_n - pred_n
        drivable = np.hypot(step_e, step_n) <= CAR_MAX_SPEED * dt
        if count == 1.0:
            if drivable:
                # A restarted segment (NaN velocity) starts still: its first drivable
                # step may end on the odd fix as well as start from it.
                restarted = np.isnan(state[S_CVE])
                state[S_CVE] = 0.0 if restarted else step_e / dt
                state[S_CVN] = 0.0 if restarted else step_n / dt
            else:
                state[S_CVE] = np.nan  # marks the restart for the next first step
                # No car drives the first step: one of its two fixes is off, and
                # which one the next steps tell. Start afresh here: anchored on the
                # first fix, a noise fix second in a 10 Hz segment held a 36 m offset
                # on the clean fixes after it, and its 364 m/s taught the velocity.
                restart = True
        else:
            norm_before = np.hypot(state[S_OE], state[S_ON])
            before_e = state[S_OE]
            before_n = state[S_ON]
            allowed = _explained_limit(p, dt)
            held = abs(state[S_QRE]) <= allowed and abs(state[S_QRN]) <= allowed
            _channel(p, state, 0, east, pred_e, out[4], step_e, dt, reported, drivable)
            _channel(p, state, 1, north, pred_n, out[5], step_n, dt, reported, drivable)
            if max(abs(state[S_OE]), abs(state[S_ON])) > p[P_THRESHOLD]:
                state[S_AGE] += dt
            else:
                state[S_AGE] = 0.0
            slack = p[P_THRESHOLD] + _RETURN_SLACK * norm_before
            if (
                norm_before > p[P_THRESHOLD]
                and held
                and state[S_OE] == 0.0
                and state[S_ON] == 0.0
                and np.hypot(out[4] + before_e, out[5] + before_n) > slack
            ):
                # Ended by the drift gate, not by a step back: remember it as released,
                # if the offset had been held through the step before (a jump's
                # points move like the track). An offset the last step set is one
                # noise fix's: remembered, a later jump's start that happened to undo
                # it read as that old fault's end, and the jump went unseen.
                state[S_RE] = before_e
                state[S_RN] = before_n
                state[S_RAGE] = 0.0
            elif state[S_RE] != 0.0 or state[S_RN] != 0.0:
                state[S_RAGE] += dt
                undone = np.hypot(out[4] + state[S_RE], out[5] + state[S_RN])
                if undone <= p[P_THRESHOLD] + _RETURN_SLACK * np.hypot(state[S_RE], state[S_RN]):
                    # The released fault ends: back on the track in the channels it
                    # held. A fault still held in the other channel goes on (an
                    # east offset held through a north burst's return was zeroed
                    # with it, and the clean track re-anchored on the faulty fix).
                    _return(p, state, 0, east)
                    _return(p, state, 1, north)
                    if max(abs(state[S_OE]), abs(state[S_ON])) <= p[P_THRESHOLD]:
                        state[S_AGE] = 0.0
                    state[S_RE] = 0.0
                    state[S_RN] = 0.0
                elif state[S_RAGE] > p[P_MAX_FAULT]:
                    state[S_RE] = 0.0
                    state[S_RN] = 0.0
            if state[S_AGE] > p[P_MAX_FAULT]:
                state[S_RE] = state[S_OE]
                state[S_RN] = state[S_ON]
                state[S_RAGE] = 0.0
                state[S_OE] = 0.0
                state[S_ON] = 0.0
                state[S_AGE] = 0.0
                state[S_CE] = east
                state[S_CN] = north
            out[0] = state[S_OE]
            out[1] = state[S_ON]
            out[2] = np.hypot(state[S_OE], state[S_ON])
            out[3] = out[2] - norm_before
            out[6] = np.hypot(east - state[S_CE], north - state[S_CN])
            out[7] = state[S_AGE]
    if count <= 1.0:
        state[S_CE] = east
        state[S_CN] = north
    state[S_COUNT] = count if restart else count + 1.0
    state[S_E] = east
    state[S_N] = north
    state[S_VE] = ve
    state[S_VN] = vn


@numba.njit(cache=True)
def _offset_kernel(
    p: FloatArray,
    dt: FloatArray,
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
) -> FloatArray:
    state = np.zeros(N_OFFSET_STATE)
    out = np.empty((east.size, N_OFFSET_FEATURES))
    for i in range(east.size):
        offset_step(p, state, dt[i], east[i], north[i], speed[i], heading[i], out[i])
    return out


def offset_features(
    dt: ArrayLike,
    east: ArrayLike,
    north: ArrayLike,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
    params: OffsetParams | None = None,
) -> FloatArray:
    """The tracker over one segment (numba); ``speed``/``heading`` may be None or contain NaN."""
    e = np.ascontiguousarray(east, dtype=np.float64)
    nan = np.full(e.size, np.nan)
    return np.asarray(
        _offset_kernel(
            (params or OffsetParams()).to_array(),
            np.ascontiguousarray(dt, dtype=np.float64),
            e,
            np.ascontiguousarray(north, dtype=np.float64),
            nan if speed is None else np.ascontiguousarray(speed, dtype=np.float64),
            nan if heading is None else np.ascontiguousarray(heading, dtype=np.float64),
        )
    )
