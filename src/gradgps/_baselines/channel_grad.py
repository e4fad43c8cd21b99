"""GRAD for scalar sensor channels: what ``grad`` means under protocol ``sensor-grid``.

The paper's comparison table corrupts sensor readings (speed, acceleration,
yaw rate), not positions, so the position pipeline of :class:`gradgps.Detector`
has nothing to look at there. GRAD's statistical core works on any 1-D
channel, so the channel GRAD is the same method on other inputs, with
features that see what sensor faults change:

per channel (``speed``, [``speed_fix_mps``], ``accel_x_mps2``, ``gyro_z_dps``)

* REMA + the 11 MS-SW features of :mod:`gradgps._grad.features` (slope,
  intercept, fit error over 30 s; spread, RSI, range, last change over 5 s;
  REMA distance, width, flag, alpha), with REMA **tuned per channel** on the
  validation split (:mod:`gradgps._train.channel_grad`);
* the raw reading and its step difference ``x[i] - x[i-1]``, that step over
  its causal robust spread (what instant, constant and bias faults change;
  the MS-SW windows blur a one-step jump on channels whose natural spread is
  as large as the fault), the reading's departure from its causal level
  (the median of the previous 30 readings) over its robust spread, and how
  many steps the reading has repeated exactly (a stuck sensor holds its
  value to the last digit; a live one rarely does twice in a row);

and across channels (**consistency**, what a fault on one sensor breaks),
the residuals

* ``d(speed)/dt - accel``: the reported speed's change against the
  measured longitudinal acceleration (mean of the two readings);
* with the second speed source (input ``sensor-fix``): ``speed -
  speed_fix`` (reported against position-derived speed, both at the
  half step) and ``d(speed_fix)/dt - accel``,

each as the residual, the residual over its robust spread, its departure
from its causal level (a slow offset between two sensors, a mounting tilt
or a scale error, stays in the level; a fault that starts now departs from
it), that departure over its robust spread, and that averaged over the last
3, 10 and 20 steps (evidence that builds up over a lasting bias or drift
while noise averages out); plus REMA (tuned per residual against the labels
of the channels it sees, :data:`CROSS_SOURCES`) + MS-SW on the residual.

-> every feature signed-log compressed (``sign(x) log(1 + |x|)``; a robust
spread is 1.4826 × the median of ``|x|`` over the previous 30 steps) -> the
same stacked GRU (32, 16) with an anomaly head and a
bias-type head over ``none``, ``instant``, ``constant``, ``bias``,
``drift``, fed the paper's sliding window of 10 steps, trained by
:func:`gradgps._train.channel_grad.dataset_channel_grad` (early stopping on
validation F1 at the threshold it will get, the baselines' data and budget),
with the anomaly threshold tuned on validation F1 under a normal-recall floor.

Where it differs from position GRAD: no offset tracker, time classifier or
recovery (the protocol scores detection and type only), and batch inference
only. A missing reading is carried forward from the previous one (0 at a
segment start); an undefined difference or residual is 0. See
docs/deviations.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._grad.features import N_CHANNEL, FeatureParams, features_batch_kernel
from .._grad.gru import GRUModel
from .._grad.rema import RemaParams
from .base import BatchBaseline, Segment, flags_frame, input_names, segments

__all__ = [
    "CROSS_SOURCES",
    "EVIDENCE_SPANS",
    "N_CROSS",
    "N_RAW",
    "ROBUST_SPAN",
    "SENSOR_BIAS_CLASSES",
    "ChannelGradDetector",
    "ChannelGradModel",
    "channel_features",
    "channel_signals",
    "cross_names",
    "feature_width",
    "rema_names",
    "signed_log",
]

SENSOR_BIAS_CLASSES = ("none", "instant", "constant", "bias", "drift")
#: Raw features per channel: the reading, its step difference, that step over its robust
#: spread, the reading's departure from its recent level (over its robust spread), and how
#: many steps it has been held exactly (a stuck sensor).
N_RAW = 5
#: Features per consistency residual: the residual, over its robust spread, its departure
#: from its recent level (raw and over its robust spread), that departure averaged over
#: :data:`EVIDENCE_SPANS`, then REMA + MS-SW on the residual.
N_CROSS = 4 + 3 + N_CHANNEL
#: Steps over which a causal level (median) and robust spread are measured.
ROBUST_SPAN = 30
#: Steps over which a residual's departure is averaged: evidence that builds up over a
#: lasting fault (a bias, a drift) while noise averages out.
EVIDENCE_SPANS = (3, 10, 20)
#: Which channels' faults each consistency residual sees (REMA on it is tuned against them).
CROSS_SOURCES = {
    "dspeed_dt_minus_accel": ("speed", "accel_x_mps2"),
    "speed_minus_speed_fix": ("speed",),
    "dspeed_fix_dt_minus_accel": ("accel_x_mps2",),
}


def _filled(x: np.ndarray) -> np.ndarray:
    """Missing readings carried forward (0 before the first reading)."""
    s = pd.Series(x).ffill().fillna(0.0)
    return np.ascontiguousarray(s.to_numpy(np.float64))


def _step(x: np.ndarray) -> np.ndarray:
    out = np.zeros_like(x)
    out[1:] = np.diff(x)
    return out


def _robust_z(x: np.ndarray, span: int = ROBUST_SPAN) -> np.ndarray:
    """``x`` over its causal robust spread: 1.4826 × the median of ``|x|`` over the previous ``span`` steps.

    0 until three earlier values exist; the spread is floored at 1e-3 units.
    """
    spread = pd.Series(np.abs(x)).shift(1).rolling(span, min_periods=3).median().to_numpy()
    z = x / np.maximum(1.4826 * spread, 1e-3)
    return np.where(np.isfinite(z), z, 0.0)


def _departure(x: np.ndarray, span: int = ROBUST_SPAN) -> np.ndarray:
    """``x`` minus its causal level: the median of the previous ``span`` values (0 before three exist).

    A slow offset between two sensors (a mounting tilt, a scale error) stays in
    the level; a fault that starts now departs from it.
    """
    level = pd.Series(x).shift(1).rolling(span, min_periods=3).median().to_numpy()
    d = x - level
    return np.where(np.isfinite(d), d, 0.0)


def _held(x: np.ndarray, cap: int = ROBUST_SPAN) -> np.ndarray:
    """Steps the reading has repeated exactly, up to ``cap``: what a stuck sensor does."""
    same = np.r_[False, np.diff(x) == 0.0]
    run = np.zeros(x.size)
    for i in np.flatnonzero(same):
        run[i] = run[i - 1] + 1.0
    return np.minimum(run, cap)


def _evidence(z: np.ndarray) -> list[np.ndarray]:
    """Causal means of ``z`` over the last :data:`EVIDENCE_SPANS` steps."""
    s = pd.Series(z)
    return [s.rolling(k, min_periods=1).mean().to_numpy() for k in EVIDENCE_SPANS]


def signed_log(x: np.ndarray) -> np.ndarray:
    """``sign(x) · log(1 + |x|)``: keeps small values, tames fault-sized outliers for the scaler."""
    out: np.ndarray = np.sign(x) * np.log1p(np.abs(x))
    return out


def cross_names(inputs: str) -> tuple[str, ...]:
    """Names of the cross-channel consistency residuals for an input kind."""
    if inputs == "sensor-fix":
        return ("dspeed_dt_minus_accel", "speed_minus_speed_fix", "dspeed_fix_dt_minus_accel")
    return ("dspeed_dt_minus_accel",)


def rema_names(inputs: str) -> tuple[str, ...]:
    """What REMA runs on, in the order of a model's ``rema`` settings: the channels, then the residuals."""
    return (*input_names(inputs), *cross_names(inputs))


