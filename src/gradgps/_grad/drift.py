"""The drift witness: a slow pull-off (the spoofing take-over) seen against the receiver's velocity.

Why: a spoofer that takes a receiver over drags its position away at a few
m/s, slowly enough that, in the positions alone, the pull-off looks like
ordinary driving (the GRU and the positions-only motion model do not see it,
BENCHMARKS.md "gnss"). A receiver that also reports speed and course (from
Doppler, or a car's wheel odometry beside it) carries an independent
witness: the positions should be the integral of that velocity. A pull-off
makes them disagree by an offset that grows in one direction; ordinary
receiver errors make them disagree by a wandering amount. A GNSS engineer
would test for the first against the second, and this module does.

**Model**, per step between two fixes that both report speed and heading
(clockwise from north, degrees), in the segment's metric frame:

* *residual*: the position step minus the velocity step (trapezoid rule),
  ``r = (p_i - p_{i-1}) - (v_i + v_{i-1}) / 2 * dt``, metres;
* *slow bias*: real receivers' reported speed and course disagree with their
  own position steps steadily (a speed scale error, a course offset): a
  scale ``a`` along the mean velocity and ``c`` across it, learnt as
  exponentially forgotten least squares of the residual rate on the speed
  (time constant ``bias_s``, shrunk towards 0 by ``bias_prior``), and taken
  off the residual;
* *noise*: ``sigma`` (metres per step) ``= sqrt(still**2 + (rel * speed *
  dt)**2)``, floored at ``noise_floor_m``: a receiver's jitter while
  standing, plus a share of the distance driven (course and speed errors
  grow with speed: a noise learnt at a red light must not judge a
  motorway). ``still`` and ``rel`` are running RMS values (time constant
  ``noise_s``, bias-corrected from their first step, priors
  ``noise_prior_m`` and ``noise_prior_rel`` before it) of the change of the
  de-biased residual from one step to the next, which a steady pull-off
  leaves untouched, learnt below and above ``still_mps``;
* *random walk*: what the residuals add up to grows like a random walk of
  step ``sqrt(g0 + 2 g1)`` (metres), with ``g0``, ``g1`` the residual's
  running autocovariances at lags 0 and 1 (time constant ``noise_s``): a
  position error that comes and goes cancels in the sum (``g1 < 0``), a
  velocity error adds up. Each squared value counts at most
  ``noise_clip_sigmas`` squared sigmas, so faults the gate lets through
  cannot inflate the estimates;
* *gate*: a residual longer than ``gate_m + gate_mps * dt + gate_sigmas *
  sigma`` is no pull-off (a jump, a noise fix, a multipath burst, a fix
  frozen while the car moves, the snap back at a pull-off's end: a spoofer
  drags at a few m/s) and restarts the test;
* *test*: a two-dimensional CUSUM of the residuals in the world frame (a
  pull-off keeps its direction while the car turns): ``o <- shrink(o + r,
  k * dt)``, the allowance ``k = allowance_sigmas * random-walk step / dt``
  (clamped to ``allowance_min_mps .. allowance_max_mps``). A drift is
  declared when ``|o|`` reaches ``h = threshold_m + threshold_sigmas *
  sigma`` (the position noise a pull-off must stand out of; the largest
  sigma since ``o`` last stood at 0, so an offset gathered at speed is not
  judged by the noise of the stop that follows) and ends when ``|o|`` falls
  below ``release * h``. Bias and noise learn only while
  ``|o|`` is below ``learn_below * h`` and no drift is declared, so a
  pull-off does not teach the witness to accept it.

Outputs per fix: the flag (1 while a drift is declared) and ``|o|``, the
accumulated offset in metres (what a spoofing user asks: how far off am I?).
A fix without a position, speed or heading is never flagged and carries the
test over without a step (the step around it has no witness). Without speed
and heading columns the witness never fires, so a positions-only file is
unchanged.

:func:`drift_step` (numba) advances one fix; :func:`drift_batch` runs it
over a segment; :func:`drift_reference` is the readable version (tested
equal).
"""

from __future__ import annotations

import math
from dataclasses import astuple, dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from .._exceptions import ConfigError

