"""Offset tracker: how far the current fix sits from the clean track, as a stated model.

Why it exists: a *jump* fault (one offset shared by many points) shows as one
big step where it starts and one where it ends; in between, the corrupted
track moves exactly like the real one. Window features and REMA see the two
steps and then re-acquire the shifted track within seconds, yet real and
injected jumps last tens of seconds. A detector with a short memory misses
most of it; the tracker gives the model that memory explicitly.

The model (per channel, east and north apart: faults may hit one and not the
other, and a prediction error in one must not leak into the other). The fix
is ``z = p + o + e``:

* ``p``, the **clean track**: position, velocity and an acceleration that
  lasts (Singer's model: the acceleration is a Gauss-Markov process of spread
  ``sigma_a`` m/s² that forgets itself with time constant ``tau_a`` s). A car
  turning or braking accelerates for seconds, not for one fix: a track of
  constant velocity with white acceleration noise lags such a manoeuvre by
  about ``a * sigma_m / sigma_a`` metres at any rate, and at 10 Hz ten fixes a
  second testify to the lag, so a long fault was released early and its end
  read as a new jump (``docs/deviations.md``);
* ``e``, the receiver's **noise**, ``sigma_m`` m;
* ``o``, the **fault**, in one of three modes: *clean* (``o = 0``; the fix
  measures the track), *jump* (``o`` constant; the fix measures the track
  through ``z - o``, since a jump's fixes move like the real track) or
  *noise* (the fix is unrelated to the track: an outlier; the track coasts).

Between two fixes ``dt`` apart the mode changes with stated probabilities:
a fault starts (clean -> jump at ``jump_per_s``, clean -> noise at
``noise_per_s``, a jump's offset uniform over +-``span_m``), ends (-> clean,
hazard ``dt / fault_s``: faults are expected to last about ``fault_s``),
changes kind (``switch_per_s``), and a noise fix is followed by another with
probability ``noise_stay``. Any mode may also *restart*: the clean track
itself was wrong (a cold start on a bad fix, a long fault taken for the
track) and starts again on the fix (``restart_per_s``, more often where a
segment starts: a track built on a few fixes is the least certain). Reported speed
and heading, where the file has both, measure the velocity (``sigma_v``
m/s): a Doppler velocity is not moved by a position fault.

The exact posterior over mode histories grows without bound; it is
approximated by a beam of :data:`BEAM` hypotheses, each with its own Kalman
state (track, velocity, covariance), offset, fault age and log-weight. At
each fix every hypothesis branches into the modes it can go to, the children
are weighted by their transition probability and the likelihood of the fix
(Gaussian where the fix measures the track, uniform over the span where it
sets an offset or is an outlier), and the best survive, always the best of
each mode among them, duplicates merged. This replaces a hand-tuned set of
rules (explained steps, re-anchoring, velocity-error runs, drift gates,
released faults) that held a phantom offset on 8-30 % of the normal fixes of
injected drives (``benchmarks/tried/tracker_accuracy.py``): there a noise fix
that looked clean re-anchored the track for good; here it is one branch,
dropped when the next fixes disagree with it.

Outputs per point: the best hypothesis's offset east/north (m: ``o`` in a
jump, ``z - p`` for an outlier, 0 when clean), its norm, the change of the
norm at this point, the fix's innovation against the best hypothesis before
it, over its spread, east/north (how surprising the fix is, in standard
deviations), the distance from the fix to that hypothesis's predicted clean
track (m), the fault's age (s, the older channel), and the evidence for a
fault (the log-weight of the best hypothesis over the best clean one, nats,
the larger channel), and the previous fix's offset norm as the best hypothesis's own
history has it now (0 where that history reads the previous fix as clean).

Why the last: the offset reported at a fix is the best hypothesis *then*; one fix
later the beam often knows better. After an outlier that looked like a manoeuvre,
the clean track follows it, the first good fix after it is read as a fault (a
phantom offset), and at the next fix the hypothesis that took the outlier for an
outlier wins again: its history says the fix before was clean. The network's
confirm head judges the previous fix one fix late; this is what a fixed-lag
smoother of one fix would tell it (``docs/deviations.md``, "the previous fix
revised").

Everything is causal and translation-invariant (the track starts on the
first fix). :func:`offset_features_reference` is the readable version; the
numba kernel :func:`offset_step` (state in a small array) is what pipelines
use, and a test keeps them equal.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError

__all__ = [
    "BEAM",
    "N_OFFSET_SCRATCH",
    "OFFSET_FEATURES",
    "OffsetParams",
    "check_state",
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
    "fault_evidence",
    "previous_offset_revised",
)
N_OFFSET_FEATURES = len(OFFSET_FEATURES)
N_OFFSET_PARAMS = 14
(
    P_SIGMA_A,
    P_TAU_A,
    P_SIGMA_M,
    P_SIGMA_V,
    P_JUMP,
    P_NOISE,
    P_SWITCH,
    P_NOISE_STAY,
    P_SPAN,
    P_FAULT_S,
    P_RESTART,
    P_START_RESTART,
    P_START_S,
    P_V0,
) = range(N_OFFSET_PARAMS)

#: Hypotheses kept per channel. On the validation drives and simulated ones at 0.5-10 Hz
#: (``benchmarks/tried/tracker_accuracy.py``, native rates) the mean phantom share was
#: 3.0 % with eight, 2.4 % with twelve, 2.2 % with sixteen, at 0.8 µs per hypothesis and
#: fix. Three slots are reserved for modes the best ones do not hold, so a clean track
#: survives a noise run.
BEAM = 12
_RESERVED = 3
# A hypothesis: clean track, velocity, acceleration, their covariance (the upper
# triangle row by row: pp, pv, pa, vv, va, aa), offset, fault age, log-weight, mode, and
# the offset it reported at the previous fix (0 where it was clean there).
H_P, H_V, H_A = range(3)
H_PP, H_PV, H_PA, H_VV, H_VA, H_AA = range(3, 9)
H_O, H_AGE, H_W, H_MODE, H_PREV = range(9, 14)
N_H = 14
CLEAN, JUMP, NOISE = 0.0, 1.0, 2.0
# Two children closer than this (m, m/s) in track, velocity and offset, of one
# mode, are one hypothesis (the better weight kept).
_SAME = 0.05
#: The chance that a fix repeating the previous one exactly (both coordinates, to the
#: last digit) was *held*: written again by a receiver that has no new solution (a
#: freeze, a tunnel, a jammed antenna), so unrelated to where the car is now. A live
#: fix repeats only where the receiver pins a standing car (static hold), and from the
#: fix alone the two are even odds: the held reading is an outlier child (its offset
#: uniform over the span, as any outlier's) at this prior instead of a fault's start,
#: the others keep their usual priors times the rest. At a stop the clean track still
#: explains a repeat better (it predicts the fix where it is); while the car moves, a
#: held fix falls behind it at once. Receiver noise never repeats a fix to the last
#: digit, so no other fix is read this way.
_HELD = 0.5
# Floor of a transition probability that long steps would take to zero or below.
_TINY = 1e-9
# The evidence feature's value when no clean hypothesis survives (nats).
_NO_CLEAN = 50.0
# State: count, last east, north, last norm of the offset, seconds since the segment
# started, then per channel the number of hypotheses and BEAM of them.
S_COUNT, S_E, S_N, S_NORM, S_T = range(5)
_S_BEAM = 5
_CHANNEL_STATE = 1 + BEAM * N_H
N_OFFSET_STATE = _S_BEAM + 2 * _CHANNEL_STATE
# Work space of one fix: up to four children per hypothesis and a restart, whether each
# has been ranked, the indices kept; then each channel's six outputs.
_MAX_KIDS = 4 * BEAM + 1
_CHILDREN = _MAX_KIDS * (N_H + 1) + BEAM
#: Work space of :func:`singer_step`: dt, the three transition entries that are not 0
#: or 1, then the process noise's upper triangle (pp, pv, pa, vv, va, aa).
N_STEP = 10
_N_CHANNEL_OUT = 6
N_OFFSET_SCRATCH = _CHILDREN + 2 * _N_CHANNEL_OUT + N_STEP


@dataclass(frozen=True)
class OffsetParams:
    """The model's stated parameters (see the module docstring).

    ``sigma_a`` m/s² and ``tau_a`` s: the spread of the clean track's acceleration and
    how long an acceleration lasts; ``sigma_m`` m: the receiver's noise; ``sigma_v``
    m/s: a reported velocity's noise; ``jump_per_s``, ``noise_per_s``: how often a jump or an outlier run starts on a clean track;
    ``switch_per_s``: how often a fault changes kind or a jump its offset;
    ``noise_stay``: the chance an outlier is followed by another; ``span_m``: the
    half-width of the uniform density of a fault's offset; ``fault_s``: a fault's
    expected length; ``restart_per_s``: how often the clean track turns out
    wrong, which is ``start_restart_per_s`` where a segment starts and falls to
    ``restart_per_s`` with a time constant of ``start_s`` seconds (a track built on a
    few fixes is the least certain: a receiver's first fixes after a cold start
    or an outage are its worst, and a track anchored on one of them reads every
    good fix after it as a jump); ``v0_sigma``: m/s, the velocity's spread where
    a track starts.
    """

    sigma_a: float = 1.0
    tau_a: float = 4.0
    sigma_m: float = 3.5
    sigma_v: float = 2.0
    jump_per_s: float = 0.005
    noise_per_s: float = 0.02
    switch_per_s: float = 0.03
    noise_stay: float = 0.7
    span_m: float = 100.0
    fault_s: float = 60.0
    restart_per_s: float = 1e-4
    start_restart_per_s: float = 0.01
    start_s: float = 10.0
    v0_sigma: float = 15.0

    def to_array(self) -> FloatArray:
        values = [
            self.sigma_a,
            self.tau_a,
            self.sigma_m,
            self.sigma_v,
            self.jump_per_s,
            self.noise_per_s,
            self.switch_per_s,
            self.noise_stay,
            self.span_m,
            self.fault_s,
            self.restart_per_s,
            self.start_restart_per_s,
            self.start_s,
            self.v0_sigma,
        ]
        if not (
            all(math.isfinite(v) for v in values)
            and self.sigma_a > 0
            and self.tau_a > 0
            and self.sigma_m > 0
            and self.sigma_v > 0
            and self.jump_per_s > 0
            and self.noise_per_s > 0
            and self.switch_per_s > 0
            and 0 < self.noise_stay < 1
            and self.span_m > 0
            and self.fault_s > 0
            and self.restart_per_s > 0
            and self.start_restart_per_s > 0
            and self.start_s > 0
            and self.v0_sigma > 0
        ):
            raise ConfigError(
                "offset tracker needs finite sigma_a, tau_a, sigma_m, sigma_v, jump_per_s, "
                "noise_per_s, switch_per_s, span_m, fault_s, restart_per_s, "
                "start_restart_per_s, start_s, v0_sigma > 0 and noise_stay in (0, 1); "
                f"got {self}"
            )
        return np.array(values, dtype=np.float64)


# ------------------------------------------------------------------ shared pieces


@numba.njit(cache=True)
def _transitions(p: FloatArray, mode: float, dt: float) -> tuple[float, float, float, float]:
    """log P(-> clean), log P(jump goes on), log P(-> new jump), log P(-> outlier) from
    ``mode`` over ``dt`` seconds (-inf where impossible)."""
    end = min(dt / p[P_FAULT_S], 0.5)
    jump = 1.0 - math.exp(-p[P_JUMP] * dt)
    noise = 1.0 - math.exp(-p[P_NOISE] * dt)
    switch = min(1.0 - math.exp(-p[P_SWITCH] * dt), 0.2)
    if mode == CLEAN:
        stay_clean = max(1.0 - jump - noise, _TINY)
        return math.log(stay_clean), -math.inf, math.log(jump), math.log(noise)
    if mode == JUMP:
        return math.log(end), math.log(1.0 - end - 2.0 * switch), math.log(switch), math.log(switch)
    stay = p[P_NOISE_STAY]
    return math.log(max(1.0 - stay - switch, _TINY)), -math.inf, math.log(switch), math.log(stay)


@numba.njit(cache=True)
def _log_restart(p: FloatArray, age_s: float, dt: float) -> float:
    """log P(the clean track was wrong) over a step of ``dt`` ending ``age_s`` seconds
    after its segment's first fix: the rate ``start_restart_per_s`` falling to
    ``restart_per_s`` with time constant ``start_s``."""
    decay = math.exp(-age_s / p[P_START_S])
    rate = p[P_RESTART] + (p[P_START_RESTART] - p[P_RESTART]) * decay
    return math.log(1.0 - math.exp(-rate * dt))


# Gauss-Legendre nodes and weights on [0, 1] (four points): the process noise of a
# step is integrated piecewise over spans of at most ``tau_a`` with them.
_GL_X = np.array([0.0694318442029737, 0.3300094782075719, 0.6699905217924281, 0.9305681557970263])
_GL_W = np.array([0.1739274225687269, 0.3260725774312731, 0.3260725774312731, 0.1739274225687269])


@numba.njit(cache=True)
def _response(s: float, alpha: float) -> tuple[float, float, float]:
    """Position, velocity and acceleration ``s`` seconds after a unit of acceleration,
    which then fades at rate ``alpha`` (expm1: exact where ``alpha * s`` is small)."""
    x = alpha * s
    return (math.expm1(-x) + x) / alpha**2, -math.expm1(-x) / alpha, math.exp(-x)


@numba.njit(cache=True)
def singer_step(p: FloatArray, dt: float, out: FloatArray) -> None:
    """The clean track's transition over ``dt`` seconds (Singer's model: the acceleration
    decays with ``tau_a`` and is driven by white noise that keeps its spread at
    ``sigma_a``) into ``out`` (:data:`N_STEP`): ``dt``, the transition's entries
    (p <- a, v <- a, a <- a) and the process noise ``Q = qc * int_0^dt r(s) r(s)' ds``
    (``r``: :func:`_response`, ``qc = 2 sigma_a² / tau_a``), integrated numerically
    (the closed form cancels catastrophically at 10 Hz). Shared by the kernel and the
    readable reference: one dt serves both channels and every hypothesis."""
    alpha = 1.0 / p[P_TAU_A]
    qc = 2.0 * p[P_SIGMA_A] ** 2 * alpha
    f02, f12, f22 = _response(dt, alpha)
    out[0] = dt
    out[1] = f02
    out[2] = f12
    out[3] = f22
    for k in range(4, N_STEP):
        out[k] = 0.0
    pieces = min(max(math.ceil(dt / p[P_TAU_A]), 1), 16)
    width = dt / pieces
    for j in range(pieces):
        for g in range(4):
            r0, r1, r2 = _response((j + _GL_X[g]) * width, alpha)
            w = qc * width * _GL_W[g]
            out[4] += w * r0 * r0
            out[5] += w * r0 * r1
            out[6] += w * r0 * r2
            out[7] += w * r1 * r1
            out[8] += w * r1 * r2
            out[9] += w * r2 * r2


@numba.njit(cache=True)
def _predict(h: FloatArray, step: FloatArray) -> None:
    """The hypothesis's track and covariance one step on (``step``: :func:`singer_step`):
    ``x <- F x``, ``P <- F P F' + Q``, written out for the transition's zeros."""
    dt, f02, f12, f22 = step[0], step[1], step[2], step[3]
    pp, pv, pa, vv, va, aa = h[H_PP], h[H_PV], h[H_PA], h[H_VV], h[H_VA], h[H_AA]
    h[H_P] += dt * h[H_V] + f02 * h[H_A]
    h[H_V] += f12 * h[H_A]
    h[H_A] *= f22
    # M = F P
    m00 = pp + dt * pv + f02 * pa
    m01 = pv + dt * vv + f02 * va
    m02 = pa + dt * va + f02 * aa
    m11 = vv + f12 * va
    m12 = va + f12 * aa
    # P' = M F' + Q (symmetric: the upper triangle)
    h[H_PP] = m00 + dt * m01 + f02 * m02 + step[4]
    h[H_PV] = m01 + f12 * m02 + step[5]
    h[H_PA] = f22 * m02 + step[6]
    h[H_VV] = m11 + f12 * m12 + step[7]
    h[H_VA] = f22 * m12 + step[8]
    h[H_AA] = f22 * f22 * aa + step[9]


@numba.njit(cache=True)
def _measure(h: FloatArray, of_velocity: bool, y: float, r: float) -> float:
    """Kalman update with ``y``, a measurement of variance ``r`` of the track's position
    (or its velocity); the log-likelihood of ``y``."""
    if of_velocity:
        c0, c1, c2, nu = h[H_PV], h[H_VV], h[H_VA], y - h[H_V]
        s = c1 + r
    else:
        c0, c1, c2, nu = h[H_PP], h[H_PV], h[H_PA], y - h[H_P]
        s = c0 + r
    h[H_P] += c0 * nu / s
    h[H_V] += c1 * nu / s
    h[H_A] += c2 * nu / s
    h[H_PP] -= c0 * c0 / s
    h[H_PV] -= c0 * c1 / s
    h[H_PA] -= c0 * c2 / s
    h[H_VV] -= c1 * c1 / s
    h[H_VA] -= c1 * c2 / s
    h[H_AA] -= c2 * c2 / s
    return float(-0.5 * math.log(2.0 * math.pi * s) - 0.5 * nu * nu / s)


@numba.njit(cache=True)
def _same(a: FloatArray, b: FloatArray) -> bool:
    return bool(
        a[H_MODE] == b[H_MODE]
        and abs(a[H_P] - b[H_P]) < _SAME
        and abs(a[H_O] - b[H_O]) < _SAME
        and abs(a[H_V] - b[H_V]) < _SAME
    )


# ------------------------------------------------------------------ numba kernel


@numba.njit(cache=True)
def _channel_start(p: FloatArray, beam: FloatArray, z: float) -> None:
    """A segment's first fix: one clean hypothesis on it, velocity unknown."""
    beam[0] = 1.0
    h = beam[1 : 1 + N_H]
    h[:] = 0.0
    h[H_P] = z
    h[H_PP] = p[P_SIGMA_M] ** 2
    h[H_VV] = p[P_V0] ** 2
    h[H_AA] = p[P_SIGMA_A] ** 2
    h[H_MODE] = CLEAN