def feature_width(inputs: str) -> int:
    """Columns of :func:`channel_features` for an input kind."""
    return len(input_names(inputs)) * (N_CHANNEL + N_RAW) + len(cross_names(inputs)) * N_CROSS


def _cross(values: dict[str, np.ndarray], dt: np.ndarray, inputs: str) -> list[np.ndarray]:
    speed, accel = values["speed"], values["accel_x_mps2"]
    accel_mid = np.r_[accel[0], 0.5 * (accel[1:] + accel[:-1])]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = [_step(speed) / dt - accel_mid]
        if inputs == "sensor-fix":
            fix = values["speed_fix_mps"]
            speed_mid = np.r_[speed[0], 0.5 * (speed[1:] + speed[:-1])]
            accel_prev = np.r_[accel[0], accel[:-1]]
            out += [speed_mid - fix, _step(fix) / dt - accel_prev]
    return [np.where(np.isfinite(c), c, 0.0) for c in out]


def channel_signals(segment: Segment, inputs: str = "sensor") -> dict[str, np.ndarray]:
    """What REMA runs on (:func:`rema_names`): each channel (missing readings carried forward)
    and each consistency residual (undefined ones 0)."""
    n = len(segment.t)
    period = float(segment.t[1] - segment.t[0]) if n > 1 and segment.t[1] > segment.t[0] else 1.0
    names = input_names(inputs)
    values = {name: _filled(segment.values[:, k]) for k, name in enumerate(names)}
    dt = np.r_[period, np.diff(segment.t)]
    dt = np.where(dt > 0, dt, np.nan)
    cross = dict(zip(cross_names(inputs), _cross(values, dt, inputs), strict=True))
    return {**values, **cross}