__all__ = [
    "DRIFT_BIAS",
    "N_DRIFT_OUT",
    "N_DRIFT_PARAMS",
    "N_DRIFT_STATE",
    "DriftParams",
    "drift_batch",
    "drift_reference",
    "drift_step",
]

FloatArray = NDArray[np.float64]

#: The bias type of a fix the witness flags.
DRIFT_BIAS = "drift"

# Parameter layout (DriftParams field order).
(
    P_THRESHOLD_M,
    P_THRESHOLD_SIGMAS,
    P_RELEASE,
    P_ALLOWANCE_SIGMAS,
    P_ALLOWANCE_MIN,
    P_ALLOWANCE_MAX,
    P_GATE_M,
    P_GATE_MPS,
    P_GATE_SIGMAS,
    P_NOISE_S,
    P_NOISE_FLOOR,
    P_NOISE_PRIOR_M,
    P_NOISE_PRIOR_REL,
    P_NOISE_CLIP,
    P_STILL,
    P_BIAS_S,
    P_BIAS_PRIOR,
    P_LEARN_BELOW,
) = range(18)
N_DRIFT_PARAMS = 18

# State layout: all zeros is a fresh segment.
(
    S_HAVE,  # 1 when the previous fix reported a velocity
    S_VE,
    S_VN,  # its velocity, m/s
    S_E,
    S_N,  # its position, m
    S_OE,
    S_ON,  # the CUSUM o, m
    S_ALARM,  # 1 while a drift is declared
    S_SIGMA,  # the largest sigma since o last stood at 0, m (0 before the first step)
    S_HAVE_R,  # 1 when the previous step's residual is kept
    S_RE,
    S_RN,  # that residual, m
    S_STILL,
    S_STILL_W,  # noise standing: forgotten sum of squared changes, and of weights
    S_REL,
    S_REL_W,  # noise driving: the same, per metre driven
    S_G1,
    S_G0,
    S_G_W,  # autocovariances at lags 1 and 0: forgotten sums, and of their weights
    S_SA,
    S_SC,
    S_SS,  # bias: forgotten sums of along*speed, cross*speed, speed**2
) = range(22)
N_DRIFT_STATE = 22

#: Outputs per fix: the flag, the accumulated offset (m).
N_DRIFT_OUT = 2


@dataclass(frozen=True)
class DriftParams:
    """Settings of the drift witness (the model: module docstring).

    ``threshold_m`` + ``threshold_sigmas`` * sigma: the offset (m) that
    declares a drift; ``release``: it ends below this share of that;
    ``allowance_sigmas``: the CUSUM's allowance in random-walk steps,
    clamped to ``allowance_min_mps .. allowance_max_mps`` (m/s); ``gate_m``,
    ``gate_mps``, ``gate_sigmas``: a step residual longer than ``gate_m +
    gate_mps * dt + gate_sigmas * sigma`` restarts the test; ``noise_s``:
    time constant (s) of the noise estimates, ``noise_floor_m`` the smallest
    sigma, ``noise_prior_m`` (standing, m) and ``noise_prior_rel`` (driving,
    per metre) their values before the first measurement,
    ``noise_clip_sigmas``: a squared value counts at most this many sigmas
    squared, ``still_mps``: below this speed the standing noise learns;
    ``bias_s``: time constant (s) of the bias estimate, ``bias_prior``:
    (m/s)**2 of zero-bias evidence it is shrunk with; ``learn_below``: bias
    and noise learn while the CUSUM is below this share of the threshold.

    The defaults were chosen on the validation splits of the shared drives
    with speed and heading (driveplotr, tuc, nevada; docs/deviations.md).
    """

    threshold_m: float = 5.0
    threshold_sigmas: float = 15.0
    release: float = 0.5
    allowance_sigmas: float = 0.5
    allowance_min_mps: float = 0.05
    allowance_max_mps: float = 1.5
    gate_m: float = 1.0
    gate_mps: float = 4.0
    gate_sigmas: float = 5.0
    noise_s: float = 60.0
    noise_floor_m: float = 0.02
    noise_prior_m: float = 0.5
    noise_prior_rel: float = 0.05
    noise_clip_sigmas: float = 3.0
    still_mps: float = 1.0
    bias_s: float = 300.0
    bias_prior: float = 1.0
    learn_below: float = 0.5

    def checked(self) -> DriftParams:
        """``self``, or ``ConfigError`` when a setting is out of range."""
        if not all(math.isfinite(v) and v >= 0.0 for v in astuple(self)):
            raise ConfigError(f"drift settings must be finite and >= 0, got {self}")
        if not (0.0 < self.release <= 1.0 and 0.0 < self.learn_below <= 1.0):
            raise ConfigError("drift release and learn_below must be in (0, 1]")
        if min(self.noise_s, self.bias_s, self.bias_prior, self.noise_floor_m) <= 0.0:
            raise ConfigError("drift noise_s, bias_s, bias_prior and noise_floor_m must be > 0")
        if self.allowance_min_mps > self.allowance_max_mps:
            raise ConfigError("drift allowance_min_mps must not exceed allowance_max_mps")
        return self

    def to_array(self) -> FloatArray:
        return np.array(astuple(self.checked()), dtype=np.float64)