@numba.njit(cache=True)
def _channel_step(
    p: FloatArray,
    beam: FloatArray,
    scratch: FloatArray,
    z: float,
    step: FloatArray,
    v: float,
    log_restart: float,
    repeated: bool,
    res: FloatArray,
) -> None:
    """Advance one channel's beam to the fix ``z`` (``step``: :func:`singer_step`;
    ``v``: reported velocity or NaN;
    ``log_restart``: log of the chance the clean track was wrong, :func:`_log_restart`;
    ``repeated``: the fix repeats the previous one exactly, see :data:`_HELD`); write
    [offset, innovation over its spread, |z - predicted track|, age, evidence, the
    previous fix's offset in the best hypothesis's history] into ``res``. ``scratch``
    (:data:`N_OFFSET_SCRATCH`) holds the children, so a fix allocates nothing."""
    dt = step[0]
    r = p[P_SIGMA_M] ** 2
    rv = p[P_SIGMA_V] ** 2
    log_u = -math.log(2.0 * p[P_SPAN])
    held = math.log(_HELD) if repeated else 0.0  # the fix is a held one, or ...
    live = math.log(1.0 - _HELD) if repeated else 0.0  # ... what it would be anyway
    n = int(beam[0])
    kids = scratch[: _MAX_KIDS * N_H].reshape((_MAX_KIDS, N_H))
    used = scratch[_MAX_KIDS * N_H : _MAX_KIDS * (N_H + 1)]
    kept = scratch[_MAX_KIDS * (N_H + 1) : _MAX_KIDS * (N_H + 1) + BEAM]
    k = 0
    for j in range(n):
        hp = kids[k]  # the parent, predicted: the first child's row until it is copied
        hp[:] = beam[1 + j * N_H : 1 + (j + 1) * N_H]
        _predict(hp, step)
        mode = hp[H_MODE]
        hp[H_PREV] = 0.0 if mode == CLEAN else hp[H_O]  # every child's previous fix
        to_clean, to_keep, to_jump, to_noise = _transitions(p, mode, dt)
        age = hp[H_AGE] + dt if mode != CLEAN else dt
        if j == 0:  # the best hypothesis before this fix
            o = hp[H_O] if mode == JUMP else 0.0
            res[1] = (z - o - hp[H_P]) / math.sqrt(hp[H_PP] + r)
            res[2] = abs(z - hp[H_P])
            # restart: the clean track starts again on the fix, its velocity as
            # uncertain as at a segment's start (a track that was wrong may have
            # been wrong in its velocity too)
            rs = kids[_MAX_KIDS - 1]
            rs[:] = hp
            rs[H_P] = z
            rs[H_A] = 0.0
            rs[H_PP] = r
            rs[H_PV] = 0.0
            rs[H_PA] = 0.0
            rs[H_VV] = max(hp[H_VV], p[P_V0] ** 2)
            rs[H_VA] = 0.0
            rs[H_AA] = p[P_SIGMA_A] ** 2
            rs[H_O] = 0.0
            rs[H_AGE] = 0.0
            rs[H_MODE] = CLEAN
            rs[H_W] = hp[H_W] + live + log_restart + log_u
        first = k
        keep = to_keep > -math.inf
        for c in range(1, 4 if keep else 3):  # copies of the predicted parent
            kids[first + c, :] = hp
        jump = kids[first + (2 if keep else 1)]
        jump[H_O] = z - hp[H_P]
        jump[H_W] += live + to_jump + log_u
        jump[H_AGE] = age
        jump[H_MODE] = JUMP
        noise = kids[first + (3 if keep else 2)]
        noise[H_O] = z - hp[H_P]
        noise[H_W] += (held if repeated else to_noise) + log_u
        noise[H_AGE] = age
        noise[H_MODE] = NOISE
        if keep:  # the jump goes on: z - o measures the track
            on = kids[first + 1]
            on[H_W] += live + to_keep + _measure(on, False, z - on[H_O], r)
            on[H_AGE] = age
        clean = kids[first]  # the fix measures the track
        clean[H_W] += live + to_clean + _measure(clean, False, z, r)
        clean[H_O] = 0.0
        clean[H_AGE] = 0.0
        clean[H_MODE] = CLEAN
        k = first + (4 if keep else 3)
    kids[k, :] = kids[_MAX_KIDS - 1]
    k += 1
    if np.isfinite(v):
        for j in range(k):
            kids[j, H_W] += _measure(kids[j], True, v, rv)
    # The best children in order of weight (the first of equals), duplicates merged,
    # the last _RESERVED places kept for modes not yet among them.
    for j in range(k):
        used[j] = 0.0
    m = 0
    seen_clean = False
    seen_jump = False
    seen_noise = False
    while m < BEAM:
        best = -1
        for j in range(k):
            if used[j] == 0.0 and (best < 0 or kids[j, H_W] > kids[best, H_W]):
                best = j
        if best < 0:
            break
        used[best] = 1.0
        duplicate = False
        for j in range(m):
            if _same(kids[best], kids[int(kept[j])]):
                duplicate = True
                break
        if duplicate:
            continue
        mode = kids[best, H_MODE]
        seen = seen_clean if mode == CLEAN else (seen_jump if mode == JUMP else seen_noise)
        if m < BEAM - _RESERVED or not seen:
            kept[m] = best
            m += 1
            if mode == CLEAN:
                seen_clean = True
            elif mode == JUMP:
                seen_jump = True
            else:
                seen_noise = True
    top = kids[int(kept[0]), H_W]
    best_clean = -math.inf
    beam[0] = float(m)
    for j in range(m):
        h = beam[1 + j * N_H : 1 + (j + 1) * N_H]
        h[:] = kids[int(kept[j])]
        h[H_W] -= top
        if h[H_MODE] == CLEAN and h[H_W] > best_clean:
            best_clean = h[H_W]
    lead = beam[1 : 1 + N_H]
    res[0] = 0.0 if lead[H_MODE] == CLEAN else lead[H_O]
    res[3] = lead[H_AGE]
    res[4] = min(-best_clean, _NO_CLEAN)
    res[5] = lead[H_PREV]


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
    scratch: FloatArray,
) -> None:
    """One point of the tracker: advance ``state`` and write the features into ``out``;
    ``scratch``: :data:`N_OFFSET_SCRATCH` floats of work space (made once per segment)."""
    beam_e = state[_S_BEAM : _S_BEAM + _CHANNEL_STATE]
    beam_n = state[_S_BEAM + _CHANNEL_STATE : _S_BEAM + 2 * _CHANNEL_STATE]
    for k in range(N_OFFSET_FEATURES):
        out[k] = 0.0
    if state[S_COUNT] == 0.0 or not dt > 0.0:
        _channel_start(p, beam_e, east)
        _channel_start(p, beam_n, north)
        state[S_NORM] = 0.0
        state[S_T] = 0.0
    else:
        ve = np.nan
        vn = np.nan
        if np.isfinite(speed) and np.isfinite(heading):
            h = np.radians(heading)
            ve = speed * np.sin(h)
            vn = speed * np.cos(h)
        state[S_T] += dt
        log_restart = _log_restart(p, state[S_T], dt)
        repeated = east == state[S_E] and north == state[S_N]
        e = scratch[_CHILDREN : _CHILDREN + _N_CHANNEL_OUT]
        n = scratch[_CHILDREN + _N_CHANNEL_OUT : _CHILDREN + 2 * _N_CHANNEL_OUT]
        step = scratch[_CHILDREN + 2 * _N_CHANNEL_OUT : N_OFFSET_SCRATCH]
        singer_step(p, dt, step)
        _channel_step(p, beam_e, scratch, east, step, ve, log_restart, repeated, e)
        _channel_step(p, beam_n, scratch, north, step, vn, log_restart, repeated, n)
        out[0] = e[0]
        out[1] = n[0]
        out[2] = np.hypot(e[0], n[0])
        out[3] = out[2] - state[S_NORM]
        out[4] = e[1]
        out[5] = n[1]
        out[6] = np.hypot(e[2], n[2])
        out[7] = max(e[3], n[3])
        out[8] = max(e[4], n[4])
        out[9] = np.hypot(e[5], n[5])
        state[S_NORM] = out[2]
    state[S_COUNT] += 1.0
    state[S_E] = east
    state[S_N] = north


