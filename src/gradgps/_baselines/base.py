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

Every baseline derives from :class:`BatchBaseline` (batch ``detect``) or
:class:`StreamingBaseline` (also :class:`FixStream`'s ``update``, and
``get_state``/``set_state``),
which validate the input once and apply the invalid-row policy of
:mod:`gradgps._result`, then delegate to the detector's own
``_detect_core`` / ``_update_valid`` (as darts' detectors and movingpandas'
cleaners do). A stream's fix whose time is before the previous usable fix
is invalid (flagged, never used); a repeated time is a reading ``dt = 0``
after the previous one, as in batch.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError
from .._result import (
    RESULT_COLUMNS,
    RESULT_DTYPES,
    PointResult,
    as_number,
    decode_floats,
    fix_reason,
    invalid_reasons,
    reading,
    result_frame,
)
from .._tracks.geo import LocalFrame
from .._tracks.track import track_rows

__all__ = [
    "INPUTS",
    "SENSOR_CHANNELS",
    "SENSOR_FIX_CHANNELS",
    "BatchBaseline",
    "FixStream",
    "Reading",
    "Segment",
    "StreamingBaseline",
    "input_names",
    "segments",
]

INPUTS = ("position", "sensor", "sensor-fix")
SENSOR_CHANNELS = ("speed", "accel_x_mps2", "gyro_z_dps")
SENSOR_FIX_CHANNELS = ("speed", "speed_fix_mps", "accel_x_mps2", "gyro_z_dps")
_REQUIRED = ("track", "t", "lat", "lon")


@dataclass(frozen=True)
class Reading:
    """A usable fix as a baseline's stream sees it: optional readings NaN when absent."""

    t: float
    lat: float
    lon: float
    speed: float = np.nan
    heading: float = np.nan
    channels: Mapping[str, float] = field(default_factory=dict)

    def sensor_values(self, inputs: str = "sensor") -> list[float]:
        """The sensor channels of ``inputs`` in :func:`input_names` order (NaN if absent)."""
        readings = {"speed": self.speed, **self.channels}
        return [float(readings.get(c, np.nan)) for c in input_names(inputs)]


class BatchBaseline(ABC):
    """A baseline's batch face: ``detect`` checks the input, runs ``_detect_core``, checks the output."""

    @abstractmethod
    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """One result row per row of ``fixes`` (built with :func:`gradgps._result.result_frame`)."""

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """One result row per input row, same index, for canonical fixes of any tracks in any order."""
        missing = [c for c in _REQUIRED if c not in fixes.columns]
        if missing:
            raise ConfigError(
                f"{type(self).__name__}.detect needs canonical fixes with columns "
                f"{list(_REQUIRED)}, missing {missing}; build them with gradgps.to_fixes"
            )
        result = self._detect_core(fixes)
        if len(result) != len(fixes) or list(result.columns) != list(RESULT_COLUMNS):
            raise AssertionError(f"{type(self).__name__} broke the result schema")
        out = result.astype(RESULT_DTYPES)
        out.index = fixes.index
        return out


class FixStream(ABC):
    """One track's fixes, one at a time: ``update`` validates, ``_update_valid`` judges.

    Every streaming baseline and streaming peer is one, so a fix is checked
    in one place, by the rule of :func:`gradgps._result.fix_reason`.
    Subclasses keep the time of their last usable fix in ``_last_t`` (``None``
    before the first and after a reset) and implement ``_update_valid``.
    """

    _last_t: float | None = None

    def _stream_last_t(self) -> float | None:
        return self._last_t

    def update(
        self,
        t: float,
        lat: float,
        lon: float,
        speed: float | None = None,
        heading: float | None = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
        **channels: float,
    ) -> PointResult:
        """Judge one fix of this detector's track; never raises on bad values.

        Unusable fixes (time, latitude or longitude missing, not a number, out
        of range, time before the previous usable fix, or a fix the receiver
        reports as no fix through ``fix_quality`` or ``satellites``) are
        flagged with their reason and change nothing. Optional readings that
        are missing or not numbers count as absent (NaN).
        """
        t_f, lat_f, lon_f = as_number(t), as_number(lat), as_number(lon)
        reason = fix_reason(
            t_f,
            lat_f,
            lon_f,
            self._stream_last_t(),
            fix_quality=fix_quality,
            satellites=satellites,
        )
        if reason:
            return PointResult.invalid(reason, classifies=False)
        extra = {name: reading(value) for name, value in channels.items()}
        return self._update_valid(
            Reading(t_f, lat_f, lon_f, reading(speed), reading(heading), extra)
        )

    @abstractmethod
    def _update_valid(self, fix: Reading) -> PointResult:
        """Judge a usable fix (finite, in range, in time order)."""


class StreamingBaseline(BatchBaseline, FixStream):
    """A baseline that also streams one track (:class:`FixStream`) and saves its memory:
    subclasses implement ``_update_valid``, ``get_state`` and ``set_state``."""

    @abstractmethod
    def get_state(self) -> dict[str, Any]:
        """The stream's memory as strict-JSON-able data."""

    @abstractmethod
    def set_state(self, state: Mapping[str, Any]) -> StreamingBaseline:
        """Restore :meth:`get_state` output (``ConfigError`` if it is not one); returns self."""


def flags_frame(
    fixes: pd.DataFrame,
    reason: np.ndarray,
    score: np.ndarray,
    threshold: float,
    bias_type: np.ndarray | None = None,
) -> pd.DataFrame:
    """The result of a classifier that repairs nothing: anomaly where ``score`` reaches
    ``threshold``, the input position as the clean one."""
    return result_frame(
        fixes.index,
        reason,
        anomaly=np.nan_to_num(score) >= threshold,
        score=score,
        lat_clean=fixes["lat"].to_numpy(np.float64),
        lon_clean=fixes["lon"].to_numpy(np.float64),
        bias_type=bias_type,
    )


def load_time(value: Any) -> float | None:
    """A stored time: ``None`` or a finite number of seconds."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise ValueError(f"a time must be a finite number, got {value!r}")
    return float(value)


def load_frame(value: Any) -> LocalFrame | None:
    """A stored tangent plane: ``None`` or ``[lat0, lon0]`` of a usable fix."""
    if value is None:
        return None
    origin = decode_floats(value)
    assert origin is not None
    if len(origin) != 2 or fix_reason(0.0, origin[0], origin[1]):
        raise ValueError(f"a frame is [lat0, lon0] of a usable fix, got {value!r}")
    return LocalFrame(origin[0], origin[1])


def state_error(what: str, exc: Exception) -> ConfigError:
    """The error for a state that is not one :meth:`get_state` wrote."""
    return ConfigError(
        f"not a {what} state ({type(exc).__name__}: {exc}); pass what get_state() returned"
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
    tracks = fixes["track"].to_numpy(dtype=object)
    t = fixes["t"].to_numpy(dtype=np.float64)
    lat = fixes["lat"].to_numpy(dtype=np.float64)
    lon = fixes["lon"].to_numpy(dtype=np.float64)
    channels = (
        None
        if inputs == "position"
        else fixes[list(names)].to_numpy(dtype=np.float64, na_value=np.nan)
    )
    out: list[Segment] = []
    for rows in track_rows(fixes, reason == ""):
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
