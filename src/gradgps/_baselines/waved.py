"""Baseline ``waved``: a weighted, fine-tuned ensemble after Javed et al. (2021).

What it follows: Javed et al. pair their MSALSTM-CNN with WAVED, an
ensemble that averages the anomaly probabilities of several fine-tuned
networks with weights adjusted on held-out data, then thresholds the
average. Here the members are the two window networks this project trains
the same way on the same data: ``cnn`` (:mod:`gradgps._baselines.cnn`) and
``lstm-cnn`` (Javed et al.'s ML-C, :mod:`gradgps._baselines.lstm_cnn`), each
fine-tuned on the experiment's training data (under per-row experiments, on
that row). The ensemble probability is ``w · p_cnn + (1 - w) · p_lstm_cnn``;
``w`` (grid 0, 0.1, ..., 1) and the threshold are the pair with the best
anomaly F1 on the validation split
(:func:`gradgps._train.baselines.dataset_waved`).

Where it simplifies: two members (the source paper's member networks and
their count are not reproduced), one weight per member rather than per
class, batch ``detect`` only (the benchmark measures ``detect``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pandas as pd

from .base import BatchBaseline, Segment, flags_frame, segments

__all__ = ["WAVED_WEIGHTS", "Member", "WavedDetector", "WavedModel", "ensemble_probability"]

#: The member weight grid searched on validation.
WAVED_WEIGHTS = tuple(np.round(np.linspace(0.0, 1.0, 11), 2).tolist())


class Member(Protocol):
    """What the ensemble needs of a member: a :class:`gradgps._baselines.window.WindowModel`."""

    @property
    def inputs(self) -> str: ...

    @property
    def max_gap_s(self) -> float: ...

    def segment_probability(self, segment: Segment) -> np.ndarray: ...


@dataclass(frozen=True)
class WavedModel:
    """The two members, the weight of the first, and the anomaly threshold."""

    cnn: Member
    lstm_cnn: Member
    weight: float
    threshold: float


def ensemble_probability(p_cnn: np.ndarray, p_lstm_cnn: np.ndarray, weight: float) -> np.ndarray:
    """The weighted average of the members' anomaly probabilities."""
    out: np.ndarray = weight * np.asarray(p_cnn, np.float64) + (1.0 - weight) * np.asarray(
        p_lstm_cnn, np.float64
    )
    return out


class WavedDetector(BatchBaseline):
    """Batch WAVED detector: both members judge every reading, the weighted mean decides."""

    def __init__(self, model: WavedModel) -> None:
        self.model = model

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        m = self.model
        segs, reason = segments(fixes, m.cnn.inputs, m.cnn.max_gap_s)
        score = np.full(len(fixes), np.nan)
        for seg in segs:
            score[seg.rows] = ensemble_probability(
                m.cnn.segment_probability(seg), m.lstm_cnn.segment_probability(seg), m.weight
            )
        return flags_frame(fixes, reason, score, m.threshold)