def check_state(state: FloatArray) -> None:
    """Raise ValueError where a stored tracker state would make the compiled step index
    out of bounds (it has no bounds checks): each channel's hypothesis count must be a
    whole number of at most :data:`BEAM` (at least one once a fix has been read), and
    each of its hypotheses' modes clean, jump or outlier."""
    for c, name in enumerate(("east", "north")):
        at = _S_BEAM + c * _CHANNEL_STATE
        n = float(state[at])
        low = 1.0 if state[S_COUNT] > 0 else 0.0
        if not (math.isfinite(n) and n == int(n) and low <= n <= BEAM):
            raise ValueError(f"offset tracker {name} hypotheses = {n!r}, expected {low:g}..{BEAM}")
        for j in range(int(n)):
            mode = float(state[at + 1 + j * N_H + H_MODE])
            if mode not in (CLEAN, JUMP, NOISE):
                raise ValueError(f"offset tracker {name} hypothesis {j} has mode {mode!r}")


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
    scratch = np.zeros(N_OFFSET_SCRATCH)
    out = np.empty((east.size, N_OFFSET_FEATURES))
    for i in range(east.size):
        offset_step(p, state, dt[i], east[i], north[i], speed[i], heading[i], out[i], scratch)
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


# ------------------------------------------------------------------ readable reference


