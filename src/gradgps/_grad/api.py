"""``gradgps.detect`` and ``gradgps.clean``: one call, the caller's type back."""

from __future__ import annotations

import os
from typing import Any, Unpack

from .._tracks.track import ColumnKeywords
from .detector import Detector, track_input

__all__ = ["clean", "detect"]


def detect(
    data: Any,
    *,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    **columns: Unpack[ColumnKeywords],
) -> Any:
    """``data`` with the detector's result columns added, in the same type.

    ``data``: a pandas DataFrame (columns found by name or named by keyword,
    e.g. ``time="ts"``; a ``DatetimeIndex`` is the time when no column is), a
    GeoPandas GeoDataFrame (point geometry, any CRS) or a movingpandas
    Trajectory/TrajectoryCollection. Result columns: ``anomaly``, ``score``,
    ``bias_type``, ``time_type``, ``lat_clean``, ``lon_clean``, ``alert``,
    ``invalid_reason``. ``model``/``threshold`` as for :class:`gradgps.Detector`.
    Fault events: ``gradgps.Detector().events(result)``.
    """
    from .._tracks.objects import add_columns

    det = Detector(model, threshold=threshold)
    inp = track_input(data, **columns)
    det._warn_about(inp.fixes)
    return add_columns(inp, det._detect_input(inp))


def clean(
    data: Any,
    *,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    keep_invalid: bool = False,
    **columns: Unpack[ColumnKeywords],
) -> Any:
    """``data`` with every position repaired, same type (see :meth:`gradgps.Detector.clean`)."""
    return Detector(model, threshold=threshold).clean(data, keep_invalid=keep_invalid, **columns)
