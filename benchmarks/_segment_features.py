"""The pipeline's features per segment of a table of fixes, in metres and seconds.

For the scripts that read what the detector's network sees (``tried/error_places.py``,
``tried/simulated_trace.py``, ``tried/tracker_accuracy.py``, ``tried/latch_members.py``,
``tried/tracker_knew.py``, ``tried/gnss_trace.py``);
never the test splits.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pandas as pd

from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import grad_features


def segment_features(
    det: Detector, fixes: pd.DataFrame, decompress: bool = True
) -> Iterator[tuple[np.ndarray, pd.DataFrame, np.ndarray]]:
    """Per segment of each track of ``fixes`` (``to_fixes``' table, positions only): its
    rows (positions in ``fixes``), its prepared points (with ``east``/``north``) and the
    features, decompressed from the network's signed ``log1p`` (or as the network reads
    them, ``decompress=False``), one column per name of
    :func:`gradgps._grad.pipeline.pipeline_feature_names`."""
    track = fixes["track"].to_numpy()
    for name in pd.unique(track):
        rows = np.flatnonzero(track == name)
        _, _, prepared, _ = det._point_outputs(fixes.iloc[rows].reset_index(drop=True))
        for k, sl in prepared.segment_slices():
            pts = prepared.points.iloc[sl]
            t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
            nan = np.full(len(t), np.nan)
            raw = grad_features(
                det.model_.params, prepared.segment_frames[k], t, lat, lon, nan, nan
            )
            values = raw.features
            yield (
                rows[sl],
                pts,
                np.sign(values) * np.expm1(np.abs(values)) if decompress else values,
            )