@dataclass
class _Hypothesis:
    x: FloatArray  # track, velocity, acceleration
    cov: FloatArray  # their 3 x 3 covariance
    offset: float
    age: float
    weight: float
    mode: float
    previous: float = 0.0  # the offset it reported at the previous fix (0: clean there)

    def copy(self) -> _Hypothesis:
        return _Hypothesis(
            self.x.copy(),
            self.cov.copy(),
            self.offset,
            self.age,
            self.weight,
            self.mode,
            self.previous,
        )

    @property
    def track(self) -> float:
        return float(self.x[0])

    @property
    def velocity(self) -> float:
        return float(self.x[1])

    def predict(self, f: FloatArray, q: FloatArray) -> None:
        self.x = f @ self.x
        self.cov = f @ self.cov @ f.T + q

    def measure(
        self, y: float, r: float, of_velocity: bool = False, row: FloatArray | None = None
    ) -> float:
        """Kalman update with a measurement ``y`` of the track (or the velocity, or
        ``row @ x`` where ``row`` is given: a state with more entries, as
        ``benchmarks/tried/drift_mode_reference.py`` keeps); its log-likelihood."""
        h = (
            row
            if row is not None
            else np.array([0.0, 1.0, 0.0] if of_velocity else [1.0, 0.0, 0.0])
        )
        s = float(h @ self.cov @ h) + r
        gain = self.cov @ h / s
        nu = y - float(h @ self.x)
        self.x = self.x + gain * nu
        self.cov = self.cov - np.outer(gain, gain) * s
        return -0.5 * math.log(2 * math.pi * s) - 0.5 * nu * nu / s


