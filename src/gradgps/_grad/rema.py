"""Reinforced EMA (REMA, paper Algorithm 1): a per-channel outlier detector.

REMA keeps an exponential moving average of one scalar channel (east or north
metres of a segment, or any sensor channel), predicts the next value from it,
draws bounds from how much the EMA itself has moved lately, and flags a value
outside the bounds. On an outlier the smoothing factor ``alpha`` is *punished*
(new data weighs less) and the EMA is reset to the mean of recent EMA values;
on a normal value ``alpha`` is *rewarded*.

Two modes, one kernel:

``paper`` -- Algorithm 1, literally. At point ``t`` (``ss`` = slide_size)::

    p      = mean(ema[t-ss], ema[t-ss//2], ema[t-ss//3])
    ema[t] = a * fed[t-1] + (1 - a) * p
    thr    = std(ema[t-ss : t-1])           # ss-1 values, ddof=0, Python slice
    margin = max(thr * sensitivity, min_margin)
    flag   = x[t] < ema[t] - margin or x[t] > ema[t] + margin
    if flag: ema[t] = mean(ema[t-ss : t-1]); a = max(a - punish, alpha_min)
    else:    a = min(a + reward, alpha_max)

  Choices where the paper is silent (tested in tests/test_rema.py):

  * *Warm-up*: the first ``ss`` points are never flagged and have NaN bounds;
    ``ema[0] = x[0]`` and ``ema[t] = a * x[t-1] + (1 - a) * ema[t-1]`` for
    ``0 < t < ss`` (plain EMA, alpha unchanged), so that every index the
    algorithm reads exists when checking starts at ``t = ss``.
  * *Value fed to the next EMA after an outlier* (``fed[t]``): the algorithm
    writes ``data[t-1]``, i.e. the raw value, outlier or not; ``paper`` mode
    does exactly that and relies on the punished ``alpha`` to damp it.
  * *Scale*: bounds are in channel units (metres for positions), no
    normalisation. ``min_margin`` (channel units, default 0 = the paper) floors
    the half-width: without it a stopped car, whose EMA has ~zero std, flags
    every fix that moves by a millimetre.
  * ``distance`` is ``|x[t] - ema[t]|`` with the *predicted* EMA (the centre of
    the bounds), so ``flag == (distance > margin)``; the emitted ``ema`` is the
    stored one (after the reset on an outlier), which is what recovery uses.

``trend`` -- a translation-invariant variant for positions of a moving
vehicle. A raw EMA of a position lags a car at 15 m/s by metres every second,
and the std of a moving EMA grows with speed, so ``paper`` bounds are wide
when moving and ~0 when stopped. ``trend`` applies the same reinforced EMA to
the *step* and predicts from ``level``, the last accepted (or, during a fault,
dead-reckoned) value. ``known`` is the step expected from an independent
source -- the reported speed and heading times the period -- or 0 where there
is none; the EMA then follows the *residual* step (step minus ``known``), a
bias such as a lagging heading, or the whole step without speed/heading::

    pred   = level + known + step_ema
    thr    = std(last ss accepted residual steps)
    base   = max(thr * sensitivity, min_margin)
    margin = base + run_growth * run
    flag   = |x[t] - pred| > margin,  unless re-acquired (below)
    if flag: level = pred (dead reckoning); a punished; run += 1
    else:    residual = x[t] - level - known
             step_ema = a * residual + (1 - a) * step_ema; level = x[t];
             a rewarded; run = 0

  ``run`` counts consecutive outliers; ``run_growth`` (channel units per
  outlier, default 0) widens the bounds as dead reckoning drifts.
  **Re-acquisition** (``reacquire_after`` = K > 0): a lasting shift of the
  whole track (the truth moved, or the anchor was the bad value) would
  otherwise be flagged forever, but growing bounds alone also accept
  single noisy values inside a long noise fault and then lose the track.
  So a flagged point whose own step from the previous *observed* value is
  as expected (``|x[t] - x[t-1] - known - step_ema| <= base``) counts as
  consistent; the K-th consistent flagged point in a row is accepted
  (``level = x[t]``, its residual is its own step, not the jump). Noise
  faults (independent offsets per point) almost never move consistently K
  times. **Bounded dead reckoning** (``max_run`` = M > 0): after M flagged
  points in a row the next point is accepted the same way whatever it does,
  so no input can keep REMA away from the fixes for longer than M points
  (dead reckoning drifts; after M points the fix is the better guess, and
  the memory of a lasting fault is the offset tracker's job). Warm-up: the first ``ss`` points are accepted unchecked
  (``step_ema`` starts at the first residual).

  Measured: docs/rema.md (benchmark ``grad`` on driveplotr and tuc test,
  tuned on validation with ``gradgps tune-rema``).

Implementation: :func:`rema_step` (numba) advances one point given the state
in two small arrays, so a whole pipeline can call it from one compiled loop;
:func:`rema_batch` runs it over an array; :class:`Rema` is the streaming
object. :func:`rema_reference` is the readable full-array version used in
tests.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError

__all__ = [
    "REMA_MODES",
    "Rema",
    "RemaOutput",
    "RemaParams",
    "rema_batch",
    "rema_reference",
    "rema_step",
]

FloatArray = NDArray[np.float64]

REMA_MODES = ("paper", "trend")

# Layout of the parameter array handed to the kernels.
(
    P_ALPHA,
    P_ALPHA_MIN,
    P_ALPHA_MAX,
    P_PUNISH,
    P_REWARD,
    P_SS,
    P_SENS,
    P_MIN_MARGIN,
    P_MODE,
    P_RUN_GROWTH,
    P_REACQUIRE,
    P_MAX_RUN,
) = range(12)
N_PARAMS = 12
# Layout of the scalar state array: alpha, points seen, last fed value (paper)
# or level (trend), step EMA, consecutive outliers and accepted steps (trend).
# Trend mode also keeps the previous observed value and how many flagged
# points in a row moved consistently from their predecessor.
S_ALPHA, S_COUNT, S_LAST, S_STEP, S_RUN, S_NSTEPS, S_PREV, S_CONSISTENT = range(8)
N_STATE = 8
# Layout of one output row.
O_FLAG, O_EMA, O_LOWER, O_UPPER, O_DISTANCE, O_ALPHA = range(6)
N_OUT = 6


@dataclass(frozen=True)
class RemaParams:
    """REMA hyper-parameters (paper names); ``min_margin`` in channel units.

    ``slide_size`` is in points. :meth:`checked` validates and returns self.
    """

    alpha: float = 0.5
    alpha_min: float = 0.1
    alpha_max: float = 0.9
    punish: float = 0.1
    reward: float = 0.05
    slide_size: int = 10
    sensitivity: float = 3.0
    min_margin: float = 0.0
    mode: str = "paper"
    run_growth: float = 0.0
    reacquire_after: int = 0
    max_run: int = 0

    def checked(self) -> RemaParams:
        if self.mode not in REMA_MODES:
            raise ConfigError(f"REMA mode must be one of {REMA_MODES}, got {self.mode!r}")
        if not 0.0 < self.alpha_min <= self.alpha <= self.alpha_max <= 1.0:
            raise ConfigError(
                "REMA needs 0 < alpha_min <= alpha <= alpha_max <= 1, got "
                f"alpha_min={self.alpha_min}, alpha={self.alpha}, alpha_max={self.alpha_max}"
            )
        if self.punish < 0 or self.reward < 0:
            raise ConfigError(f"punish and reward must be >= 0, got {self.punish}, {self.reward}")
        if int(self.slide_size) != self.slide_size or self.slide_size < 3:
            raise ConfigError(f"slide_size must be an integer >= 3 (points), got {self.slide_size}")
        if not (self.sensitivity > 0 and np.isfinite(self.sensitivity)):
            raise ConfigError(f"sensitivity must be a positive number, got {self.sensitivity}")
        if not (self.min_margin >= 0 and np.isfinite(self.min_margin)):
            raise ConfigError(f"min_margin must be >= 0 (channel units), got {self.min_margin}")
        if not (self.run_growth >= 0 and np.isfinite(self.run_growth)):
            raise ConfigError(
                f"run_growth must be >= 0 (channel units per point), got {self.run_growth}"
            )
        if int(self.max_run) != self.max_run or self.max_run < 0:
            raise ConfigError(
                f"max_run must be an integer >= 0 (points; 0 = unbounded), got {self.max_run}"
            )
        if int(self.reacquire_after) != self.reacquire_after or self.reacquire_after < 0:
            raise ConfigError(
                f"reacquire_after must be an integer >= 0 (points; 0 = never), "
                f"got {self.reacquire_after}"
            )
        return self

    def to_array(self) -> FloatArray:
        """The parameters as the float64 array the kernels take."""
        self.checked()
        return np.array(
            [
                self.alpha,
                self.alpha_min,
                self.alpha_max,
                self.punish,
                self.reward,
                float(self.slide_size),
                self.sensitivity,
                self.min_margin,
                float(REMA_MODES.index(self.mode)),
                self.run_growth,
                float(self.reacquire_after),
                float(self.max_run),
            ],
            dtype=np.float64,
        )

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> RemaParams:
        """Parse :meth:`to_json` output; unknown or missing keys are a ConfigError."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ConfigError(f"REMA parameters are not valid JSON: {exc}") from exc
        return cls.from_dict(data)

    @classmethod
    def from_dict(cls, data: Any) -> RemaParams:
        names = {f.name for f in fields(cls)}
        if not isinstance(data, dict) or set(data) - names:
            extra = sorted(set(data) - names) if isinstance(data, dict) else data
            raise ConfigError(f"unknown REMA parameters {extra}; expected keys {sorted(names)}")
        values = dict(data)
        for key in ("slide_size", "reacquire_after", "max_run"):
            if key in values:
                values[key] = int(values[key])
        return cls(**values).checked()


