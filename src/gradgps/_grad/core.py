"""REMA + MS-SW features + time classifier + recovery in one compiled step per point.

This is the statistical half of GRAD as one loop body, :func:`core_step`, so
that a full streaming pipeline (later with a GRU) runs one compiled call per
point. To keep the per-call cost low, everything lives in *two* flat float64
arrays: ``P`` (parameters) and ``S`` (state), laid out by :func:`_layout`;
the kernel takes slices of them (free in numba) and hands them to the
per-piece kernels of :mod:`gradgps._grad.rema`, :mod:`gradgps._grad.features`,
:mod:`gradgps._grad.time_classifier` and :mod:`gradgps._grad.recovery`, each of which
has its own readable reference and tests.

Per point: REMA on east and north -> the point is anomalous if either channel
flags -> time type -> recovery -> (optional, default on) the recovered
position is written back into both REMA states as the value the next
prediction starts from, so one fault does not poison the points after it.
Features are computed from the *observed* positions (a model must see the
fault to detect it).

:func:`core_batch` runs the same kernel over arrays; :func:`core_step` is one
point (the tests' and benchmarks' streaming ``CorePipeline`` wraps it).

Speed choices (``benchmarks/core_speed.py``, docs/rema.md): the per-point
kernels are inlined into this loop (``inline="always"``); every kernel of the
core uses ``error_model="numpy"`` (a float division by zero would give inf or
NaN instead of raising; every division here is guarded or by a positive
constant), which drops a branch and a cold error path per division; window
sums may be reordered (``reassoc``) so they vectorise, with reference
agreement to 1e-9 tested; the batch writes only the returned arrays, which
NumPy allocates (huge pages on large arrays).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._exceptions import ConfigError
from .features import (
    N_CHANNEL,
    FeatureParams,
    channel_features_step,
    cross_features_step,
    history_push,
    velocity_step,
)
from .recovery import N_RECOVERY_STATE, RecoveryParams, recovery_step
from .rema import (
    N_OUT,
    N_PARAMS,
    N_STATE,
    O_DISTANCE,
    O_EMA,
    O_FLAG,
    O_LOWER,
    O_UPPER,
    P_ALPHA,
    P_SS,
    S_ALPHA,
    S_LAST,
    RemaParams,
    rema_step,
)
from .time_classifier import INTERMITTENT, N_TIME_STATE, T_GAP, TRANSIENT, TimeParams, time_step

__all__ = [
    "CoreOutput",
    "CoreParams",
    "core_batch",
    "core_new_state",
    "core_state_size",
    "core_step",
]

FloatArray = NDArray[np.float64]

# P layout after the REMA (9), time (3) and recovery (2) parameters.
_P_TIME = N_PARAMS
_P_REC = _P_TIME + 3
_P_PERIOD, _P_LONG, _P_SHORT, _P_CROSS, _P_FEED = range(_P_REC + 2, _P_REC + 7)
N_CORE_PARAMS = _P_FEED + 1
# Result block at the start of ``out``: then REMA rows (east, north), then features.
R_FLAG, R_CODE, R_EAST, R_NORTH, R_ALERT, R_SCORE = range(6)
N_RESULT = 6


@numba.njit(cache=True, error_model="numpy", inline="always")
def _layout(P: FloatArray) -> tuple[int, int, int, int, int, int, int, int, int]:
    """Offsets into S: rema east state/ring, rema north state/ring, hist east/north, count, time, recovery."""
    ss = int(P[P_SS])
    hist = 2 * max(int(P[_P_LONG]), int(P[_P_SHORT]) + 1)
    rs_e = 0
    rr_e = rs_e + N_STATE
    rs_n = rr_e + ss
    rr_n = rs_n + N_STATE
    h_e = rr_n + ss
    h_n = h_e + hist
    cnt = h_n + hist
    ts = cnt + 1
    rec = ts + N_TIME_STATE
    return rs_e, rr_e, rs_n, rr_n, h_e, h_n, cnt, ts, rec


@numba.njit(cache=True, error_model="numpy")
def core_state_size(P: FloatArray) -> int:
    return _layout(P)[8] + N_RECOVERY_STATE


@numba.njit(cache=True, error_model="numpy")
def core_new_state(P: FloatArray) -> FloatArray:
    S = np.zeros(core_state_size(P))
    rs_e, _, rs_n, _, _, _, _, ts, _ = _layout(P)
    S[rs_e + S_ALPHA] = P[P_ALPHA]
    S[rs_n + S_ALPHA] = P[P_ALPHA]
    S[ts + T_GAP] = np.inf
    return S


@numba.njit(cache=True, error_model="numpy", inline="always")
def _score(row: FloatArray) -> float:
    """distance / (distance + half-width): 0 on the EMA, 0.5 on a bound, -> 1 far out."""
    half = 0.5 * (row[O_UPPER] - row[O_LOWER])
    d = row[O_DISTANCE]
    if not np.isfinite(half) or d + half <= 0.0:
        return 0.0
    return float(d / (d + half))


@numba.njit(cache=True, error_model="numpy")
def core_step(
    P: FloatArray,
    S: FloatArray,
    east: float,
    north: float,
    speed: float,
    heading: float,
    out: FloatArray,
) -> None:
    """Advance the whole statistical pipeline by one point; fill ``out`` (see module doc)."""
    rs_e, rr_e, rs_n, rr_n, h_e, h_n, cnt, ts, rec = _layout(P)
    ss = int(P[P_SS])
    period = P[_P_PERIOD]
    rema_p = P[:N_PARAMS]
    row_e = out[N_RESULT : N_RESULT + N_OUT]
    row_n = out[N_RESULT + N_OUT : N_RESULT + 2 * N_OUT]
    step_e, step_n = velocity_step(speed, heading, period)
    rema_step(rema_p, S[rs_e : rs_e + N_STATE], S[rr_e : rr_e + ss], east, step_e, row_e)
    rema_step(rema_p, S[rs_n : rs_n + N_STATE], S[rr_n : rr_n + ss], north, step_n, row_n)
    count = int(S[cnt]) + 1
    S[cnt] = count
    win_e = history_push(S[h_e:h_n], count, east)
    win_n = history_push(S[h_n:cnt], count, north)
    f0 = N_RESULT + 2 * N_OUT
    long_n = int(P[_P_LONG])
    short_n = int(P[_P_SHORT])
    channel_features_step(win_e, long_n, short_n, period, row_e, out[f0 : f0 + N_CHANNEL])
    channel_features_step(
        win_n, long_n, short_n, period, row_n, out[f0 + N_CHANNEL : f0 + 2 * N_CHANNEL]
    )
    if P[_P_CROSS] != 0.0:
        c0 = f0 + 2 * N_CHANNEL
        if count == 1:
            out[c0] = np.nan
            out[c0 + 1] = np.nan
        else:
            cross_features_step(
                east - win_e[win_e.size - 2],
                north - win_n[win_n.size - 2],
                period,
                speed,
                heading,
                out[c0 : c0 + 2],
            )
    flag = 1.0 if row_e[O_FLAG] != 0.0 or row_n[O_FLAG] != 0.0 else 0.0
    code = time_step(P[_P_TIME : _P_TIME + 3], S[ts : ts + N_TIME_STATE], flag)
    recovery_step(
        P[_P_REC : _P_REC + 2],
        S[rec : rec + N_RECOVERY_STATE],
        code,
        period,
        east,
        north,
        row_e[O_EMA],
        row_n[O_EMA],
        speed,
        heading,
        out[R_EAST : R_ALERT + 1],
    )
    if P[_P_FEED] != 0.0 and code in (TRANSIENT, INTERMITTENT):
        # Only into the channel that flagged: the other one accepted its value.
        if row_e[O_FLAG] != 0.0:
            S[rs_e + S_LAST] = out[R_EAST]
        if row_n[O_FLAG] != 0.0:
            S[rs_n + S_LAST] = out[R_NORTH]
    out[R_FLAG] = flag
    out[R_CODE] = code
    out[R_SCORE] = max(_score(row_e), _score(row_n))


@numba.njit(cache=True, error_model="numpy")
def _core_batch_kernel(
    P: FloatArray,
    east: FloatArray,
    north: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    features: FloatArray,
    results: FloatArray,
    emas: FloatArray,
) -> None:
    """Fill ``features``, ``results`` and ``emas`` (allocated by the caller, see :func:`core_batch`).

    The per-point row is built in one reused scratch array and only what
    :class:`CoreOutput` returns is stored, straight into its final arrays.
    """
    S = core_new_state(P)
    n = east.size
    f0 = N_RESULT + 2 * N_OUT
    width = f0 + features.shape[1]
    row = np.zeros(width)
    for i in range(n):
        core_step(P, S, east[i], north[i], speed[i], heading[i], row)
        # Element loops: a slice assignment may copy through a temporary array.
        for k in range(width - f0):
            features[i, k] = row[f0 + k]
        for k in range(N_RESULT):
            results[i, k] = row[k]
        emas[i, 0] = row[N_RESULT + O_EMA]
        emas[i, 1] = row[N_RESULT + N_OUT + O_EMA]


@dataclass(frozen=True)
class CoreParams:
    """Everything :func:`core_step` needs; ``period`` is the segment's sampling period (s)."""

    period: float = 1.0
    rema: RemaParams = field(default_factory=RemaParams)
    features: FeatureParams = field(default_factory=FeatureParams)
    time: TimeParams = field(default_factory=TimeParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
    feed_recovered: bool = True

    def to_array(self) -> FloatArray:
        long_n, short_n = self.features.points(self.period)
        return np.concatenate(
            [
                self.rema.to_array(),
                self.time.to_array(),
                self.recovery.to_array(),
                [
                    self.period,
                    long_n,
                    short_n,
                    float(self.features.speed_heading),
                    float(self.feed_recovered),
                ],
            ]
        )

    def n_features(self) -> int:
        return 2 * N_CHANNEL + (2 if self.features.speed_heading else 0)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CoreParams:
        return cls(
            period=float(data["period"]),
            rema=RemaParams.from_dict(data["rema"]),
            features=FeatureParams(**data["features"]),
            time=TimeParams(**data["time"]),
            recovery=RecoveryParams(**data["recovery"]),
            feed_recovered=bool(data["feed_recovered"]),
        )


class CoreOutput(NamedTuple):
    """Per-point results of :func:`core_batch`."""

    features: FloatArray
    flag: NDArray[np.int8]
    time_code: NDArray[np.int8]
    east_clean: FloatArray
    north_clean: FloatArray
    alert: NDArray[np.int8]
    score: FloatArray
    ema_east: FloatArray
    ema_north: FloatArray


def _split(features: FloatArray, results: FloatArray, emas: FloatArray) -> CoreOutput:
    return CoreOutput(
        features=features,
        flag=results[:, R_FLAG].astype(np.int8),
        time_code=results[:, R_CODE].astype(np.int8),
        east_clean=results[:, R_EAST].copy(),
        north_clean=results[:, R_NORTH].copy(),
        alert=results[:, R_ALERT].astype(np.int8),
        score=results[:, R_SCORE].copy(),
        ema_east=emas[:, 0].copy(),
        ema_north=emas[:, 1].copy(),
    )


def core_batch(
    east: ArrayLike,
    north: ArrayLike,
    params: CoreParams | None = None,
    *,
    speed: ArrayLike | None = None,
    heading: ArrayLike | None = None,
) -> CoreOutput:
    """The pipeline over one segment (arrays of one length; speed/heading optional)."""
    prm = params or CoreParams()
    e = np.ascontiguousarray(east, dtype=np.float64)
    n = e.size
    arrays = []
    for name, values in (("north", north), ("speed", speed), ("heading", heading)):
        arr = (
            np.full(n, np.nan) if values is None else np.ascontiguousarray(values, dtype=np.float64)
        )
        if arr.shape != (n,):
            raise ConfigError(f"{name} must have one value per point ({n}), got shape {arr.shape}")
        arrays.append(arr)
    north_a, speed_a, heading_a = arrays
    # Allocated by NumPy, not inside the kernel: NumPy asks Linux for huge pages
    # on large arrays, which saves most of the page faults of fresh memory
    # (measured: about a fifth of the time on a 1M-point segment).
    features = np.empty((n, prm.n_features()))
    results = np.empty((n, N_RESULT))
    emas = np.empty((n, 2))
    _core_batch_kernel(prm.to_array(), e, north_a, speed_a, heading_a, features, results, emas)
    return _split(features, results, emas)
