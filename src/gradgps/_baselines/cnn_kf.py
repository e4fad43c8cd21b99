"""Baseline ``cnn-kf``: van Wyk et al.'s CNN in front of a Kalman filter with a χ² detector.

What it follows: van Wyk et al. (2020) pass the readings through a CNN that
detects anomalous ones; those are removed before the Kalman filter, whose χ²
detector then catches what the CNN missed. Here: the ``cnn`` baseline's
network (:mod:`gradgps._baselines.window`) judges every reading; readings it
flags are *forced* in the ``kf`` filter (:mod:`gradgps._baselines.kalman`): flagged,
replaced by the prediction, never used to update; the filter's χ² test
judges the rest. A reading is anomalous when either stage flags it; the
score is the larger of the two stages' scores.

Where it simplifies: the CNN and the filter are the separately trained
``cnn`` and ``kf`` baselines, except that the filter's χ² threshold is tuned
again on validation *with* the CNN in front (the combination's own best
threshold). Batch only needs the CNN's probabilities per segment first,
because the CNN reads raw readings, never the filter's output; streaming
runs both per reading and gives the same numbers.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from .._result import PointResult
from .base import Reading, StreamingBaseline, state_error
from .kalman import KalmanDetector, KalmanParams, filter_result, kf_segment
from .window import WindowClassifier, WindowModel

__all__ = ["CnnKalmanDetector"]


class CnnKalmanDetector(StreamingBaseline):
    """CNN flags first, then the Kalman filter and χ² test on what the CNN let through."""

    def __init__(self, cnn: WindowModel, kalman: KalmanParams) -> None:
        self.cnn = cnn
        self.kalman = kalman
        self._cnn_stream = WindowClassifier(cnn)
        self._kf_stream = KalmanDetector.from_params(kalman)

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        segs, reason, probs = WindowClassifier(self.cnn).segment_flags(fixes)
        k = self.kalman
        q, r = np.array(k.q), np.array(k.r)
        cnn_flags = [p >= self.cnn.threshold for p in probs]
        outs = [
            kf_segment(seg, q, r, k.threshold, k.joint, flag)
            for seg, flag in zip(segs, cnn_flags, strict=True)
        ]
        return filter_result(
            fixes, k, segs, reason, outs, cnn_flags, [p.astype(np.float64) for p in probs]
        )

    def _stream_last_t(self) -> float | None:
        return self._cnn_stream._stream_last_t()

    def _update_valid(self, fix: Reading) -> PointResult:
        """One usable reading of this detector's track: CNN verdict, then the filter with it forced."""
        c = self._cnn_stream._update_valid(fix)
        k = self._kf_stream.step_valid(fix, forced=bool(c.anomaly))
        return replace(k, score=max(k.score, c.score))

    def get_state(self) -> dict[str, Any]:
        return {"cnn": self._cnn_stream.get_state(), "kf": self._kf_stream.get_state()}

    def set_state(self, state: Mapping[str, Any]) -> CnnKalmanDetector:
        """Restore :meth:`get_state` output; a bad state leaves this detector as it was."""
        try:
            cnn, kf = state["cnn"], state["kf"]
        except (KeyError, TypeError) as exc:
            raise state_error("cnn-kf", exc) from exc
        before = self._cnn_stream.get_state()
        self._cnn_stream.set_state(cnn)
        try:
            self._kf_stream.set_state(kf)
        except Exception:
            self._cnn_stream.set_state(before)
            raise
        return self