@numba.njit(cache=True)
def _rms(total: float, weight: float, prior: float) -> float:
    """A bias-corrected running RMS: ``prior`` before the first value."""
    return math.sqrt(total / weight) if weight > 0.0 else prior


@numba.njit(cache=True)
def _forget(s: FloatArray, at: int, value: float, w: float) -> None:
    """Exponential forgetting of the sum at ``s[at]`` and its weight at ``s[at + 1]``."""
    s[at] = (1.0 - w) * s[at] + w * value
    s[at + 1] = (1.0 - w) * s[at + 1] + w


@numba.njit(cache=True)
def drift_step(
    p: FloatArray,
    s: FloatArray,
    dt: float,
    east: float,
    north: float,
    speed: float,
    heading: float,
    out: FloatArray,
) -> None:
    """Advance the witness by one fix at ``(east, north)`` m, ``dt`` s after the previous fix
    of its segment, reporting ``speed`` (m/s) and ``heading`` (degrees; NaN: not reported).

    Writes the flag and the accumulated offset (m) into ``out[0:2]``. A fix without a
    finite position, speed or heading is no step.
    """
    reported = (
        np.isfinite(speed) and np.isfinite(heading) and np.isfinite(east) and np.isfinite(north)
    )
    ve = vn = 0.0
    if reported:
        rad = math.radians(heading)
        ve = speed * math.sin(rad)
        vn = speed * math.cos(rad)
    if s[S_HAVE] != 0.0 and reported and dt > 0.0:
        me = 0.5 * (ve + s[S_VE])
        mn = 0.5 * (vn + s[S_VN])
        sp = math.hypot(me, mn)
        still = _rms(s[S_STILL], s[S_STILL_W], p[P_NOISE_PRIOR_M])
        rel = _rms(s[S_REL], s[S_REL_W], p[P_NOISE_PRIOR_REL])
        sigma = max(p[P_NOISE_FLOOR], math.hypot(still, rel * sp * dt))
        if s[S_OE] != 0.0 or s[S_ON] != 0.0:  # judged by the noise the offset grew in
            s[S_SIGMA] = max(s[S_SIGMA], sigma)
        else:
            s[S_SIGMA] = sigma
        level = p[P_THRESHOLD_M] + p[P_THRESHOLD_SIGMAS] * s[S_SIGMA]
        re = (east - s[S_E]) / dt - me  # residual rate, m/s
        rn = (north - s[S_N]) / dt - mn
        fit_a = fit_c = 0.0
        if sp > 0.0:
            ue = me / sp
            un = mn / sp
            fit_a = re * ue + rn * un  # along the motion
            fit_c = re * un - rn * ue  # to its right
            along = fit_a - s[S_SA] / (s[S_SS] + p[P_BIAS_PRIOR]) * sp
            cross = fit_c - s[S_SC] / (s[S_SS] + p[P_BIAS_PRIOR]) * sp
            re = along * ue + cross * un
            rn = along * un - cross * ue
        ee = re * dt
        en = rn * dt
        if math.hypot(ee, en) > p[P_GATE_M] + p[P_GATE_MPS] * dt + p[P_GATE_SIGMAS] * sigma:
            s[S_OE] = s[S_ON] = 0.0
            s[S_HAVE_R] = 0.0
        else:
            if s[S_ALARM] == 0.0 and math.hypot(s[S_OE], s[S_ON]) < p[P_LEARN_BELOW] * level:
                w = min(1.0, dt / p[P_NOISE_S])
                if s[S_HAVE_R] != 0.0:
                    cap = (p[P_NOISE_CLIP] * sigma) ** 2
                    change = min(0.5 * ((ee - s[S_RE]) ** 2 + (en - s[S_RN]) ** 2), cap)
                    if sp < p[P_STILL]:
                        _forget(s, S_STILL, change, w)
                    else:
                        _forget(s, S_REL, change / (sp * dt) ** 2, w)
                    g0 = min(ee * ee + en * en, cap)
                    g1 = max(-g0, min(g0, ee * s[S_RE] + en * s[S_RN]))
                    s[S_G1] = (1.0 - w) * s[S_G1] + w * g1
                    _forget(s, S_G0, g0, w)
                w = min(1.0, dt / p[P_BIAS_S])
                s[S_SA] = (1.0 - w) * s[S_SA] + w * fit_a * sp
                s[S_SC] = (1.0 - w) * s[S_SC] + w * fit_c * sp
                s[S_SS] = (1.0 - w) * s[S_SS] + w * sp * sp
            s[S_HAVE_R] = 1.0
            s[S_RE] = ee
            s[S_RN] = en
            walk = sigma * sigma
            if s[S_G_W] > 0.0:
                walk = max(0.0, (s[S_G0] + 2.0 * s[S_G1]) / s[S_G_W])
            allowance = p[P_ALLOWANCE_SIGMAS] * math.sqrt(walk) / dt
            allowance = min(p[P_ALLOWANCE_MAX], max(p[P_ALLOWANCE_MIN], allowance)) * dt
            oe = s[S_OE] + ee
            on = s[S_ON] + en
            size = math.hypot(oe, on)
            shrink = (size - allowance) / size if size > allowance else 0.0
            s[S_OE] = oe * shrink
            s[S_ON] = on * shrink
    if reported:
        s[S_HAVE] = 1.0
        s[S_VE] = ve
        s[S_VN] = vn
        s[S_E] = east
        s[S_N] = north
    else:
        s[S_HAVE] = 0.0
        s[S_HAVE_R] = 0.0
    offset = math.hypot(s[S_OE], s[S_ON])
    level = p[P_THRESHOLD_M] + p[P_THRESHOLD_SIGMAS] * s[S_SIGMA]
    if offset >= level:
        s[S_ALARM] = 1.0
    elif offset < p[P_RELEASE] * level:
        s[S_ALARM] = 0.0
    out[0] = s[S_ALARM]
    out[1] = offset


