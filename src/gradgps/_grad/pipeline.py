"""The whole GRAD pipeline for one fix, as one compiled step.

Per fix: project to the track's metric frame -> MS-SW + REMA features
(:mod:`gradgps._grad.core`) and the offset tracker
(:mod:`gradgps._grad.offset`) -> the GRU (:mod:`gradgps._grad.gru`) -> anomaly if
P(anomaly) >= threshold -> time type (:mod:`gradgps._grad.time_classifier`) ->
recovery (:mod:`gradgps._grad.recovery`) -> clean position back to degrees.

Why one step: a car needs a verdict per fix in microseconds, and every
Python-level call costs about a microsecond of dispatch. So parameters live
in one float64 vector ``P``, state in one float64 vector ``S`` plus the GRU's
float32 hidden state ``H``, and :func:`grad_step` does everything. The batch
path (:func:`grad_segments`) loops the *same* per-point function over each
segment, so batch and streaming give identical numbers, bit for bit.

The features (the GRU's input) depend only on the fixes, never on the GRU's
decisions: the core pipeline's REMA runs on its own flags. That keeps
training simple (features are computed once, then the network is fitted) and
makes the verdict of one fix unable to corrupt the features of the next. The
GRU's decisions drive the time classifier and the recovery.

**A segment's sampling period** (which turns window lengths in seconds into
points, and drives the recovery's dead reckoning) is the median of its first
:data:`PERIOD_STEPS` (5) time steps (:func:`segment_period`). One odd step
(a fix 0.1 s or 1 ms after the first, as a receiver emits while it locks on)
cannot set it: a GNSS engineer reads a receiver's rate off its steady steps,
not off its first. A stream only knows those steps as they arrive, so while
a segment has fewer than ``PERIOD_STEPS`` steps its period is *provisional*:
the median of the steps seen so far (1 s for the lone first fix). Whenever
that estimate changes, the segment is rebuilt from a fresh state with the
new period and its fixes so far are replayed (at most ``PERIOD_STEPS + 1``
fixes are kept for this); each fix's verdict is the one computed when it
arrived. From the ``PERIOD_STEPS``-th step on the period is fixed. Batch
detection (:func:`grad_segments`) reproduces exactly this sequence, so batch
equals streaming bit for bit.

Memory is bounded whatever the timestamps: a window holds ``window_s /
period`` fixes, capped at :data:`gradgps._grad.features.MAX_WINDOW_POINTS`
(the window then covers fewer seconds at very high rates), and fixes less
than 1 ms apart never form a step (see :data:`gradgps._grad.detector.MIN_STEP_S`).

Features are compressed with a signed ``log1p`` before the network's scaler
(see :func:`_compress`).

Layout of ``P``: core parameters (``N_CORE_PARAMS``), then the rest block
(offset N_OFFSET_PARAMS, time 3, recovery 2, threshold, period, GRU dims 6, frame 12,
motion on/off + N_MOTION_PARAMS, drift witness on/off + N_DRIFT_PARAMS).
Layout of ``S``: core state, offset state, time state, recovery state, drift witness
state, motion state.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from .._exceptions import ConfigError
from .._tracks.geo import N_FRAME_CONSTANTS, LocalFrame, to_geodetic_scalar, to_local_scalar
from .core import (
    _P_CROSS,
    N_CORE_PARAMS,
    N_RESULT,
    CoreParams,
    core_new_state,
    core_step,
)
from .defaults import grad_rema_params, grad_time_params
from .drift import N_DRIFT_OUT, N_DRIFT_PARAMS, N_DRIFT_STATE, DriftParams, drift_step
from .features import N_CHANNEL, FeatureParams, feature_names
from .gru import (
    _heads,
    _layer_size,
    _recurrent_step,
    _scratch_size,
    _sigmoid_scalar,
    _tanh_scalar,
)
from .motion import (
    MOTION_FEATURES,
    N_MOTION_FEATURES,
    N_MOTION_PARAMS,
    N_MOTION_STATE,
    MotionParams,
    motion_step,
    motion_velocity,
)
from .offset import (
    N_OFFSET_FEATURES,
    N_OFFSET_PARAMS,
    N_OFFSET_SCRATCH,
    N_OFFSET_STATE,
    OFFSET_FEATURES,
    OffsetParams,
    offset_step,
)
from .recovery import N_RECOVERY_STATE, RecoveryParams, recovery_step, within_reach
from .rema import N_OUT, O_EMA, O_LOWER, O_UPPER, RemaParams
from .time_classifier import (
    N_TIME_STATE,
    NONE,
    PERMANENT,
    T_GAP,
    T_RUN,
    TRANSIENT,
    TimeParams,
    TimeSpans,
    time_step,
)

__all__ = [
    "LANES",
    "N_NETWORK_DIMS",
    "N_POINT_OUT",
    "PERIOD_STEPS",
    "PipelineParams",
    "RateThresholds",
    "grad_features",
    "grad_segments",
    "grad_step",
    "lanes_step",
    "new_lane_work",
    "new_state",
    "new_work",
    "pipeline_feature_names",
    "segment_period",
    "warmup_periods",
]

FloatArray = NDArray[np.float64]

# The rest block of P, after the core parameters.
_OFF = 0
_TIME = _OFF + N_OFFSET_PARAMS
_REC = _TIME + 3
_THR = _REC + 2
_PERIOD, _DIMS = _THR + 1, _THR + 2
# The network's dims ([F, H1, H2, K, C, M], gradgps._grad.gru.pack_parameters).
N_NETWORK_DIMS = 6
_FRAME = _DIMS + N_NETWORK_DIMS
# The motion model: an on/off flag, then its parameters (zeros when off).
_MOTION_ON = _FRAME + N_FRAME_CONSTANTS
_MOTION = _MOTION_ON + 1
# The drift witness (issue 16): an on/off flag, then its parameters (zeros when off).
_DRIFT_ON = _MOTION + N_MOTION_PARAMS
_DRIFT = _DRIFT_ON + 1
# The recovery's reach (gradgps._grad.recovery.within_reach): reach_m, reach_accel_mps2.
_REACH = _DRIFT + N_DRIFT_PARAMS
# The confirm head's threshold when verdicts settle one fix late (0: at once).
_SETTLE = _REACH + 2
N_REST_PARAMS = _SETTLE + 1
# A settling segment's state ends with its pending fix (the last one read, whose
# verdict waits for the next fix): whether there is one, its inputs to the verdict,
# then scratch for the time classifier's and the recovery's states (the pending fix's
# verdict at once is worked out on copies, so the state keeps the settled history).
(
    _PEND_HAS,
    _PEND_E,
    _PEND_N,
    _PEND_SPEED,
    _PEND_HEADING,
    _PEND_EMA_E,
    _PEND_EMA_N,
    _PEND_DRIFT,
    _PEND_MEASURED,
    _PEND_DT,
    _PEND_SCORE,
    _PEND_CLASS,
    _PEND_SCRATCH,
) = range(13)
N_PENDING = _PEND_SCRATCH + N_TIME_STATE + N_RECOVERY_STATE
# ``off_out`` scratch: offset features, motion features, then the speed and
# heading the pipeline used for the point (reported, or the motion model's).
_SH = N_OFFSET_FEATURES + N_MOTION_FEATURES
# Then the drift witness's outputs (flag, offset m), then the offset tracker's work space.
_DRIFT_OUT = _SH + 2
_OFF_SCRATCH = _DRIFT_OUT + N_DRIFT_OUT
_N_OFF_OUT = _OFF_SCRATCH + N_OFFSET_SCRATCH
# State blocks after the core's: offset, time, recovery, drift witness, motion.
_N_TAIL_STATE = N_OFFSET_STATE + N_TIME_STATE + N_RECOVERY_STATE + N_DRIFT_STATE + N_MOTION_STATE
# Per-point outputs. O_CONFIRM, with a confirm head: where verdicts settle one fix late,
# the head's P(anomaly) of the point, read at the next point (the read that decided it;
# NaN for a verdict at once); where they do not, the head's P(anomaly) of the point
# *before* this one, read with this point seen (meaningless at a segment's first
# point). NaN without the head.
O_FLAG, O_SCORE, O_BIAS, O_TIME, O_LAT, O_LON, O_ALERT, O_CONFIRM = range(8)
N_POINT_OUT = 8
#: Time steps a segment's sampling period is the median of (see the module docstring).
PERIOD_STEPS = 5


@dataclass(frozen=True)
class RateThresholds:
    """A model's thresholds for segments sampled every ``from_period_s`` seconds or slower.

    Why: the network's probabilities are not calibrated alike at every rate. One
    pair of thresholds, chosen on validation drives at 0.5-10 Hz pooled, kept the
    pool's normal recall at the floor while the real drives at 0.5 Hz fell below
    it (DrivePlotR 0.981, Austin 0.979 on the recipe's validation points), the
    simulated 0.5 Hz drives and the faster ones hiding them
    (``gradgps._train.calibrate``). ``confirm`` is ignored where the model settles
    no verdicts late.
    """

    from_period_s: float
    anomaly: float
    confirm: float

    def checked(self) -> RateThresholds:
        if not (math.isfinite(self.from_period_s) and self.from_period_s > 0):
            raise ConfigError(
                f"a rate band's from_period_s must be a positive number, got {self.from_period_s!r}"
            )
        for name in ("anomaly", "confirm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 < value < 1.0):
                raise ConfigError(
                    f"a rate band's {name} threshold must be in (0, 1), got {value!r}"
                )
        return self


@dataclass(frozen=True)
class PipelineParams:
    """Everything but the network weights; saved in a model's ``config.json``."""

    rema: RemaParams = field(default_factory=grad_rema_params)
    features: FeatureParams = field(default_factory=FeatureParams)
    offset: OffsetParams = field(default_factory=OffsetParams)
    time: TimeParams = field(default_factory=grad_time_params)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
    threshold: float = 0.5
    max_gap_s: float = 5.0
    motion: MotionParams | None = field(default_factory=MotionParams)
    """The positions-only motion model's features (:mod:`gradgps._grad.motion`); ``None``
    in models trained before it existed (their ``config.json`` has no ``motion``)."""
    drift: DriftParams | None = None
    """The drift witness (:mod:`gradgps._grad.drift`), not learnt; off unless a model's
    ``config.json`` names it (``"drift": {}`` for its defaults). Off in the shipped
    model: on the DrivePlotR test drives (phone positions with the phone's own speed
    and heading) its defaults, chosen on the validation drives, flagged 20.5 % of the
    clean fixes as drift (721 of 3,512; `gradgps bench --suite robustness`, cell
    ``+speed+heading``), where the validation drives gave 0.00 %; the train drives give
    5.05 % (`benchmarks/drift_check.py --threshold-sigmas 15 --split train`): real
    stretches where the position steps and the reported speed or course disagree for
    half a minute, which a pull-off along the track resembles (docs/deviations.md)."""
    confirm_threshold: float | None = None
    """Where the network has a confirm head (a second anomaly head that judges the
    previous fix): its threshold, and each fix's verdict *settles* one fix late: the
    confirm head's read at the next fix of the segment decides it (the anomaly head's
    at once at a segment's last fix), and its time type and repair follow that
    verdict (:func:`grad_step`). ``None``: verdicts at once. Set from the model's
    ``thresholds.confirm`` when it is loaded, never saved in the pipeline settings."""
    rate_thresholds: tuple[RateThresholds, ...] = ()
    """Thresholds of their own for slowly sampled segments: a segment sampled every
    ``from_period_s`` seconds or slower takes the last such band's ``anomaly`` and
    ``confirm`` in place of :attr:`threshold` and :attr:`confirm_threshold`. Set
    from the model's ``thresholds.by_rate`` when it is loaded (:class:`RateThresholds`),
    never saved in the pipeline settings; ``()``: one pair for every rate."""
    verdict_time: TimeSpans | None = field(default_factory=TimeSpans)
    """How the verdicts' time types (and so which faults are permanent) count ``time``'s
    thresholds at each segment's period: in fixes up to 1 Hz, in the time those take
    at 1 Hz above (:class:`TimeSpans`). ``None``: in fixes at every rate. Models saved
    before it existed say nothing and get the default; ``"verdict_time": null`` in a
    model's pipeline settings keeps fixes. REMA's own classifier inside the features
    still counts ``time`` in fixes, as the network was trained."""

    def core(self, period: float) -> CoreParams:
        return CoreParams(
            period=period,
            rema=self.rema,
            features=self.features,
            time=self.time,
            recovery=self.recovery,
            feed_recovered=True,
        )

    def to_dict(self) -> dict[str, Any]:
        from dataclasses import asdict

        data = asdict(self)
        del data["confirm_threshold"]  # the model's thresholds.confirm, not a setting
        del data["rate_thresholds"]  # the model's thresholds.by_rate, not a setting
        return data

    def thresholds_at(self, period: float) -> tuple[float, float | None]:
        """(anomaly, confirm) thresholds of a segment sampled every ``period`` s."""
        anomaly, confirm = self.threshold, self.confirm_threshold
        for band in sorted(self.rate_thresholds, key=lambda b: b.from_period_s):
            if period >= band.from_period_s:
                anomaly = band.anomaly
                confirm = confirm if confirm is None else band.confirm
        return anomaly, confirm

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PipelineParams:
        missing = [f.name for f in fields(OffsetParams) if f.name not in data["offset"]]
        if missing:
            # Saved by an earlier tracker (before 2026-11-27: no tau_a, a constant-velocity
            # clean track): the same feature names, other values. Filling in today's
            # defaults would run the network on features it never saw, silently.
            raise ConfigError(
                f"its offset tracker settings have no {', '.join(missing)}: it was trained "
                "with an earlier offset tracker, whose features this version no longer "
                "computes"
            )
        return cls(
            rema=RemaParams.from_dict(data["rema"]),
            features=FeatureParams(**data["features"]),
            offset=OffsetParams(**data["offset"]),
            time=TimeParams(**data["time"]),
            recovery=RecoveryParams(**data["recovery"]),
            threshold=float(data["threshold"]),
            max_gap_s=float(data["max_gap_s"]),
            motion=MotionParams(**data["motion"]).checked() if data.get("motion") else None,
            drift=_drift_params(data),
            verdict_time=_verdict_time(data),
        )

    def array(self, period: float, frame: LocalFrame, dims: NDArray[np.int64]) -> FloatArray:
        """``P`` for one segment sampled every ``period`` s in ``frame``, GRU of ``dims``."""
        if len(dims) != N_NETWORK_DIMS:  # every slot after them would be read one off
            raise ConfigError(f"a network's dims have {N_NETWORK_DIMS} entries, got {len(dims)}")
        core = self.core(period).to_array()
        anomaly, confirm = self.thresholds_at(period)
        rest = np.concatenate(
            [
                self.offset.to_array(),
                (
                    self.time
                    if self.verdict_time is None
                    else self.verdict_time.at_period(self.time, period)
                ).to_array(),
                self.recovery.to_array(),
                [anomaly, period],
                np.asarray(dims, dtype=np.float64),
                frame.constants(),
                [0.0 if self.motion is None else 1.0],
                np.zeros(N_MOTION_PARAMS) if self.motion is None else self.motion.to_array(period),
                [0.0 if self.drift is None else 1.0],
                np.zeros(N_DRIFT_PARAMS) if self.drift is None else self.drift.to_array(),
                self.recovery.reach_array(),
                [self._settle(dims, confirm)],
            ]
        )
        return np.concatenate([core, rest])

    def _settle(self, dims: NDArray[np.int64], confirm: float | None) -> float:
        """``P``'s settle slot: the confirm threshold where the network has the head and
        one is set, else 0."""
        if confirm is None or int(dims[4]) == 0:
            return 0.0
        if not 0.0 < confirm < 1.0:
            raise ConfigError(f"the confirm threshold must be in (0, 1), got {confirm}")
        return float(confirm)

    def settles(self, dims: NDArray[np.int64]) -> bool:
        """Whether a network of ``dims`` gives its verdicts one fix late (see
        :attr:`confirm_threshold`)."""
        return self._settle(dims, self.confirm_threshold) > 0.0


def _verdict_time(data: dict[str, Any]) -> TimeSpans | None:
    """How a saved ``pipeline`` block counts the verdicts' time types: absent (a model
    saved before it existed) means the default :class:`TimeSpans`, ``null`` fixes."""
    if "verdict_time" not in data:
        return TimeSpans()
    return None if data["verdict_time"] is None else TimeSpans(**data["verdict_time"])


def _drift_params(data: dict[str, Any]) -> DriftParams | None:
    """The drift witness's settings in a saved ``pipeline`` block: absent or ``null``
    means off."""
    if data.get("drift") is None:
        return None
    return DriftParams(**data["drift"]).checked()


def pipeline_feature_names(params: PipelineParams) -> list[str]:
    """Names of the GRU's input features, in order."""
    motion = [] if params.motion is None else list(MOTION_FEATURES)
    return feature_names(params.features) + list(OFFSET_FEATURES) + motion


def new_state(P: FloatArray) -> FloatArray:
    """Fresh ``S`` for a segment with parameters ``P``."""
    core = core_new_state(P[:N_CORE_PARAMS])
    rest = np.zeros(_N_TAIL_STATE + _pending_size(P))
    rest[N_OFFSET_STATE + T_GAP] = np.inf
    return np.concatenate([core, rest])


@numba.njit(cache=True)
def _pending_size(P: FloatArray) -> int:
    """The pending block's length at the end of ``S`` (0 where verdicts come at once)."""
    return N_PENDING if P[N_CORE_PARAMS + _SETTLE] > 0.0 else 0


@numba.njit(cache=True)
def _tail_end(P: FloatArray, S: FloatArray) -> int:
    """Where the tail blocks of ``S`` end (before a pending block)."""
    return S.size - _pending_size(P)


@numba.njit(cache=True)
def _n_core_features(Pc: FloatArray) -> int:
    # Two position channels, plus the 2 speed/heading cues when enabled (see CoreParams).
    return 2 * N_CHANNEL + (2 if Pc[_P_CROSS] != 0.0 else 0)


@numba.njit(cache=True)
def _features_point(
    P: FloatArray,
    S: FloatArray,
    core_out: FloatArray,
    off_out: FloatArray,
    dt: float,
    lat: float,
    lon: float,
    speed: float,
    heading: float,
    x: Any,
) -> tuple[float, float]:
    """Project, run motion model + core + offset tracker, write the feature vector into
    ``x``; return (east, north).

    Where the fix has no reported speed or heading, the motion model's predicted
    velocity (:func:`motion_velocity`) stands in for the missing one in REMA's
    expected step, the offset tracker and the recovery: without it those fall
    back to per-channel constant-velocity guesses that lag in every curve and
    never re-acquire after a long jump on a positions-only file (issue 13).
    The offset tracker never takes it: it estimates its own velocity from the
    fixes (its Kalman filter), and a velocity drawn from the same fixes is no
    second measurement; only a reported speed *and* heading measure it.
    The speed and heading used are left in ``off_out[_SH : _SH + 2]`` for the
    recovery in :func:`_verdict`.
    """
    Pc = P[:N_CORE_PARAMS]
    rest = P[N_CORE_PARAMS:]
    end = _tail_end(P, S)
    core_size = end - _N_TAIL_STATE
    east, north = to_local_scalar(rest[_FRAME : _FRAME + N_FRAME_CONSTANTS], lat, lon)
    off_speed = speed  # the reported velocity only, never the motion model's
    off_heading = heading
    if rest[_MOTION_ON] != 0.0:
        ms = end - N_MOTION_STATE
        m_out = off_out[N_OFFSET_FEATURES:_SH]
        motion_step(rest[_MOTION : _MOTION + N_MOTION_PARAMS], S[ms:end], dt, east, north, m_out)
        if not (np.isfinite(speed) and np.isfinite(heading)):
            m_speed, m_heading = motion_velocity(S[ms:end])
            if not np.isfinite(speed):
                speed = m_speed
            if not np.isfinite(heading):
                heading = m_heading
    off_out[_SH] = speed
    off_out[_SH + 1] = heading
    core_step(Pc, S[:core_size], east, north, speed, heading, core_out)
    offset_step(
        rest[_OFF : _OFF + N_OFFSET_PARAMS],
        S[core_size : core_size + N_OFFSET_STATE],
        dt,
        east,
        north,
        off_speed,
        off_heading,
        off_out,
        off_out[_OFF_SCRATCH:],
    )
    f0 = N_RESULT + 2 * N_OUT
    nc = _n_core_features(Pc)
    for k in range(nc):
        x[k] = _compress(core_out[f0 + k])
    for k in range(N_OFFSET_FEATURES):
        x[nc + k] = _compress(off_out[k])
    if rest[_MOTION_ON] != 0.0:
        m0 = nc + N_OFFSET_FEATURES
        for k in range(N_MOTION_FEATURES):
            x[m0 + k] = _compress(off_out[N_OFFSET_FEATURES + k])
    return east, north


@numba.njit(cache=True)
def _compress(v: float) -> float:
    """Signed log1p: metre-scale features span 0.1 m (noise) to 200 m (jumps), and a
    standard scaler alone would squash the normal range into a sliver near zero."""
    if v >= 0.0:
        return math.log1p(v)
    if v < 0.0:
        return -math.log1p(-v)
    return v  # NaN stays NaN (the GRU reads it as the training mean)


@numba.njit(cache=True)
def _verdict(
    P: FloatArray,
    S: FloatArray,
    dims: Any,
    gru_out: Any,
    core_out: FloatArray,
    rec_out: FloatArray,
    east: float,
    north: float,
    speed: float,
    heading: float,
    drift: float,
    measured: bool,
    dt: float,
    out: FloatArray,
    settled: FloatArray,
) -> None:
    """The network's outputs ``gru_out`` -> threshold -> time type -> recovery -> clean
    position in degrees (the part of :func:`grad_step` after the GRU, shared with the
    many-stream step :func:`lanes_step`): into ``out``, or, where verdicts settle one
    fix late, :func:`_settle` (``out`` at once, ``settled`` the previous fix's).

    A transient or intermittent fix's clean position is the recovery's prediction held
    within reach of the fix (:func:`within_reach`), after as many periods without a
    trusted fix as the time classifier's current run of flags. ``measured``: the fix
    reports both speed and heading, so the prediction moved with the measured
    velocity and only the reach's constant part applies; such a fix is repaired so
    even in a *permanent* fault (which still raises its alert): dead reckoning on a
    measured velocity stays good for as long as the fault lasts, where the paper's
    reason to leave a permanent fault alone (its estimate drifts too far to be
    trusted) holds for a velocity guessed from the positions. ``dt``: the time step
    to this fix, which the prediction advances by (a dropped fix is a longer step).

    ``drift``: the drift witness's flag. A fix the GRU passes but the witness
    flags is an anomaly of bias class ``dims[3]`` (``drift``, after the head's
    classes: the head has no drift class); the GRU's own verdicts stand.
    """
    if P[N_CORE_PARAMS + _SETTLE] > 0.0:
        _settle(
            P,
            S,
            dims,
            gru_out,
            core_out,
            rec_out,
            east,
            north,
            speed,
            heading,
            drift,
            measured,
            dt,
            out,
            settled,
        )
        return
    ts = _tail_end(P, S) - _N_TAIL_STATE + N_OFFSET_STATE
    rs = ts + N_TIME_STATE
    _decide_at_once(
        P,
        S[ts : ts + N_TIME_STATE],
        S[rs : rs + N_RECOVERY_STATE],
        dims,
        gru_out,
        core_out,
        rec_out,
        east,
        north,
        speed,
        heading,
        drift,
        measured,
        dt,
        gru_out[1 + dims[3]] if dims[4] != 0 else np.nan,
        out,
    )


@numba.njit(cache=True)
def _decide_at_once(
    P: FloatArray,
    time_state: FloatArray,
    rec_state: FloatArray,
    dims: Any,
    gru_out: Any,
    core_out: FloatArray,
    rec_out: FloatArray,
    east: float,
    north: float,
    speed: float,
    heading: float,
    drift: float,
    measured: bool,
    dt: float,
    confirm: float,
    out: FloatArray,
) -> None:
    """The anomaly head's verdict on its own fix (:func:`_at_once`), applied on the given
    time classifier's and recovery's states (:func:`_apply`)."""
    flag, best = _at_once(P[N_CORE_PARAMS + _THR], dims, gru_out, drift)
    _apply(
        P,
        time_state,
        rec_state,
        flag,
        best,
        float(gru_out[0]),
        confirm,
        east,
        north,
        core_out[N_RESULT + O_EMA],
        core_out[N_RESULT + N_OUT + O_EMA],
        speed,
        heading,
        measured,
        dt,
        rec_out,
        out,
    )


@numba.njit(cache=True)
def _anomaly_class(dims: Any, gru_out: Any) -> int:
    """The bias head's most likely anomaly class (1 .. K-1; 0 is normal)."""
    best = 1
    for k in range(2, dims[3]):
        if gru_out[1 + k] > gru_out[1 + best]:
            best = k
    return best


@numba.njit(cache=True)
def _at_once(threshold: float, dims: Any, gru_out: Any, drift: float) -> tuple[float, int]:
    """The anomaly head's verdict on its own fix: (flag, bias class), the drift witness
    flagging what the head passes as class ``dims[3]``."""
    if gru_out[0] >= threshold:
        return 1.0, _anomaly_class(dims, gru_out)
    if drift != 0.0:
        return 1.0, int(dims[3])
    return 0.0, 0


@numba.njit(cache=True)
def _apply(
    P: FloatArray,
    time_state: FloatArray,
    rec_state: FloatArray,
    flag: float,
    best: int,
    score: float,
    confirm: float,
    east: float,
    north: float,
    ema_e: float,
    ema_n: float,
    speed: float,
    heading: float,
    measured: bool,
    dt: float,
    rec_out: FloatArray,
    out: FloatArray,
) -> None:
    """A decided fix: time type, repair, clean position in degrees, into ``out``
    (advancing ``time_state`` and ``rec_state``; see :func:`_verdict`)."""
    rest = P[N_CORE_PARAMS:]
    code = time_step(rest[_TIME : _TIME + 3], time_state, flag)
    recovery_step(
        rest[_REC : _REC + 2],
        rec_state,
        TRANSIENT if code == PERMANENT and measured else code,
        dt if dt > 0.0 else rest[_PERIOD],
        east,
        north,
        ema_e,
        ema_n,
        speed,
        heading,
        rec_out,
    )
    if code != NONE and (code != PERMANENT or measured):
        rec_out[0], rec_out[1] = within_reach(
            rest[_REACH : _REACH + 2],
            0.0 if measured else time_state[T_RUN] * rest[_PERIOD],
            east,
            north,
            rec_out[0],
            rec_out[1],
        )
    lat_c, lon_c = to_geodetic_scalar(
        rest[_FRAME : _FRAME + N_FRAME_CONSTANTS], rec_out[0], rec_out[1]
    )
    out[O_FLAG] = flag
    out[O_SCORE] = score
    out[O_BIAS] = best
    out[O_TIME] = code
    out[O_LAT] = lat_c
    out[O_LON] = lon_c
    out[O_ALERT] = 1.0 if code == PERMANENT else 0.0
    out[O_CONFIRM] = confirm


@numba.njit(cache=True)
def _settle(
    P: FloatArray,
    S: FloatArray,
    dims: Any,
    gru_out: Any,
    core_out: FloatArray,
    rec_out: FloatArray,
    east: float,
    north: float,
    speed: float,
    heading: float,
    drift: float,
    measured: bool,
    dt: float,
    out: FloatArray,
    settled: FloatArray,
) -> None:
    """:func:`_verdict` for a network whose verdicts settle one fix late
    (:attr:`PipelineParams.confirm_threshold`).

    The fix read before this one (the pending fix in ``S``) is decided by the confirm
    head's read now (``gru_out[1 + dims[3]]``) against the confirm threshold (the
    drift witness still flags what the head passes), and its time type and repair
    advance the state: ``settled``, final. This fix then becomes the pending one, and
    its verdict at once (the anomaly head's, on copies of the time classifier's and
    the recovery's states, so the state keeps only settled verdicts) goes to ``out``:
    what a stream reports at once, and the final verdict of a segment's last fix.
    ``settled[O_FLAG]`` is NaN when there was no pending fix (a segment's first);
    ``O_CONFIRM`` of a settled fix is the read that decided it, of an at-once one NaN.
    """
    rest = P[N_CORE_PARAMS:]
    end = _tail_end(P, S)
    ts = end - _N_TAIL_STATE + N_OFFSET_STATE
    rs = ts + N_TIME_STATE
    pend = S[end:]
    if pend[_PEND_HAS] != 0.0:
        confirm = float(gru_out[1 + dims[3]])
        flag, best = 0.0, 0
        if confirm >= rest[_SETTLE]:
            flag, best = 1.0, int(pend[_PEND_CLASS])
        elif pend[_PEND_DRIFT] != 0.0:
            flag, best = 1.0, int(dims[3])
        _apply(
            P,
            S[ts : ts + N_TIME_STATE],
            S[rs : rs + N_RECOVERY_STATE],
            flag,
            best,
            pend[_PEND_SCORE],
            confirm,
            pend[_PEND_E],
            pend[_PEND_N],
            pend[_PEND_EMA_E],
            pend[_PEND_EMA_N],
            pend[_PEND_SPEED],
            pend[_PEND_HEADING],
            pend[_PEND_MEASURED] != 0.0,
            pend[_PEND_DT],
            rec_out,
            settled,
        )
    else:
        settled[O_FLAG] = np.nan
    pend[_PEND_HAS] = 1.0
    pend[_PEND_E] = east
    pend[_PEND_N] = north
    pend[_PEND_SPEED] = speed
    pend[_PEND_HEADING] = heading
    pend[_PEND_EMA_E] = core_out[N_RESULT + O_EMA]
    pend[_PEND_EMA_N] = core_out[N_RESULT + N_OUT + O_EMA]
    pend[_PEND_DRIFT] = drift
    pend[_PEND_MEASURED] = 1.0 if measured else 0.0
    pend[_PEND_DT] = dt
    pend[_PEND_SCORE] = gru_out[0]
    pend[_PEND_CLASS] = _anomaly_class(dims, gru_out)
    scratch_t = pend[_PEND_SCRATCH : _PEND_SCRATCH + N_TIME_STATE]
    scratch_r = pend[_PEND_SCRATCH + N_TIME_STATE : _PEND_SCRATCH + N_TIME_STATE + N_RECOVERY_STATE]
    scratch_t[:] = S[ts : ts + N_TIME_STATE]
    scratch_r[:] = S[rs : rs + N_RECOVERY_STATE]
    _decide_at_once(
        P,
        scratch_t,
        scratch_r,
        dims,
        gru_out,
        core_out,
        rec_out,
        east,
        north,
        speed,
        heading,
        drift,
        measured,
        dt,
        np.nan,
        out,
    )


@numba.njit(cache=True)
def _dims(P: FloatArray) -> NDArray[np.int64]:
    rest = P[N_CORE_PARAMS:]
    dims = np.empty(N_NETWORK_DIMS, np.int64)
    for k in range(N_NETWORK_DIMS):
        dims[k] = int(rest[_DIMS + k])
    return dims


@numba.njit(cache=True)
def _core_width(P: FloatArray) -> int:
    return N_RESULT + 2 * N_OUT + _n_core_features(P[:N_CORE_PARAMS])


@numba.njit(cache=True)
def new_work(P: FloatArray) -> Any:
    """The work arrays of one segment's per-fix step (``dims`` and six scratch arrays).

    Made once per segment (the Detector keeps them with the segment's state),
    so a streamed fix allocates nothing.
    """
    dims = _dims(P)
    return (
        dims,
        np.empty(_core_width(P)),
        np.empty(_N_OFF_OUT),
        np.empty(3),
        np.empty(dims[0], np.float32),
        np.empty(_scratch_size(dims), np.float32),
        np.empty(1 + dims[3] + dims[4], np.float32),
    )


@numba.njit(cache=True)
def grad_step(
    P: FloatArray,
    S: FloatArray,
    H: Any,
    gp: Any,
    work: Any,
    dt: float,
    lat: float,
    lon: float,
    speed: float,
    heading: float,
    out: FloatArray,
    settled: FloatArray,
) -> None:
    """One fix of one segment: advance ``S`` and ``H`` and write the fix's :data:`N_POINT_OUT`
    outputs into ``out``.

    ``work``: :func:`new_work` of this segment's ``P``. Where verdicts settle one fix
    late (:attr:`PipelineParams.confirm_threshold`), ``out`` is this fix's verdict at
    once and ``settled`` the previous fix's final one (``settled[O_FLAG]`` NaN: none,
    at a segment's first fix; see :func:`_settle`); otherwise ``settled`` is not
    touched and ``out`` is final.
    """
    dims, core_out, off_out, rec_out, x, scratch, gru_out = work
    east, north = _features_point(P, S, core_out, off_out, dt, lat, lon, speed, heading, x)
    _drift_point(P, S, off_out, dt, east, north, speed, heading)
    _recurrent_step(gp, dims, x, H, scratch)
    _heads(gp, dims, H, scratch, gru_out)
    _verdict(
        P,
        S,
        dims,
        gru_out,
        core_out,
        rec_out,
        east,
        north,
        off_out[_SH],
        off_out[_SH + 1],
        off_out[_DRIFT_OUT],
        np.isfinite(speed) and np.isfinite(heading),
        dt,
        out,
        settled,
    )


@numba.njit(cache=True)
def _drift_point(
    P: FloatArray,
    S: FloatArray,
    off_out: FloatArray,
    dt: float,
    east: float,
    north: float,
    speed: float,
    heading: float,
) -> None:
    """The drift witness (:mod:`gradgps._grad.drift`) on the *reported* speed and heading
    (never the motion model's stand-in: the witness must be independent of the
    positions); its flag and offset into ``off_out[_DRIFT_OUT:]`` (0 when off)."""
    rest = P[N_CORE_PARAMS:]
    off_out[_DRIFT_OUT] = 0.0
    off_out[_DRIFT_OUT + 1] = 0.0
    if rest[_DRIFT_ON] != 0.0:
        ds = _tail_end(P, S) - N_MOTION_STATE - N_DRIFT_STATE
        drift_step(
            rest[_DRIFT : _DRIFT + N_DRIFT_PARAMS],
            S[ds : ds + N_DRIFT_STATE],
            dt,
            east,
            north,
            speed,
            heading,
            off_out[_DRIFT_OUT:],
        )


@numba.njit(cache=True)
def _segment_kernel(
    P: FloatArray,
    S: FloatArray,
    H: Any,
    gp: Any,
    dt: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Rows of one stretch of a segment, each fix's final verdict: where verdicts settle
    one fix late, each row is overwritten by its settled verdict when the next fix is
    read, and the last keeps its verdict at once (the segment may go on: the caller
    knows). Also returns the settled verdict of the fix before the stretch (NaN flag:
    none, or verdicts at once), for a stretch that continues a state."""
    work = new_work(P)
    out = np.empty((lat.size, N_POINT_OUT))
    settled = np.full(N_POINT_OUT, np.nan)
    before = np.full(N_POINT_OUT, np.nan)
    for i in range(lat.size):
        grad_step(P, S, H, gp, work, dt[i], lat[i], lon[i], speed[i], heading[i], out[i], settled)
        if not np.isnan(settled[O_FLAG]):
            if i > 0:
                out[i - 1] = settled
            else:
                before[:] = settled
            settled[O_FLAG] = np.nan
    return out, before


@numba.njit(cache=True)
def _features_kernel(
    P: FloatArray,
    S: FloatArray,
    dt: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    n_features: int,
) -> tuple[FloatArray, FloatArray]:
    """The features step over one segment: the GRU's inputs ``(n, n_features)`` and
    REMA's bounds ``(n, 4)`` (east lower, upper, north lower, upper) at each fix,
    both from the one pass, so the bounds a report draws are the features' REMA."""
    core_out = np.empty(_core_width(P))
    off_out = np.empty(_N_OFF_OUT)
    out = np.empty((lat.size, n_features))
    bounds = np.empty((lat.size, 4))
    for i in range(lat.size):
        _features_point(
            P, S, core_out, off_out, dt[i], lat[i], lon[i], speed[i], heading[i], out[i]
        )
        bounds[i, 0] = core_out[N_RESULT + O_LOWER]
        bounds[i, 1] = core_out[N_RESULT + O_UPPER]
        bounds[i, 2] = core_out[N_RESULT + N_OUT + O_LOWER]
        bounds[i, 3] = core_out[N_RESULT + N_OUT + O_UPPER]
    return out, bounds


# The inputs of the batch drivers, as one tuple (numba passes it as is):
# (Ps, Ss, s_off, gp, Hs, begin, end, dt, lat, lon, speed, heading, out).
@numba.njit(cache=True)
def _batch_segment(k: int, batch: Any) -> None:
    """Rows ``begin[k]:end[k]`` of segment ``k`` from its state (``Ss[s_off[k]:s_off[k+1]]``:
    the states lie end to end, never padded to the largest) and ``Hs[k]``, exactly as
    :func:`_segment_kernel`, into ``out``."""
    Ps, Ss, s_off, gp, Hs, begin, end, dt, lat, lon, speed, heading, out = batch
    a, b = begin[k], end[k]
    if b <= a:
        return
    S = Ss[s_off[k] : s_off[k + 1]].copy()
    H = Hs[k].copy()
    rows, before = _segment_kernel(
        Ps[k], S, H, gp, dt[a:b], lat[a:b], lon[a:b], speed[a:b], heading[a:b]
    )
    out[a:b] = rows
    if not np.isnan(before[O_FLAG]):  # a settled verdict for the last warm-up row
        out[a - 1] = before


# Two drivers over the same per-segment step: one thread (the default: safe to call from
# any number of the caller's threads), and segments spread over numba's threads (opt-in:
# with numba's "workqueue" threading layer, two caller threads must not enter it at once;
# "omp" and "tbb" are fine). They are separate functions, not one function compiled twice,
# because numba's on-disk cache keys a kernel by its function, not by its flags.
@numba.njit(cache=True)
def _batch_serial(n_seg: int, batch: Any) -> None:
    for k in range(n_seg):
        _batch_segment(k, batch)


@numba.njit(cache=True, parallel=True)
def _batch_parallel(n_seg: int, batch: Any) -> None:
    for k in numba.prange(n_seg):
        _batch_segment(k, batch)


def grad_segments(
    params: PipelineParams,
    frames: list[LocalFrame],
    gp: NDArray[np.float32],
    dims: NDArray[np.int64],
    starts: NDArray[np.int64],
    t: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    threads: int = 1,
) -> FloatArray:
    """Per-point outputs (n, N_POINT_OUT) for many segments (``starts`` = their boundaries, one frame
    each), exactly as a stream scores them (see the module docstring on the period); with
    ``threads`` > 1 the segments are spread over that many numba threads. Same numbers
    either way."""
    n_seg = starts.size - 1
    out = np.empty((t.size, N_POINT_OUT))
    if n_seg <= 0:
        return out
    h_len = int(dims[1] + dims[2])
    Ps = []
    states = []
    Hs = np.zeros((n_seg, h_len), np.float32)
    begin = np.empty(n_seg, np.int64)
    end = starts[1:].astype(np.int64)
    dt = np.empty(t.size)
    for k in range(n_seg):
        a, b = int(starts[k]), int(starts[k + 1])
        dt[a:b] = _segment_dt(t[a:b])
        periods = warmup_periods(t[a : min(b, a + PERIOD_STEPS + 1)])
        if all(p == periods[-1] for p in periods[1:]):
            # The period never changes after the first step: the stream's rebuilds are
            # no-ops (the lone first fix's verdict does not depend on the period).
            P = params.array(periods[-1], frames[k], dims)
            states.append(new_state(P))
            begin[k] = a
        else:
            P, S, H = _warm_up(
                params, frames[k], gp, dims, periods, a, dt, lat, lon, speed, heading, out
            )
            states.append(S)
            Hs[k] = H
            begin[k] = a + len(periods)
        Ps.append(P)
    s_off = np.r_[0, np.cumsum([x.size for x in states])].astype(np.int64)
    Ss = np.concatenate(states)
    batch = (np.array(Ps), Ss, s_off, gp, Hs, begin, end, dt, lat, lon, speed, heading, out)
    if threads <= 1:
        _batch_serial(n_seg, batch)
        return out
    previous = numba.get_num_threads()
    numba.set_num_threads(min(threads, int(numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]
    try:
        _batch_parallel(n_seg, batch)
    finally:
        numba.set_num_threads(previous)
    return out


def _warm_up(
    params: PipelineParams,
    frame: LocalFrame,
    gp: NDArray[np.float32],
    dims: NDArray[np.int64],
    periods: list[float],
    a: int,
    dt: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    out: FloatArray,
) -> tuple[FloatArray, FloatArray, NDArray[np.float32]]:
    """Rows ``a .. a + len(periods) - 1`` of a segment as a stream scores them while its
    period is provisional: rebuilt and replayed whenever the estimate changes. Returns
    the segment's (P, S, H) after them."""
    h_len = int(dims[1] + dims[2])
    P = S = np.zeros(0)
    H = np.zeros(h_len, np.float32)
    current = math.nan
    settles = params.settles(dims)
    for j, period in enumerate(periods):
        if period != current:
            current = period
            P = params.array(period, frame, dims)
            S, H = new_state(P), np.zeros(h_len, np.float32)
            rows = slice(a, a + j + 1)
        else:
            rows = slice(a + j, a + j + 1)
        d = dt[rows].copy()
        if rows.start == a:
            d[0] = 0.0
        o, before = _segment_kernel(
            P, S, H, gp, d, lat[rows], lon[rows], speed[rows], heading[rows]
        )
        out[a + j] = o[-1]
        # Settling verdicts: the previous row as the stream had it final at this fix.
        if settles and len(o) > 1:
            out[a + j - 1] = o[-2]
        elif not np.isnan(before[O_FLAG]):
            out[a + j - 1] = before
    return P, S, H


def _median(values: list[float]) -> float:
    """Median of a short list (the mean of the middle two for an even count)."""
    v = sorted(values)
    m = len(v) // 2
    return v[m] if len(v) % 2 else (v[m - 1] + v[m]) / 2.0


def warmup_periods(t: FloatArray | list[float]) -> list[float]:
    """The period in force at each of a segment's first fixes ``t`` (at most
    ``PERIOD_STEPS + 1`` are used): 1 s at the first, then the median of the steps so far."""
    times = [float(x) for x in t[: PERIOD_STEPS + 1]]
    steps = [b - a for a, b in itertools.pairwise(times)]
    return [1.0] + [_median(steps[:j]) for j in range(1, len(steps) + 1)]


def _segment_dt(t: FloatArray) -> FloatArray:
    return np.r_[0.0, np.diff(t)] if t.size else np.zeros(0)


def segment_period(t: FloatArray) -> float:
    """A segment's sampling period: the median of its first :data:`PERIOD_STEPS` time steps
    (1 s for a one-fix segment). See the module docstring."""
    return warmup_periods(t)[-1]


class SegmentFeatures(NamedTuple):
    """What :func:`grad_features` computes for one segment."""

    #: The GRU's input features, ``(n, F)`` float64 (training and inspection).
    features: FloatArray
    #: REMA's lower and upper bounds on east and north, ``(n, 4)`` metres:
    #: driven point by point exactly as the detector drives REMA (the motion
    #: model's velocity standing in for a missing speed or heading), so a
    #: report draws the REMA the verdicts came from, not a look-alike.
    rema_bounds: FloatArray


def grad_features(
    params: PipelineParams,
    frame: LocalFrame,
    t: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
) -> SegmentFeatures:
    """The GRU's input features and REMA's bounds for one segment, from a fresh state."""
    names = pipeline_feature_names(params)
    dims = np.array([len(names), 0, 0, 0, 0, 1], np.int64)  # no network: features only
    P = params.array(segment_period(t), frame, dims)
    features, bounds = _features_kernel(
        P, new_state(P), _segment_dt(t), lat, lon, speed, heading, len(names)
    )
    return SegmentFeatures(np.asarray(features), np.asarray(bounds))


# -- Many streams in one step ------------------------------------------------------
#
# lanes_step: one GRAD step for many independent streams at once ("lanes"), the same
# numbers bit for bit.
#
# grad_step scores one fix of one stream: the
# features, then the GRU as matrix-vector products (96 and 48 gate rows), then
# the verdict. Each of those products is a loop over the inputs whose body is a
# short vector loop over the gates, and at this size the loop's set-up costs
# about as much as its arithmetic: the network took more than half of a fix's
# time. A fleet scores one fix of thousands of vehicles at a time, so
# lanes_step runs the same step for many streams together: the
# features stream by stream (the very function ``grad_step`` calls), then both
# GRU layers for all streams as matrix-matrix products whose innermost loop
# runs over the streams (long, contiguous, vectorised), then the verdict
# stream by stream (again ``grad_step``'s own function).
#
# The numbers are those of ``grad_step``, bit for bit: every gate of every
# stream is summed in the same order as :func:`gradgps._grad.gru._cell` sums it
# (its bias, then input 0, 1, 2, ..., each product rounded to float32 and added
# in float32), four inputs per pass with the additions kept in that order, and
# the gates go through the same functions. ``tests/test_lanes.py`` holds
# lanes_step to ``grad_step`` fix by fix; the fleet's property test
# holds gradgps.FleetDetector (which runs on it) to one Detector per
# vehicle.

#: Streams stepped together: long enough that the GRU's inner loops run over many
#: streams, short enough that one block's gate buffers stay in the L1/L2 caches.
LANES = 128


@numba.njit(cache=True)
def new_lane_work(P: FloatArray, lanes: int) -> Any:
    """Work arrays of :func:`lanes_step` for up to ``lanes`` streams of models shaped like ``P``.

    ``(dims, core_out, off_out, rec_out, x, xt, ht, gi, gh, scratch, gru_out, east_north)``.
    """
    dims = _dims(P)
    n_features, hidden1, hidden2 = dims[0], dims[1], dims[2]
    widest = max(hidden1, hidden2)
    return (
        dims,
        np.empty((lanes, _core_width(P))),
        np.empty((lanes, _N_OFF_OUT)),
        np.empty(3),
        np.empty((lanes, n_features), np.float32),
        np.empty((n_features, lanes), np.float32),
        np.empty((hidden1 + hidden2, lanes), np.float32),
        np.empty((3 * widest, lanes), np.float32),
        np.empty((3 * widest, lanes), np.float32),
        np.empty(_scratch_size(dims), np.float32),
        np.empty(1 + dims[3] + dims[4], np.float32),
        np.empty((lanes, 2)),
    )


@numba.njit(cache=True)
def _products(params: Any, o_w: int, n_in: int, g: int, inputs: Any, gates: Any, n: int) -> None:
    """``gates[i, v] += sum_j W[j, i] * inputs[j, v]`` for the first ``n`` streams, ``W`` (n_in x
    g) at ``params[o_w:]``, in :func:`gradgps._grad.gru._cell`'s order: j = 0, 1, 2, ...,
    each product and sum in float32 (four inputs per pass, added left to right)."""
    j = 0
    while j + 4 <= n_in:
        x0, x1, x2, x3 = inputs[j], inputs[j + 1], inputs[j + 2], inputs[j + 3]
        for i in range(g):
            w0 = params[o_w + j * g + i]
            w1 = params[o_w + (j + 1) * g + i]
            w2 = params[o_w + (j + 2) * g + i]
            w3 = params[o_w + (j + 3) * g + i]
            row = gates[i]
            for v in range(n):
                row[v] = (((row[v] + w0 * x0[v]) + w1 * x1[v]) + w2 * x2[v]) + w3 * x3[v]
        j += 4
    while j < n_in:
        xj = inputs[j]
        for i in range(g):
            w = params[o_w + j * g + i]
            row = gates[i]
            for v in range(n):
                row[v] += w * xj[v]
        j += 1


@numba.njit(cache=True)
def _cell_lanes(
    params: Any, o_wih: int, n_in: int, size: int, x: Any, h: Any, gi: Any, gh: Any, n: int
) -> None:
    """:func:`gradgps._grad.gru._cell` for ``n`` streams: ``x`` (n_in x lanes), ``h`` (size x
    lanes) updated in place; ``gi``, ``gh``: gate buffers (at least 3 size x lanes)."""
    g = 3 * size
    o_whh = o_wih + n_in * g
    o_bih = o_whh + size * g
    o_bhh = o_bih + g
    for i in range(g):
        bi = params[o_bih + i]
        bh = params[o_bhh + i]
        for v in range(n):
            gi[i, v] = bi
            gh[i, v] = bh
    _products(params, o_wih, n_in, g, x, gi, n)
    _products(params, o_whh, size, g, h, gh, n)
    for i in range(size):
        for v in range(n):
            r = _sigmoid_scalar(gi[i, v] + gh[i, v])
            z = _sigmoid_scalar(gi[size + i, v] + gh[size + i, v])
            c = _tanh_scalar(gi[2 * size + i, v] + r * gh[2 * size + i, v])
            h[i, v] = (1.0 - z) * c + z * h[i, v]


@numba.njit(cache=True)
def lanes_step(
    Ps: FloatArray,
    Ss: FloatArray,
    s_off: NDArray[np.int64],
    s_len: NDArray[np.int64],
    Hs: Any,
    gp: Any,
    work: Any,
    slot: NDArray[np.int64],
    rows: NDArray[np.int64],
    n: int,
    dt: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    out: FloatArray,
    settled: FloatArray,
) -> None:
    """One fix for each of ``n`` streams (no stream twice), as :func:`grad_step` scores it.

    Stream ``v`` has parameters ``Ps[slot[v]]``, state ``Ss[s_off[slot[v]]:][:s_len[slot[v]]]``
    and GRU state ``Hs[slot[v]]``; its fix is row ``rows[v]`` of ``dt``, ``lat``, ``lon``,
    ``speed``, ``heading``, and its :data:`N_POINT_OUT` outputs go to ``out[rows[v]]``
    (and, where verdicts settle one fix late, the previous fix's final verdict to
    ``settled[rows[v]]``, as :func:`grad_step` writes them). ``work``:
    :func:`new_lane_work` (for at least ``n`` streams).
    """
    dims, core_out, off_out, rec_out, x, xt, ht, gi, gh, scratch, gru_out, en = work
    n_features, hidden1, hidden2 = dims[0], dims[1], dims[2]
    for v in range(n):
        s = slot[v]
        i = rows[v]
        a = s_off[s]
        S = Ss[a : a + s_len[s]]
        east, north = _features_point(
            Ps[s], S, core_out[v], off_out[v], dt[i], lat[i], lon[i], speed[i], heading[i], x[v]
        )
        _drift_point(Ps[s], S, off_out[v], dt[i], east, north, speed[i], heading[i])
        en[v, 0] = east
        en[v, 1] = north
    # The GRU for all streams at once (gradgps._grad.gru._recurrent_step, transposed).
    for j in range(n_features):
        mean = gp[j]
        inv_std = gp[n_features + j]
        for v in range(n):
            scaled = (x[v, j] - mean) * inv_std
            xt[j, v] = scaled if math.isfinite(scaled) else 0.0
    for k in range(hidden1 + hidden2):
        for v in range(n):
            ht[k, v] = Hs[slot[v], k]
    o1 = 2 * n_features
    _cell_lanes(gp, o1, n_features, hidden1, xt, ht[:hidden1], gi, gh, n)
    o2 = o1 + _layer_size(n_features, hidden1)
    _cell_lanes(gp, o2, hidden1, hidden2, ht[:hidden1], ht[hidden1:], gi, gh, n)
    for v in range(n):
        s = slot[v]
        H = Hs[s]
        for k in range(hidden1 + hidden2):
            H[k] = ht[k, v]
        _heads(gp, dims, H, scratch, gru_out)
        a = s_off[s]
        i = rows[v]
        _verdict(
            Ps[s],
            Ss[a : a + s_len[s]],
            dims,
            gru_out,
            core_out[v],
            rec_out,
            en[v, 0],
            en[v, 1],
            off_out[v, _SH],
            off_out[v, _SH + 1],
            off_out[v, _DRIFT_OUT],
            np.isfinite(speed[i]) and np.isfinite(heading[i]),
            dt[i],
            out[i],
            settled[i],
        )
