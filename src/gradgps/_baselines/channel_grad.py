"""GRAD for scalar sensor channels: what ``grad`` means under protocol ``sensor-grid``.

The paper's comparison table corrupts sensor readings (speed, acceleration,
yaw rate), not positions, so the position pipeline of :class:`gradgps.Detector`
has nothing to look at there. GRAD's statistical core works on any 1-D
channel, so the channel-wise GRAD is the same method on other inputs:

per channel (``speed``, ``accel_x_mps2``, ``gyro_z_dps``) REMA + the MS-SW
features of :mod:`gradgps._grad.features` (the 11 per-channel features, no
cross-channel cues) -> the three channels' features side by side -> the same
stacked GRU (32, 16) with an anomaly head and a bias-type head over the
sensor-grid classes ``none``, ``instant``, ``constant``, ``bias``, ``drift``,
trained by :func:`gradgps._train.baselines.dataset_channel_grad`
with :func:`gradgps._train.torch_gru.train_model` (stream mode, early stopping
on validation F1, 3-minute budget, the same injection seeds as GRAD, the
``mixed`` row), threshold tuned on validation.

Where it differs from position GRAD: no offset tracker, time classifier or
recovery (the protocol scores detection and type only), REMA with its
paper defaults in channel units, and batch inference only (the benchmark
measures ``detect``; the position GRAD is the streaming product). A missing
reading is carried forward from the previous one (0 at a segment start).
The features use the numba kernel of the position features with the second
(north) channel fed zeros and dropped: the same code GRAD runs, at twice
the arithmetic it needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._grad.features import N_CHANNEL, FeatureParams, features_batch_kernel
from .._grad.gru import GRUModel
from .._grad.rema import RemaParams
from .base import BatchBaseline, Segment, flags_frame, segments

__all__ = ["SENSOR_BIAS_CLASSES", "ChannelGradDetector", "ChannelGradModel", "channel_features"]

SENSOR_BIAS_CLASSES = ("none", "instant", "constant", "bias", "drift")


def _filled(x: np.ndarray) -> np.ndarray:
    """Missing readings carried forward (0 before the first reading)."""
    s = pd.Series(x).ffill().fillna(0.0)
    return np.ascontiguousarray(s.to_numpy(np.float64))


def channel_features(segment: Segment, features: FeatureParams, rema: RemaParams) -> np.ndarray:
    """(n, 11 C) per-channel REMA + MS-SW features of one sensor segment."""
    n = len(segment.t)
    period = float(segment.t[1] - segment.t[0]) if n > 1 and segment.t[1] > segment.t[0] else 1.0
    long_n, short_n = features.points(period)
    zeros, nan = np.zeros(n), np.full(n, np.nan)
    parts = [
        features_batch_kernel(
            _filled(segment.values[:, k]),
            zeros,
            nan,
            nan,
            period,
            long_n,
            short_n,
            rema.to_array(),
            False,
        )[:, :N_CHANNEL]
        for k in range(segment.values.shape[1])
    ]
    return np.hstack(parts)


@dataclass(frozen=True)
class ChannelGradModel:
    gru: GRUModel
    threshold: float
    features: FeatureParams
    rema: RemaParams
    max_gap_s: float = 5.0


class ChannelGradDetector(BatchBaseline):
    """Batch channel-wise GRAD detector over fixes carrying the three sensor channels."""

    def __init__(self, model: ChannelGradModel) -> None:
        self.model = model

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        m = self.model
        segs, reason = segments(fixes, "sensor", m.max_gap_s)
        n = len(fixes)
        score = np.full(n, np.nan)
        bias = np.full(n, None, dtype=object)
        names = np.array(SENSOR_BIAS_CLASSES, dtype=object)
        for seg in segs:
            pred, _ = m.gru.predict_stream(channel_features(seg, m.features, m.rema))
            score[seg.rows] = pred.anomaly
            bias[seg.rows] = names[np.argmax(pred.bias, axis=1)]
        anomaly = np.nan_to_num(score) >= m.threshold
        bias = np.where(anomaly, bias, "none")
        bias[reason != ""] = None
        return flags_frame(fixes, reason, score, m.threshold, bias)