class RemaOutput(NamedTuple):
    """Per-point REMA results; bounds are NaN during the warm-up."""

    flag: NDArray[np.int8]
    ema: FloatArray
    lower: FloatArray
    upper: FloatArray
    distance: FloatArray
    alpha: FloatArray


@numba.njit(cache=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _window_mean_std(ring: FloatArray, start: int, count: int) -> tuple[float, float]:
    """Mean and population std of ``count`` ring values from absolute index ``start``.

    Two passes (no cancellation), each over the at most two contiguous pieces
    of the ring, so the loops carry no modulo or wrap-around branch.
    """
    size = ring.size
    first = start % size
    head = min(count, size - first)
    tail = count - head
    total = 0.0
    for i in range(first, first + head):
        total += ring[i]
    for i in range(tail):
        total += ring[i]
    mean = total / count
    sq = 0.0
    for i in range(first, first + head):
        d = ring[i] - mean
        sq += d * d
    for i in range(tail):
        d = ring[i] - mean
        sq += d * d
    return mean, np.sqrt(sq / count)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _push_step(state: FloatArray, ring: FloatArray, step: float) -> None:
    """Trend mode: append an accepted step to the ring (indexed by accepted-step count)."""
    n_steps = int(state[S_NSTEPS])
    ring[n_steps % ring.size] = step
    state[S_NSTEPS] = n_steps + 1


@numba.njit(cache=True, error_model="numpy")
def rema_new_state(p: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Fresh (scalar state, ring) arrays for parameters ``p``."""
    state = np.zeros(N_STATE)
    state[S_ALPHA] = p[P_ALPHA]
    return state, np.zeros(int(p[P_SS]))


@numba.njit(cache=True, error_model="numpy", inline="always")
def rema_step(
    p: FloatArray, state: FloatArray, ring: FloatArray, x: float, known_step: float, out: FloatArray
) -> None:
    """Advance REMA by one value ``x``; write one output row into ``out`` (see module doc).

    ``known_step`` is the step expected from an independent source (reported
    speed and heading times the period, channel units), NaN when there is none;
    only ``trend`` mode uses it. ``ring`` (length slide_size) holds the last ss
    EMA values (paper) or the last ss accepted step residuals (trend); the
    absolute index of point ``t`` is ``t % ss`` (paper) or the accepted-step
    count modulo ss (trend).
    """
    ss = int(p[P_SS])
    t = int(state[S_COUNT])
    a = state[S_ALPHA]
    paper = p[P_MODE] == 0.0
    nan = np.nan
    flag = 0.0
    lower = nan
    upper = nan
    if paper:
        if t == 0:
            ema = x
            distance = 0.0
        elif t < ss:
            ema = a * state[S_LAST] + (1.0 - a) * ring[(t - 1) % ss]
            distance = abs(x - ema)
        else:
            pred = (ring[(t - ss) % ss] + ring[(t - ss // 2) % ss] + ring[(t - ss // 3) % ss]) / 3.0
            ema = a * state[S_LAST] + (1.0 - a) * pred
            recent_mean, thr = _window_mean_std(ring, t - ss, ss - 1)
            margin = max(thr * p[P_SENS], p[P_MIN_MARGIN])
            lower = ema - margin
            upper = ema + margin
            distance = abs(x - ema)
            if x < lower or x > upper:
                flag = 1.0
                ema = recent_mean
                a = max(a - p[P_PUNISH], p[P_ALPHA_MIN])
            else:
                a = min(a + p[P_REWARD], p[P_ALPHA_MAX])
        ring[t % ss] = ema
        state[S_LAST] = x
    else:
        base_step = known_step if np.isfinite(known_step) else 0.0
        if t == 0:
            ema = x
            distance = 0.0
            state[S_LAST] = x
        elif t < ss:
            residual = x - state[S_LAST] - base_step
            state[S_STEP] = residual if t == 1 else a * residual + (1.0 - a) * state[S_STEP]
            ema = x
            distance = 0.0
            _push_step(state, ring, residual)
            state[S_LAST] = x
        else:
            ema = state[S_LAST] + base_step + state[S_STEP]
            n_steps = int(state[S_NSTEPS])
            count = min(n_steps, ss)
            _, thr = _window_mean_std(ring, n_steps - count, count)
            base = max(thr * p[P_SENS], p[P_MIN_MARGIN])
            margin = base + p[P_RUN_GROWTH] * state[S_RUN]
            lower = ema - margin
            upper = ema + margin
            distance = abs(x - ema)
            outside = x < lower or x > upper
            own_step = x - state[S_PREV] - base_step
            if outside and state[S_RUN] > 0.0 and abs(own_step - state[S_STEP]) <= base:
                state[S_CONSISTENT] += 1.0
            else:
                state[S_CONSISTENT] = 0.0
            reacquire = (p[P_REACQUIRE] > 0.0 and state[S_CONSISTENT] >= p[P_REACQUIRE]) or (
                p[P_MAX_RUN] > 0.0 and state[S_RUN] >= p[P_MAX_RUN]
            )
            if outside and not reacquire:
                flag = 1.0
                state[S_LAST] = ema
                state[S_RUN] += 1.0
                a = max(a - p[P_PUNISH], p[P_ALPHA_MIN])
            else:
                # On re-acquisition the step is the track's own, not the jump to it.
                residual = own_step if outside else x - state[S_LAST] - base_step
                state[S_CONSISTENT] = 0.0
                state[S_STEP] = a * residual + (1.0 - a) * state[S_STEP]
                _push_step(state, ring, residual)
                state[S_LAST] = x
                state[S_RUN] = 0.0
                a = min(a + p[P_REWARD], p[P_ALPHA_MAX])
    state[S_PREV] = x
    state[S_ALPHA] = a
    state[S_COUNT] = t + 1
    out[O_FLAG] = flag
    out[O_EMA] = ema
    out[O_LOWER] = lower
    out[O_UPPER] = upper
    out[O_DISTANCE] = distance
    out[O_ALPHA] = a


@numba.njit(cache=True, error_model="numpy")
def rema_batch_kernel(p: FloatArray, x: FloatArray, known_step: FloatArray) -> FloatArray:
    """REMA over a whole array from a fresh state; (n, 6) output rows."""
    state, ring = rema_new_state(p)
    out = np.empty((x.size, N_OUT))
    for i in range(x.size):
        rema_step(p, state, ring, x[i], known_step[i], out[i])
    return out


def _split(rows: FloatArray) -> RemaOutput:
    return RemaOutput(
        flag=rows[:, O_FLAG].astype(np.int8),
        ema=rows[:, O_EMA].copy(),
        lower=rows[:, O_LOWER].copy(),
        upper=rows[:, O_UPPER].copy(),
        distance=rows[:, O_DISTANCE].copy(),
        alpha=rows[:, O_ALPHA].copy(),
    )


def _known_steps(values: FloatArray, known_step: ArrayLike | None) -> FloatArray:
    if values.ndim != 1:
        raise ConfigError(f"REMA takes one channel as a 1-D array, got shape {values.shape}")
    if known_step is None:
        return np.full(values.size, np.nan)
    steps = np.ascontiguousarray(known_step, dtype=np.float64)
    if steps.shape != values.shape:
        raise ConfigError(
            f"known_step must have one value per point ({values.size}), got shape {steps.shape}"
        )
    return steps


def rema_batch(
    x: ArrayLike, params: RemaParams | None = None, known_step: ArrayLike | None = None
) -> RemaOutput:
    """REMA over one channel of one segment (compiled kernel).

    ``known_step``: optional expected step per point from speed and heading
    (channel units, NaN where unknown); used by ``trend`` mode only.
    """
    values = np.ascontiguousarray(x, dtype=np.float64)
    steps = _known_steps(values, known_step)
    return _split(rema_batch_kernel((params or RemaParams()).to_array(), values, steps))


def rema_reference(
    x: ArrayLike, params: RemaParams | None = None, known_step: ArrayLike | None = None
) -> RemaOutput:
    """Readable full-array REMA, written from the algorithm text; tests compare the kernel to it."""
    prm = (params or RemaParams()).checked()
    x = np.asarray(x, dtype=np.float64)
    base_steps = np.nan_to_num(_known_steps(x, known_step), nan=0.0)
    n, ss, a = x.size, prm.slide_size, prm.alpha
    flag = np.zeros(n, dtype=np.int8)
    ema = np.zeros(n)
    lower = np.full(n, np.nan)
    upper = np.full(n, np.nan)
    distance = np.zeros(n)
    alphas = np.zeros(n)
    if prm.mode == "paper":
        for t in range(n):
            if t == 0:
                ema[t] = x[0]
            elif t < ss:
                ema[t] = a * x[t - 1] + (1 - a) * ema[t - 1]
                distance[t] = abs(x[t] - ema[t])
            else:
                p_value = np.mean([ema[t - ss // i] for i in (1, 2, 3)])
                ema[t] = a * x[t - 1] + (1 - a) * p_value
                margin = max(float(np.std(ema[t - ss : t - 1])) * prm.sensitivity, prm.min_margin)
                lower[t], upper[t] = ema[t] - margin, ema[t] + margin
                distance[t] = abs(x[t] - ema[t])
                if x[t] < lower[t] or x[t] > upper[t]:
                    flag[t] = 1
                    ema[t] = np.mean(ema[t - ss : t - 1])
                    a = max(a - prm.punish, prm.alpha_min)
                else:
                    a = min(a + prm.reward, prm.alpha_max)
            alphas[t] = a
        return RemaOutput(flag, ema, lower, upper, distance, alphas)
    level = 0.0
    step_ema = 0.0
    residuals: list[float] = []  # accepted step minus known step, newest last
    run = 0
    consistent = 0  # flagged points in a row that moved consistently from the one before
    for t in range(n):
        if t < ss:
            if t > 0:
                residual = x[t] - level - base_steps[t]
                step_ema = residual if t == 1 else a * residual + (1 - a) * step_ema
                residuals.append(residual)
            level = ema[t] = x[t]
        else:
            ema[t] = level + base_steps[t] + step_ema
            base = float(np.std(residuals[-ss:])) * prm.sensitivity
            margin = max(base, prm.min_margin) + prm.run_growth * run
            lower[t], upper[t] = ema[t] - margin, ema[t] + margin
            distance[t] = abs(x[t] - ema[t])
            outside = abs(x[t] - ema[t]) > margin
            own_step = x[t] - x[t - 1] - base_steps[t]
            moved_as_expected = abs(own_step - step_ema) <= max(base, prm.min_margin)
            consistent = consistent + 1 if outside and run > 0 and moved_as_expected else 0
            forced = prm.max_run > 0 and run >= prm.max_run
            if outside and not (
                (prm.reacquire_after > 0 and consistent >= prm.reacquire_after) or forced
            ):
                flag[t] = 1
                level = ema[t]
                run += 1
                a = max(a - prm.punish, prm.alpha_min)
            else:
                residual = own_step if outside else x[t] - level - base_steps[t]
                consistent = 0
                step_ema = a * residual + (1 - a) * step_ema
                residuals.append(residual)
                level = x[t]
                run = 0
                a = min(a + prm.reward, prm.alpha_max)
        alphas[t] = a
    return RemaOutput(flag, ema, lower, upper, distance, alphas)


class Rema:
    """Streaming REMA on one channel, river style: ``update(x)`` per value.

    State is two small float arrays (built here, advanced by the compiled
    :func:`rema_step`); :meth:`get_state` / :meth:`set_state` move it as plain
    JSON-able data, so a stream can be paused and resumed anywhere.
    """

    def __init__(self, params: RemaParams | None = None) -> None:
        self.params = (params or RemaParams()).checked()
        self._p = self.params.to_array()
        self._state, self._ring = rema_new_state(self._p)
        self._out = np.zeros(N_OUT)

    def update(
        self, x: float, known_step: float = np.nan
    ) -> tuple[int, float, float, float, float, float]:
        """Feed one value (and optionally its expected step); return ``(flag, ema, lower, upper, distance, alpha)``."""
        rema_step(self._p, self._state, self._ring, float(x), float(known_step), self._out)
        o = self._out
        return (
            int(o[O_FLAG]),
            float(o[O_EMA]),
            float(o[O_LOWER]),
            float(o[O_UPPER]),
            float(o[O_DISTANCE]),
            float(o[O_ALPHA]),
        )

    def get_state(self) -> dict[str, Any]:
        return {
            "params": asdict(self.params),
            "state": self._state.tolist(),
            "ring": self._ring.tolist(),
        }

    def set_state(self, state: dict[str, Any]) -> Rema:
        params = RemaParams.from_dict(state["params"])
        scalars = np.asarray(state["state"], dtype=np.float64)
        ring = np.asarray(state["ring"], dtype=np.float64)
        if scalars.shape != (N_STATE,) or ring.shape != (params.slide_size,):
            raise ConfigError(
                f"REMA state has shapes {scalars.shape} and {ring.shape}, expected "
                f"({N_STATE},) and ({params.slide_size},): it was saved by another version"
            )
        self.params, self._p = params, params.to_array()
        self._state, self._ring = scalars.copy(), ring.copy()
        return self
