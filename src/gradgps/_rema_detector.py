"""``RemaDetector``: the statistical GRAD pipeline as a batch detector (no GRU).

``detect(fixes)``: preprocess -> per segment :func:`gradgps._core_pipeline.core_batch`
(REMA on east and north, anomaly if either flags, time type, recovery) ->
one result row per input row (``Prepared.to_rows``), with the columns of the
detector interface in ``docs/architecture.md``. REMA cannot tell bias types
apart, so ``bias_type`` is ``unknown`` for anomalies and ``none`` otherwise.
Recovered positions go back to degrees through the track's own frame. Rows
that are not usable fixes get ``anomaly=0``, NaN clean positions and their
``invalid_reason``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from ._core_pipeline import CoreParams, core_batch
from ._features import FeatureParams
from ._preprocess import preprocess
from ._recovery import RecoveryParams
from ._rema import RemaParams
from ._time_classifier import TIME_TYPES, TimeParams

__all__ = ["RemaDetector"]


@dataclass
class RemaDetector:
    """Batch REMA detector; parameters as in :class:`CoreParams` plus ``max_gap_s`` for preprocessing.

    The default REMA parameters are the best of the few measured in
    ``benchmarks/rema_quality.py`` (trend mode, 5 m floor, sensitivity 4),
    not yet a full grid search (``tune_rema``).
    """

    rema: RemaParams = field(default_factory=lambda: RemaParams(mode="trend", min_margin=5.0,
                                                                   sensitivity=4.0))
    time: TimeParams = field(default_factory=TimeParams)
    recovery: RecoveryParams = field(default_factory=RecoveryParams)
    feed_recovered: bool = True
    max_gap_s: float = 5.0

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        prepared = preprocess(fixes, max_gap_s=self.max_gap_s)
        pts = prepared.points
        n = len(pts)
        flag = np.zeros(n, dtype=np.int8)
        code = np.zeros(n, dtype=np.int8)
        alert = np.zeros(n, dtype=np.int8)
        score = np.zeros(n)
        lat_clean = np.full(n, np.nan)
        lon_clean = np.full(n, np.nan)
        base = CoreParams(rema=self.rema, features=FeatureParams(speed_heading=False),
                          time=self.time, recovery=self.recovery,
                          feed_recovered=self.feed_recovered)
        columns = {c: pts[c].to_numpy(dtype=np.float64) for c in ("t", "east", "north")}
        for c in ("speed", "heading"):
            if c in pts.columns:
                columns[c] = pts[c].to_numpy(dtype=np.float64)
        tracks = pts["track"].to_numpy(dtype=object)
        for _, sl in prepared.segment_slices():
            track = str(tracks[sl.start])
            params = replace(base, period=prepared.nominal_period[track])
            out = core_batch(columns["east"][sl], columns["north"][sl], params,
                             speed=columns.get("speed", np.full(n, np.nan))[sl],
                             heading=columns.get("heading", np.full(n, np.nan))[sl])
            flag[sl], code[sl], alert[sl], score[sl] = out.flag, out.time_code, out.alert, out.score
            lat_clean[sl], lon_clean[sl] = prepared.frames[track].to_geodetic(
                out.east_clean, out.north_clean)
        names = np.array(TIME_TYPES, dtype=object)
        anomaly = prepared.to_rows(flag, fill=0).astype(np.int8)
        result = pd.DataFrame(
            {
                "anomaly": anomaly,
                "score": prepared.to_rows(score, fill=0.0).astype(np.float64),
                "bias_type": np.where(anomaly == 1, "unknown", "none").astype(object),
                "time_type": prepared.to_rows(names[code], fill="none"),
                "lat_clean": prepared.to_rows(lat_clean).astype(np.float64),
                "lon_clean": prepared.to_rows(lon_clean).astype(np.float64),
                "alert": prepared.to_rows(alert, fill=0).astype(np.int8),
                "invalid_reason": prepared.row_reason,
            },
            index=fixes.index,
        )
        return result
