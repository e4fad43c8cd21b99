"""Recovery: replace repairable anomalous positions, alert on permanent faults.

The paper replaces transient and intermittent anomalies with the EMA value
and, for permanent ones, leaves the data and sends an alert (an EMA drifts
too far from the truth over a long fault to be trusted). Two estimators:

``ema`` (the paper): the recovered value is REMA's stored EMA of the point.

``velocity`` (better for vehicles): constant-velocity prediction from the
last recovered point, ``rec[t] = rec[t-1] + v * period``, where ``v`` is the
reported speed and heading when both are finite at the point (east =
speed * sin(heading), north = speed * cos(heading)), else an EMA
(``velocity_alpha``) of the velocities of recent normal points. A position EMA
lags a moving car by ``speed * (1 - alpha) / alpha * period`` metres; a
constant-velocity prediction does not.

Both estimators pass permanent points through unchanged with ``alert = 1``.
The velocity state is updated from normal points only, and the last recovered
value (not the faulty one) is what the next prediction starts from, so one
fault does not poison what follows. Errors: :func:`rmse`.

**Reach** (:func:`within_reach`, applied by the GRAD pipeline to the position
it reports, never to the prediction chain above). A prediction is only as good
as the assumption under it: after ``tau`` seconds without a trusted fix the
vehicle may be anywhere within ``reach(tau) = reach_m + reach_accel_mps2 *
tau**2 / 2`` of a constant-velocity prediction (``reach_m``: the fix noise and
velocity error a prediction starts with; ``reach_accel_mps2``: an acceleration
sustained against the prediction: braking, pulling away, turning). A flagged
fix inside that disc is as plausible as the prediction, so it is kept as it
is; one outside it is moved onto the disc's edge, the nearest physically
plausible place. Without it a clean fix flagged during a hard stop was
replaced by dead reckoning at the old speed, up to 100 m from where the car
was (issue 13, Nevada validation drive); with it the repaired position is at
most ``reach(tau)`` from the prediction, so a real fault's repair error is at
most the prediction's own plus ``reach(tau)``, and it is never farther from
the truth than both the fix and the prediction (it lies between them).
``reach_m = reach_accel_mps2 = 0`` gives the plain prediction back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError
from .time_classifier import NONE, PERMANENT

__all__ = [
    "RECOVERY_METHODS",
    "RecoveryParams",
    "recover",
    "recover_reference",
    "recovery_step",
    "rmse",
    "within_reach",
    "within_reach_reference",
]

FloatArray = NDArray[np.float64]
RECOVERY_METHODS = ("ema", "velocity")
# State array: last recovered east, north; velocity east, north (m/s); points seen.
R_E, R_N, R_VE, R_VN, R_COUNT = range(5)
N_RECOVERY_STATE = 5


@dataclass(frozen=True)
class RecoveryParams:
    """``reach_m``, ``reach_accel_mps2``: the reach (module docstring), used by the
    GRAD pipeline only; the defaults are a fix's few metres of noise plus a
    velocity error of a few m/s over the first second, and 3 m/s^2, a firm stop or
    start held against the prediction (checked on the validation drives:
    ``benchmarks/validation_check.py --repair``)."""

    method: str = "velocity"
    velocity_alpha: float = 0.5
    reach_m: float = 5.0
    reach_accel_mps2: float = 3.0

    def reach_array(self) -> FloatArray:
        """``[reach_m, reach_accel_mps2]`` for :func:`within_reach`."""
        for name in ("reach_m", "reach_accel_mps2"):
            value = getattr(self, name)
            if not (value >= 0.0 and np.isfinite(value)):
                raise ConfigError(f"recovery {name} must be a finite number >= 0, got {value}")
        return np.array([self.reach_m, self.reach_accel_mps2])

    def to_array(self) -> FloatArray:
        if self.method not in RECOVERY_METHODS:
            raise ConfigError(
                f"recovery method must be one of {RECOVERY_METHODS}, got {self.method!r}"
            )
        if not 0.0 < self.velocity_alpha <= 1.0:
            raise ConfigError(f"velocity_alpha must be in (0, 1], got {self.velocity_alpha}")
        return np.array([float(RECOVERY_METHODS.index(self.method)), self.velocity_alpha])


@numba.njit(cache=True, error_model="numpy", inline="always")
def recovery_step(
    p: FloatArray,
    state: FloatArray,
    code: int,
    period: float,
    east: float,
    north: float,
    ema_e: float,
    ema_n: float,
    speed: float,
    heading: float,
    out: FloatArray,
) -> None:
    """One point: write (east, north, alert) into ``out`` and advance the state."""
    alert = 0.0
    rec_e = east
    rec_n = north
    if code == NONE:
        if state[R_COUNT] > 0.0:
            va = p[1]
            state[R_VE] = va * (east - state[R_E]) / period + (1.0 - va) * state[R_VE]
            state[R_VN] = va * (north - state[R_N]) / period + (1.0 - va) * state[R_VN]
    elif code == PERMANENT:
        alert = 1.0
    elif p[0] == 0.0:
        rec_e = ema_e
        rec_n = ema_n
    elif state[R_COUNT] > 0.0:
        if np.isfinite(speed) and np.isfinite(heading):
            h = np.radians(heading)
            ve = speed * np.sin(h)
            vn = speed * np.cos(h)
        else:
            ve = state[R_VE]
            vn = state[R_VN]
        rec_e = state[R_E] + ve * period
        rec_n = state[R_N] + vn * period
    state[R_E] = rec_e
    state[R_N] = rec_n
    state[R_COUNT] += 1.0
    out[0] = rec_e
    out[1] = rec_n
    out[2] = alert


@numba.njit(cache=True, error_model="numpy", inline="always")
def within_reach(
    p: FloatArray, tau: float, east: float, north: float, pred_e: float, pred_n: float
) -> tuple[float, float]:
    """The fix ``(east, north)`` if it lies within the reach after ``tau`` s of the
    prediction ``(pred_e, pred_n)``, else the point of the reach's edge nearest to it
    (module docstring; ``p``: :meth:`RecoveryParams.reach_array`)."""
    reach = p[0] + 0.5 * p[1] * tau * tau
    de = east - pred_e
    dn = north - pred_n
    miss = np.sqrt(de * de + dn * dn)
    if not miss > reach:  # inside, or a NaN fix (kept as it is)
        return east, north
    scale = reach / miss
    return pred_e + de * scale, pred_n + dn * scale


def within_reach_reference(
    params: RecoveryParams,
    tau: ArrayLike,
    fix: ArrayLike,
    prediction: ArrayLike,
) -> NDArray[np.float64]:
    """Readable :func:`within_reach` over rows: ``fix`` and ``prediction`` are
    ``(n, 2)`` east/north metres, ``tau`` seconds without a trusted fix per row."""
    r0, accel = params.reach_array()
    z = np.atleast_2d(np.asarray(fix, dtype=np.float64))
    pred = np.atleast_2d(np.asarray(prediction, dtype=np.float64))
    reach = r0 + 0.5 * accel * np.asarray(tau, dtype=np.float64) ** 2
    out = z.copy()
    for i in range(len(z)):
        miss = np.linalg.norm(z[i] - pred[i])
        if miss > reach[i]:
            out[i] = pred[i] + (z[i] - pred[i]) * reach[i] / miss
    return out


@numba.njit(cache=True, error_model="numpy")
def _recover_kernel(
    p: FloatArray,
    codes: NDArray[np.int8],
    period: float,
    east: FloatArray,
    north: FloatArray,
    ema_e: FloatArray,
    ema_n: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
) -> FloatArray:
    out = np.empty((east.size, 3))
    state = np.zeros(N_RECOVERY_STATE)
    for i in range(east.size):
        recovery_step(
            p,
            state,
            codes[i],
            period,
            east[i],
            north[i],
            ema_e[i],
            ema_n[i],
            speed[i],
            heading[i],
            out[i],
        )
    return out


def _arrays(size: int, **named: ArrayLike | None) -> list[FloatArray]:
    out = []
    for name, values in named.items():
        arr = (
            np.full(size, np.nan)
            if values is None
            else np.ascontiguousarray(values, dtype=np.float64)
        )
        if arr.shape != (size,):
            raise ConfigError(
                f"{name} must have one value per point ({size}), got shape {arr.shape}"
            )
        out.append(arr)
    return out


def recover(
    codes: ArrayLike,
    period: float,
    east: ArrayLike,
    north: ArrayLike,
    ema_east: ArrayLike,
    ema_north: ArrayLike,
    params: RecoveryParams | None = None,
    *,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int8]]:
    """Recovered ``(east, north, alert)`` for one segment given per-point time-type codes."""
    c = np.ascontiguousarray(codes, dtype=np.int8)
    e, nn, ee, en, sp, hd = _arrays(
        c.size,
        east=east,
        north=north,
        ema_east=ema_east,
        ema_north=ema_north,
        speed=speed,
        heading=heading,
    )
    rows = _recover_kernel(
        (params or RecoveryParams()).to_array(), c, float(period), e, nn, ee, en, sp, hd
    )
    return rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].astype(np.int8)


def recover_reference(
    codes: ArrayLike,
    period: float,
    east: ArrayLike,
    north: ArrayLike,
    ema_east: ArrayLike,
    ema_north: ArrayLike,
    params: RecoveryParams | None = None,
    *,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int8]]:
    """Readable version of :func:`recover` on 2-vectors, for tests."""
    prm = params or RecoveryParams()
    prm.to_array()
    c = np.asarray(codes)
    pos, ema, sp, hd = (
        np.column_stack(_arrays(c.size, e=east, n=north)),
        np.column_stack(_arrays(c.size, e=ema_east, n=ema_north)),
        *_arrays(c.size, speed=speed, heading=heading),
    )
    rec = pos.copy()
    alert = np.zeros(c.size, dtype=np.int8)
    velocity = np.zeros(2)
    for i in range(c.size):
        if c[i] == NONE:
            if i > 0:
                velocity = (
                    prm.velocity_alpha * (pos[i] - rec[i - 1]) / period
                    + (1 - prm.velocity_alpha) * velocity
                )
        elif c[i] == PERMANENT:
            alert[i] = 1
        elif prm.method == "ema":
            rec[i] = ema[i]
        elif i > 0:
            v = velocity
            if np.isfinite(sp[i]) and np.isfinite(hd[i]):
                v = sp[i] * np.array([np.sin(np.radians(hd[i])), np.cos(np.radians(hd[i]))])
            rec[i] = rec[i - 1] + v * period
    return rec[:, 0], rec[:, 1], alert


def rmse(
    east: ArrayLike,
    north: ArrayLike,
    east_true: ArrayLike,
    north_true: ArrayLike,
    mask: ArrayLike | None = None,
) -> float:
    """Root mean square horizontal error (m), over ``mask`` points when given."""
    de = np.asarray(east, dtype=np.float64) - np.asarray(east_true, dtype=np.float64)
    dn = np.asarray(north, dtype=np.float64) - np.asarray(north_true, dtype=np.float64)
    sq = de * de + dn * dn
    if mask is not None:
        sq = sq[np.asarray(mask, dtype=bool)]
    return float(np.sqrt(sq.mean())) if sq.size else float("nan")
