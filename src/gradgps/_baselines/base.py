"""What the comparison baselines (``kf``, ``cnn``, ``cnn-kf``, ``lstm-cnn``) share: their input.

The paper compares GRAD with detectors built for *sensor* readings (van Wyk
et al. 2020; Javed et al. 2021). To run them on the same data as GRAD, every
baseline reads one of two kinds of input, chosen by the benchmark protocol:

* ``position`` (protocol ``grad``): a track's fixes in its own tangent plane
  (``LocalFrame`` at its first usable fix), east and north in metres: two
  channels, which is how a Kalman filter or a network sees a position;
* ``sensor`` (protocol ``sensor-grid``): the scalar readings ``speed`` (m/s),
  ``accel_x_mps2`` (m/s²) and ``gyro_z_dps`` (deg/s), as in the source papers;
* ``sensor-fix``: the same plus ``speed_fix_mps``, the speed derived from the
  fixes (:func:`gradgps._data.inject.with_fix_speed`): a second speed sensor
  beside the reported speed, as SPMD has two (protocol option ``fix_speed``).

A track is cut into *segments* at gaps longer than ``max_gap_s`` (what
preprocessing does for GRAD): nothing before a long dropout says anything
about the readings after it, so each segment starts a fresh filter or window.
Unlike GRAD's preprocessing, rows are never merged: repeated timestamps are
kept as readings ``dt = 0`` apart, so every input row gets its own verdict.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._exceptions import ConfigError
from .._result import PointResult
from .._tracks.geo import LocalFrame
from .._tracks.preprocess import invalid_reasons

__all__ = [
    "INPUTS",
    "SENSOR_CHANNELS",
    "SENSOR_FIX_CHANNELS",
    "Segment",
    "input_names",
    "result_frame",
    "segments",
]

INPUTS = ("position", "sensor", "sensor-fix")
SENSOR_CHANNELS = ("speed", "accel_x_mps2", "gyro_z_dps")
SENSOR_FIX_CHANNELS = ("speed", "speed_fix_mps", "accel_x_mps2", "gyro_z_dps")


def unusable_fix(t: float, lat: float, lon: float) -> PointResult | None:
    """The baselines' verdict on a fix they cannot use (not flagged), or None if usable."""
    usable = (
        math.isfinite(t)
        and math.isfinite(lat)
        and math.isfinite(lon)
        and abs(lat) <= 90.0
        and abs(lon) <= 180.0
    )
    if usable:
        return None
    return PointResult(
        0,
        math.nan,
        None,
        None,
        math.nan,
        math.nan,
        0,
        invalid_reason="time, latitude or longitude unusable",
    )


def input_names(inputs: str) -> tuple[str, ...]:
    """The channel names of an input kind, in the order of :attr:`Segment.values` columns."""
    if inputs == "position":
        return ("east", "north")
    if inputs == "sensor":
        return SENSOR_CHANNELS
    if inputs == "sensor-fix":
        return SENSOR_FIX_CHANNELS
    raise ConfigError(f"unknown input kind {inputs!r}; choose one of {', '.join(INPUTS)}")


@dataclass(frozen=True)
class Segment:
    """Readings of one track between long gaps, in time order.

    ``rows``: positions (0..n-1) of these readings in the input frame;
    ``values``: (n, C) float64, the channels of :func:`input_names` (NaN
    where a sensor reading is missing); ``frame``: the track's tangent plane.
    """

    track: str
    rows: np.ndarray
    t: np.ndarray
    values: np.ndarray
    frame: LocalFrame


def segments(
    fixes: pd.DataFrame, inputs: str, max_gap_s: float = 5.0
) -> tuple[list[Segment], np.ndarray]:
    """Cut canonical fixes into :class:`Segment` s; also return each row's ``invalid_reason``.

    Rows that are not usable fixes (time, latitude or longitude missing or out
    of range) belong to no segment.
    """
    names = input_names(inputs)
    if inputs != "position":
        missing = [c for c in names if c not in fixes.columns]
        if missing:
            raise ConfigError(
                f"sensor baselines need columns {list(names)} in the fixes, missing {missing}; "
                "pass them as channels to to_fixes (gradgps bench does under protocol sensor-grid)"
            )
    reason = invalid_reasons(fixes)
    usable = np.flatnonzero(reason == "")
    tracks = fixes["track"].to_numpy(dtype=object)
    t = fixes["t"].to_numpy(dtype=np.float64)
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    channels = (
        None
        if inputs == "position"
        else fixes[list(names)].to_numpy(dtype=np.float64, na_value=np.nan)
    )
    order = usable[np.lexsort((t[usable], pd.factorize(tracks[usable])[0]))]
    out: list[Segment] = []
    if order.size == 0:
        return out, reason
    track_change = np.flatnonzero(tracks[order][1:] != tracks[order][:-1]) + 1
    for rows in np.split(order, track_change):
        frame = LocalFrame(float(lat[rows[0]]), float(lon[rows[0]]))
        if channels is None:
            east, north = frame.to_local(lat[rows], lon[rows])
            values = np.column_stack([east, north])
        else:
            values = channels[rows]
        cuts = np.flatnonzero(np.diff(t[rows]) > max_gap_s) + 1
        for piece, vals in zip(np.split(rows, cuts), np.split(values, cuts), strict=True):
            out.append(
                Segment(str(tracks[rows[0]]), piece, t[piece], np.ascontiguousarray(vals), frame)
            )
    return out, reason


def result_frame(
    fixes: pd.DataFrame,
    reason: np.ndarray,
    anomaly: np.ndarray,
    score: np.ndarray,
    lat_clean: np.ndarray,
    lon_clean: np.ndarray,
    bias_type: Sequence[str | None] | np.ndarray | None = None,
) -> pd.DataFrame:
    """The detector-interface frame (docs/architecture.md) from per-row arrays.

    Baselines do not classify time types, and only name a bias type when
    ``bias_type`` is given: what they do not produce stays missing (``None``).
    Unusable rows get ``anomaly=0`` and their reason, as in the speed gate.
    """
    n = len(fixes)
    return pd.DataFrame(
        {
            "anomaly": np.asarray(anomaly, dtype=np.int8),
            "score": np.asarray(score, dtype=np.float64),
            "bias_type": np.full(n, None, dtype=object)
            if bias_type is None
            else np.asarray(bias_type, dtype=object),
            "time_type": np.full(n, None, dtype=object),
            "lat_clean": np.asarray(lat_clean, dtype=np.float64),
            "lon_clean": np.asarray(lon_clean, dtype=np.float64),
            "alert": np.zeros(n, dtype=np.int8),
            "invalid_reason": reason,
        },
        index=fixes.index,
    )