def _ms_sw(x: np.ndarray, period: float, features: FeatureParams, rema: RemaParams) -> np.ndarray:
    """REMA + the 11 MS-SW features of one 1-D signal."""
    n = x.size
    long_n, short_n = features.points(period)
    zeros, nan = np.zeros(n), np.full(n, np.nan)
    out: np.ndarray = features_batch_kernel(
        x, zeros, nan, nan, period, long_n, short_n, rema.to_array(), False
    )[:, :N_CHANNEL]
    return out


def channel_features(
    segment: Segment, features: FeatureParams, rema: Sequence[RemaParams], inputs: str = "sensor"
) -> np.ndarray:
    """(n, :func:`feature_width`) features of one sensor segment, signed-log compressed.

    ``rema``: one setting per :func:`rema_names` entry (channels, then residuals).
    """
    n = len(segment.t)
    period = float(segment.t[1] - segment.t[0]) if n > 1 and segment.t[1] > segment.t[0] else 1.0
    signals = channel_signals(segment, inputs)
    parts = []
    for k, name in enumerate(input_names(inputs)):
        x = signals[name]
        parts.append(_ms_sw(x, period, features, rema[k]))
        step = _step(x)
        level = _departure(x)
        parts.append(np.column_stack([x, step, _robust_z(step), _robust_z(level), _held(x)]))
    first = len(input_names(inputs))
    for j, name in enumerate(cross_names(inputs)):
        r = signals[name]
        d = _departure(r)
        dz = _robust_z(d)
        parts.append(np.column_stack([r, _robust_z(r), d, dz, *_evidence(dz)]))
        parts.append(_ms_sw(r, period, features, rema[first + j]))
    out: np.ndarray = signed_log(np.hstack(parts))
    return out


@dataclass(frozen=True)
class ChannelGradModel:
    gru: GRUModel
    threshold: float
    features: FeatureParams
    rema: tuple[RemaParams, ...]
    inputs: str = "sensor"
    max_gap_s: float = 5.0


class ChannelGradDetector(BatchBaseline):
    """Batch channel GRAD detector over fixes carrying the sensor channels of its input kind."""

    def __init__(self, model: ChannelGradModel) -> None:
        self.model = model

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        m = self.model
        segs, reason = segments(fixes, m.inputs, m.max_gap_s)
        n = len(fixes)
        score = np.full(n, np.nan)
        bias = np.full(n, None, dtype=object)
        names = np.array(SENSOR_BIAS_CLASSES, dtype=object)
        for seg in segs:
            pred = m.gru.predict(channel_features(seg, m.features, m.rema, m.inputs))
            score[seg.rows] = pred.anomaly
            bias[seg.rows] = names[np.argmax(pred.bias, axis=1)]
        anomaly = np.nan_to_num(score) >= m.threshold
        bias = np.where(anomaly, bias, "none")
        bias[reason != ""] = None
        return flags_frame(fixes, reason, score, m.threshold, bias)