@numba.njit(cache=True)
def _drift_loop(
    p: FloatArray,
    dt: FloatArray,
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
) -> FloatArray:
    s = np.zeros(N_DRIFT_STATE)
    out = np.empty((east.size, N_DRIFT_OUT))
    for i in range(east.size):
        drift_step(p, s, dt[i], east[i], north[i], speed[i], heading[i], out[i])
    return out


def drift_batch(
    t: FloatArray,
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    params: DriftParams | None = None,
) -> FloatArray:
    """:func:`drift_step` over one segment from a fresh state: ``(n, 2)`` flag, offset (m)."""
    p = (params or DriftParams()).to_array()
    times = np.asarray(t, np.float64)
    dt = np.r_[0.0, np.diff(times)] if times.size else np.zeros(0)
    e, n, v, h = (np.asarray(a, np.float64) for a in (east, north, speed, heading))
    return np.asarray(_drift_loop(p, dt, e, n, v, h))


class _RunningMean:
    """A bias-corrected exponentially forgotten mean (the reference's noise estimates)."""

    def __init__(self) -> None:
        self.total = self.weight = 0.0

    def known(self) -> bool:
        return self.weight > 0.0

    def mean(self) -> float:
        return self.total / self.weight

    def add(self, value: float, w: float) -> None:
        self.total = (1 - w) * self.total + w * value
        self.weight = (1 - w) * self.weight + w


