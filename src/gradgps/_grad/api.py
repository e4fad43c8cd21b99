"""``gradgps.detect`` and ``gradgps.clean``: one call, the caller's type back."""

from __future__ import annotations

import os
from typing import Any

from .detector import Detector, track_input

__all__ = ["clean", "detect"]


def detect(
    data: Any,
    *,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    time: str | None = None,
    lat: str | None = None,
    lon: str | None = None,
    track: str | None = None,
    speed: str | None = None,
    heading: str | None = None,
    alt: str | None = None,
    hdop: str | None = None,
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
    inp = track_input(data, time, lat, lon, track, speed, heading, alt, hdop)
    result = det.detect_fixes(inp.fixes)
    result.index = inp.index
    return add_columns(inp, result)


def clean(
    data: Any,
    *,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    keep_invalid: bool = False,
    time: str | None = None,
    lat: str | None = None,
    lon: str | None = None,
    track: str | None = None,
    speed: str | None = None,
    heading: str | None = None,
    alt: str | None = None,
    hdop: str | None = None,
) -> Any:
    """``data`` with every position repaired, same type (see :meth:`gradgps.Detector.clean`)."""
    return Detector(model, threshold=threshold).clean(
        data,
        keep_invalid=keep_invalid,
        time=time,
        lat=lat,
        lon=lon,
        track=track,
        speed=speed,
        heading=heading,
        alt=alt,
        hdop=hdop,
    )