def _singer_matrices(p: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
    """The transition F and process noise Q of the clean track over ``dt``."""
    step = np.zeros(N_STEP)
    singer_step(p, dt, step)
    f = np.array([[1.0, dt, step[1]], [0.0, 1.0, step[2]], [0.0, 0.0, step[3]]])
    pp, pv, pa, vv, va, aa = step[4:]
    q = np.array([[pp, pv, pa], [pv, vv, va], [pa, va, aa]])
    return f, q


def best_of(
    kids: list[_Hypothesis],
    free: int = BEAM - _RESERVED,
    offset_of: Callable[[_Hypothesis], float] = lambda h: h.offset,
) -> list[_Hypothesis]:
    """The beam's next hypotheses from ``kids`` (the readable reference's selection):
    best first, duplicates (one mode, track, velocity and ``offset_of`` within
    :data:`_SAME`) merged, at most :data:`BEAM`, of which all but ``free`` are kept
    for modes the best ones do not hold; weights made relative to the best."""
    kids.sort(key=lambda h: -h.weight)
    kept: list[_Hypothesis] = []
    seen: set[float] = set()
    for h in kids:
        if any(
            h.mode == o.mode
            and abs(h.track - o.track) < _SAME
            and abs(offset_of(h) - offset_of(o)) < _SAME
            and abs(h.velocity - o.velocity) < _SAME
            for o in kept
        ):
            continue
        if len(kept) < free or h.mode not in seen:
            kept.append(h)
            seen.add(h.mode)
        if len(kept) >= BEAM:
            break
    top = kept[0].weight
    for h in kept:
        h.weight -= top
    return kept


def _reference_channel(
    prm: OffsetParams,
    dt: FloatArray,
    z: FloatArray,
    v: FloatArray,
    repeated: NDArray[np.bool_],
    trace: list[tuple[int, list[_Hypothesis]]] | None = None,
) -> FloatArray:
    """One channel of :func:`offset_features_reference` (columns: offset, innovation over
    its spread, distance to the predicted track, age, evidence, the previous fix's offset
    as revised); ``trace``, where given, receives ``(fix, beam)`` after every fix, the
    hypotheses best first, for reading why the tracker holds an offset
    (``benchmarks/tried/beam_trace_sim.py``)."""
    p = prm.to_array()
    r, rv = prm.sigma_m**2, prm.sigma_v**2
    log_u = -math.log(2 * prm.span_m)
    out = np.zeros((len(z), _N_CHANNEL_OUT))
    beam: list[_Hypothesis] = []
    since_start = 0.0
    for i in range(len(z)):
        if i == 0 or not dt[i] > 0:
            start_cov = np.diag([r, prm.v0_sigma**2, prm.sigma_a**2])
            beam = [_Hypothesis(np.array([z[i], 0.0, 0.0]), start_cov, 0.0, 0.0, 0.0, CLEAN)]
            since_start = 0.0
            continue
        d = float(dt[i])
        since_start += d
        # a fix repeated exactly: held (an outlier) or live, at even odds (_HELD)
        live = math.log(1 - _HELD) if repeated[i] else 0.0
        log_restart = _log_restart(p, since_start, d)  # least certain where it starts
        f, q = _singer_matrices(p, d)
        kids: list[_Hypothesis] = []
        restart = None
        for j, parent in enumerate(beam):
            h = parent.copy()
            h.predict(f, q)
            h.previous = 0.0 if h.mode == CLEAN else h.offset  # what it said at the last fix
            if j == 0:
                o = h.offset if h.mode == JUMP else 0.0
                out[i, 1] = (z[i] - o - h.track) / math.sqrt(h.cov[0, 0] + r)
                out[i, 2] = abs(z[i] - h.track)
                restart = h.copy()
                restart.x = np.array([z[i], h.velocity, 0.0])
                restart.offset, restart.age, restart.mode = 0.0, 0.0, CLEAN
                restart.cov = np.diag([r, max(h.cov[1, 1], prm.v0_sigma**2), prm.sigma_a**2])
                restart.weight += live + log_restart + log_u
            to_clean, to_keep, to_jump, to_noise = _transitions(p, h.mode, d)
            age = h.age + d if h.mode != CLEAN else d
            clean = h.copy()  # the fix measures the track
            clean.weight += live + to_clean + clean.measure(float(z[i]), r)
            clean.offset, clean.age, clean.mode = 0.0, 0.0, CLEAN
            kids.append(clean)
            if to_keep > -math.inf:  # the jump goes on: z - o measures the track
                keep = h.copy()
                keep.weight += live + to_keep + keep.measure(float(z[i]) - h.offset, r)
                keep.age = age
                kids.append(keep)
            for mode, log_p in ((JUMP, to_jump), (NOISE, to_noise)):  # the fix sets o
                fault = h.copy()
                fault.offset, fault.age, fault.mode = float(z[i]) - h.track, age, mode
                held = mode == NOISE and repeated[i]
                fault.weight += (math.log(_HELD) if held else live + log_p) + log_u
                kids.append(fault)
        assert restart is not None
        kids.append(restart)
        if math.isfinite(v[i]):
            for h in kids:
                h.weight += h.measure(float(v[i]), rv, of_velocity=True)
        beam = kept = best_of(kids)
        if trace is not None:
            trace.append((i, kept))  # never changed after: the next fix copies them
        best = beam[0]
        best_clean = max((h.weight for h in beam if h.mode == CLEAN), default=-math.inf)
        out[i, 0] = 0.0 if best.mode == CLEAN else best.offset
        out[i, 3] = best.age
        out[i, 4] = min(-best_clean, _NO_CLEAN)
        out[i, 5] = best.previous
    return out


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
    sp = np.asarray(speed, dtype=np.float64)
    hd = np.asarray(heading, dtype=np.float64)
    rad = np.radians(hd)
    ve, vn = sp * np.sin(rad), sp * np.cos(rad)
    e_arr = np.asarray(east, dtype=np.float64)
    n_arr = np.asarray(north, dtype=np.float64)
    repeated = np.r_[False, (np.diff(e_arr) == 0) & (np.diff(n_arr) == 0)]
    e = _reference_channel(prm, d, e_arr, ve, repeated)
    n = _reference_channel(prm, d, n_arr, vn, repeated)
    out = np.zeros((len(d), N_OFFSET_FEATURES))
    norm_before = 0.0
    for i in range(1, len(d)):
        if not d[i] > 0:  # the track starts again here, as at the first fix
            norm_before = 0.0
            continue
        norm = math.hypot(e[i, 0], n[i, 0])
        out[i] = (
            e[i, 0],
            n[i, 0],
            norm,
            norm - norm_before,
            e[i, 1],
            n[i, 1],
            math.hypot(e[i, 2], n[i, 2]),
            max(e[i, 3], n[i, 3]),
            max(e[i, 4], n[i, 4]),
            math.hypot(e[i, 5], n[i, 5]),
        )
        norm_before = norm
    return out