def drift_reference(
    t: FloatArray,
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    params: DriftParams | None = None,
) -> FloatArray:
    """Readable version of :func:`drift_batch`: the model of the module docstring in plain
    Python with 2-vectors."""
    prm = (params or DriftParams()).checked()
    rows = []
    prev: tuple[float, np.ndarray, np.ndarray] | None = None  # time, position, velocity
    cusum = np.zeros(2)  # o, metres
    last: np.ndarray | None = None  # the previous step's residual, while kept
    alarm = False
    peak = 0.0  # the largest noise since the CUSUM last stood at 0
    still, rel = _RunningMean(), _RunningMean()  # squared changes: standing, per metre
    lag0, lag1 = _RunningMean(), _RunningMean()  # residual autocovariances
    bias_along = bias_cross = speed_sq = 0.0  # forgotten sums of the bias fit
    for i in range(len(t)):
        pos = np.array([east[i], north[i]])
        vel = None
        if all(math.isfinite(v) for v in (speed[i], heading[i], east[i], north[i])):
            course = math.radians(heading[i])
            vel = speed[i] * np.array([math.sin(course), math.cos(course)])
        if prev is not None and vel is not None and t[i] - prev[0] > 0.0:
            dt = t[i] - prev[0]
            mean_v = 0.5 * (vel + prev[2])
            sp = float(np.hypot(*mean_v))
            standing = math.sqrt(still.mean()) if still.known() else prm.noise_prior_m
            driving = math.sqrt(rel.mean()) if rel.known() else prm.noise_prior_rel
            sigma = max(prm.noise_floor_m, math.hypot(standing, driving * sp * dt))
            peak = max(peak, sigma) if cusum.any() else sigma
            threshold = prm.threshold_m + prm.threshold_sigmas * peak
            rate = (pos - prev[1]) / dt - mean_v  # the residual rate, m/s
            fit = (0.0, 0.0)
            if sp > 0.0:
                ahead = mean_v / sp
                right = np.array([ahead[1], -ahead[0]])
                fit = (float(rate @ ahead), float(rate @ right))
                scale = sp / (speed_sq + prm.bias_prior)
                rate = (fit[0] - bias_along * scale) * ahead + (fit[1] - bias_cross * scale) * right
            residual = rate * dt
            if np.hypot(*residual) > prm.gate_m + prm.gate_mps * dt + prm.gate_sigmas * sigma:
                cusum, last = np.zeros(2), None  # no pull-off: restart the test
            else:
                if not alarm and np.hypot(*cusum) < prm.learn_below * threshold:
                    w = min(1.0, dt / prm.noise_s)
                    if last is not None:
                        cap = (prm.noise_clip_sigmas * sigma) ** 2
                        change = min(float(np.sum((residual - last) ** 2)) / 2.0, cap)
                        if sp < prm.still_mps:
                            still.add(change, w)
                        else:
                            rel.add(change / (sp * dt) ** 2, w)
                        g0 = min(float(residual @ residual), cap)
                        lag1.add(max(-g0, min(g0, float(residual @ last))), w)
                        lag0.add(g0, w)
                    w = min(1.0, dt / prm.bias_s)
                    bias_along = (1 - w) * bias_along + w * fit[0] * sp
                    bias_cross = (1 - w) * bias_cross + w * fit[1] * sp
                    speed_sq = (1 - w) * speed_sq + w * sp * sp
                last = residual
                walk = max(0.0, lag0.mean() + 2.0 * lag1.mean()) if lag0.known() else sigma**2
                allowance = prm.allowance_sigmas * math.sqrt(walk) / dt
                allowance = min(prm.allowance_max_mps, max(prm.allowance_min_mps, allowance)) * dt
                cusum = cusum + residual
                size = float(np.hypot(*cusum))
                cusum = cusum * ((size - allowance) / size if size > allowance else 0.0)
        if vel is None:
            prev, last = None, None
        else:
            prev = (float(t[i]), pos, vel)
        offset = float(np.hypot(*cusum))
        threshold = prm.threshold_m + prm.threshold_sigmas * peak
        if offset >= threshold:
            alarm = True
        elif offset < prm.release * threshold:
            alarm = False
        rows.append((1.0 if alarm else 0.0, offset))
    return np.array(rows, dtype=np.float64).reshape(-1, N_DRIFT_OUT)
