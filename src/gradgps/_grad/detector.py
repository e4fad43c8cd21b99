"""``gradgps.Detector``: GRAD for one vehicle's live stream, or for whole tables of tracks.

Two faces, one computation (:mod:`gradgps._grad.pipeline`):

* streaming, river style: ``update(t, lat, lon, speed=None, heading=None)``
  per fix of *one* track returns a :class:`~gradgps._result.PointResult`;
  ``get_state()`` / ``set_state()`` move the whole state as plain JSON-able
  data (checkpoint, restore in another process, continue);
* batch: ``detect(frame)`` for any number of tracks returns one result row
  per input row, in input order.

Both read each track in row order with one rule and give the same numbers
bit for bit (tested), whatever the order of the input: batch runs the same
compiled per-fix step on the fixes a stream would use. A fix whose time is
not at least :data:`MIN_STEP_S` (1 ms) after the previous usable fix of its
track (a repeated or backward timestamp) is *invalid* in both: flagged with a
reason, never merged or averaged with its neighbours, never used.

Invalid fixes (time, latitude or longitude missing, not finite or out of
range; a repeated or backward time) come back with
``anomaly=1``, ``invalid_reason`` saying why, NaN score and clean position,
and never touch the detector's state. Speed and heading are optional: a
missing, non-numeric or infinite reading is treated as absent (NaN), and the
fix is still used. A gap longer than the model's
``max_gap_s`` starts a new segment: every state is reset, because nothing
learnt before a long dropout says anything about the fixes after it.

A segment's first fix is scored before its sampling period is known; when
the second fix arrives the segment is rebuilt with the period (its first time
step) and the first fix replayed. The first fix's own verdict cannot change
by this: with one point, no feature depends on the period.

``gradgps.MultiTrackDetector`` (below) keeps one streaming Detector per track id.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._exceptions import ConfigError, GradGPSError, ModelError
from .._result import (
    RESULT_DTYPES,
    PointResult,
    as_number,
    decode_floats,
    encode_floats,
    fix_reason,
    reading,
    result_frame,
    results_frame,
)
from .._tracks.geo import LocalFrame
from .._tracks.preprocess import stream_reasons
from .defaults import MIN_STEP_S, grad_points
from .events import fault_events
from .model_io import gru_model, load_model
from .pipeline import (
    N_POINT_OUT,
    O_ALERT,
    O_BIAS,
    O_FLAG,
    O_LAT,
    O_LON,
    O_SCORE,
    O_TIME,
    PipelineParams,
    grad_segments,
    grad_step,
    new_state,
    new_work,
    pipeline_feature_names,
)
from .time_classifier import TIME_TYPES

__all__ = [
    "DEFAULT_MODEL",
    "MIN_STEP_S",
    "Detector",
    "GradModel",
    "MultiTrackDetector",
    "load_grad_model",
]

#: Name of the model shipped inside the package, used by ``Detector()``.
DEFAULT_MODEL = "default"


@dataclass(frozen=True)
class GradModel:
    """A loaded GRAD model: packed GRU parameters plus the pipeline settings it was trained with."""

    path: str
    params: PipelineParams
    gru_params: NDArray[np.float32]
    dims: NDArray[np.int64]
    bias_classes: tuple[str, ...]
    checksum: str
    config: Mapping[str, Any]


def _default_model_dir() -> Path:
    return Path(str(resources.files("gradgps") / "models" / DEFAULT_MODEL))


@lru_cache(maxsize=16)
def _load_cached(path: str, mtime_ns: int) -> GradModel:
    weights, config = load_model(path)
    if config.get("mode") != "stream":
        raise ModelError(
            f"{path}: the Detector runs stream-mode models (one GRU step per fix); "
            f"this one is {config.get('mode')!r}. Train it with --mode stream"
        )
    try:
        params = PipelineParams.from_dict(config["features"]["params"]["pipeline"])
        _check_buffers(params)
    except (GradGPSError, KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ModelError(
            f"{path}/config.json: no usable pipeline settings ({exc}); "
            "the model was not trained by gradgps train"
        ) from exc
    names = pipeline_feature_names(params)
    if list(config["features"]["names"]) != names:
        raise ModelError(
            f"{path}/config.json: its features {config['features']['names']} are not "
            f"the ones this version computes ({names}); retrain the model"
        )
    threshold = float(config["thresholds"]["anomaly"])
    params = PipelineParams(**{**params.__dict__, "threshold": threshold})
    try:
        net = gru_model(weights, config)
    except GradGPSError as exc:
        raise ModelError(f"{path}/config.json: {exc}; retrain the model") from exc
    return GradModel(
        path=path,
        params=params,
        gru_params=net.params,
        dims=net.dims,
        bias_classes=tuple(config["class_names"]["bias"]),
        checksum=str(config["weights_sha256"]),
        config=config,
    )


#: Most fixes a feature window may hold (at the fastest rate, 1 kHz): 1,000 s.
_MAX_WINDOW_POINTS = 1_000_000


def _check_buffers(params: PipelineParams) -> None:
    """Refuse settings whose per-segment parameters are not finite numbers or whose buffers
    would not fit in memory, before a stream meets them (a hand-edited config)."""
    long_n, _ = params.features.points(MIN_STEP_S)
    if long_n > _MAX_WINDOW_POINTS:
        raise ValueError(
            f"a {params.features.long_window_s} s window needs {long_n:,} slots "
            f"at 1 kHz, more than {_MAX_WINDOW_POINTS:,}"
        )
    P = params.array(MIN_STEP_S, LocalFrame(0.0, 0.0), np.ones(4, np.int64))
    if P.dtype != np.float64 or not np.isfinite(P).all():
        raise ValueError("a setting is not a finite number")
    new_state(P)


def load_grad_model(model: str | os.PathLike[str] | None = None) -> GradModel:
    """Load (and cache) a model directory; ``None`` means the default model shipped with gradgps."""
    path = _default_model_dir() if model is None else Path(model)
    if not path.is_dir():
        raise ModelError(
            f"{path}: no such model directory; pass a directory written by "
            "'gradgps train' (or nothing, for the default model)"
        )
    resolved = str(path.resolve())
    stamp = max((p.stat().st_mtime_ns for p in path.iterdir()), default=0)
    return _load_cached(resolved, stamp)


_STATE_FORMAT = 2


def _time_number(value: Any) -> float:
    """A fix time as seconds: numbers as they are; datetimes, Timestamps, ISO-8601 strings to unix."""
    if isinstance(value, str | pd.Timestamp | np.datetime64) or hasattr(value, "isoformat"):
        try:
            stamp: Any = pd.Timestamp(value)
        except (TypeError, ValueError):
            return math.nan
        if pd.isna(stamp):
            return math.nan
        if stamp.tzinfo is None:
            stamp = stamp.tz_localize("UTC")
        return float(stamp.value) / 1e9
    return as_number(value)


def _readings(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`gradgps._result.reading` for a whole column."""
    return np.where(np.isfinite(values), values, np.nan)


class Detector:
    """GRAD anomaly detector, classifier and repairer (see the module docstring).

    ``model``: a model directory written by ``gradgps train``; ``None`` uses
    the default model shipped with gradgps (trained on simulated drives).
    ``threshold`` overrides the model's anomaly threshold (P(anomaly) at or
    above it is an anomaly; lower finds more faults and raises more false
    alarms).
    """

    def __init__(
        self, model: str | os.PathLike[str] | None = None, *, threshold: float | None = None
    ) -> None:
        self.model = model
        self.threshold = threshold
        loaded = load_grad_model(model)
        if threshold is not None:
            if not (0.0 < threshold < 1.0):
                raise ConfigError(f"threshold must be in (0, 1), got {threshold}")
            loaded = GradModel(
                **{
                    **loaded.__dict__,
                    "params": PipelineParams(
                        **{**loaded.params.__dict__, "threshold": float(threshold)}
                    ),
                }
            )
        self.model_ = loaded
        self._out = np.zeros(N_POINT_OUT)
        self._reset()

    # -- streaming ---------------------------------------------------------

    def _reset(self) -> None:
        self._frame: LocalFrame | None = None
        self._last_t: float | None = None
        self._P: NDArray[np.float64] | None = None
        self._S: NDArray[np.float64] | None = None
        self._H: NDArray[np.float32] | None = None
        self._work: Any = None
        self._seg_count = 0
        self._first: tuple[float, float, float, float, float] | None = None

    def _new_segment(self, period: float) -> None:
        assert self._frame is not None
        m = self.model_
        self._P = m.params.array(period, self._frame, m.dims)
        self._S = new_state(self._P)
        self._H = np.zeros(int(m.dims[1] + m.dims[2]), np.float32)
        self._work = new_work(self._P)

    def _step(self, dt: float, lat: float, lon: float, speed: float, heading: float) -> None:
        assert self._P is not None
        assert self._S is not None
        if self._work is None:  # restored by set_state: made on the first step
            self._work = new_work(self._P)
        grad_step(
            self._P,
            self._S,
            self._H,
            self.model_.gru_params,
            self._work,
            dt,
            lat,
            lon,
            speed,
            heading,
            self._out,
        )

    def update(
        self,
        t: Any,
        lat: float,
        lon: float,
        speed: float | None = None,
        heading: float | None = None,
        **channels: float,
    ) -> PointResult:
        """Score one fix of this detector's track; returns at once, never raises on bad values.

        ``t``: seconds (unix or relative), or a datetime, ``pandas.Timestamp``
        or ISO-8601 string (naive ones read as UTC).

        ``channels`` (other sensor readings) are accepted for interface
        compatibility and ignored by the position model.
        """
        t_f, lat_f, lon_f = _time_number(t), as_number(lat), as_number(lon)
        reason = fix_reason(t_f, lat_f, lon_f, self._last_t, MIN_STEP_S)
        if reason:
            return PointResult.invalid(reason)
        sp, hd = reading(speed), reading(heading)
        if self._frame is None:
            self._frame = LocalFrame(lat_f, lon_f)
        dt = 0.0 if self._last_t is None else t_f - self._last_t
        if self._last_t is None or dt > self.model_.params.max_gap_s:
            self._seg_count = 0
        if self._seg_count == 0:
            self._new_segment(1.0)
            self._first = (t_f, lat_f, lon_f, sp, hd)
            self._step(0.0, lat_f, lon_f, sp, hd)
        elif self._seg_count == 1:
            assert self._first is not None
            _, lat0, lon0, sp0, hd0 = self._first
            self._new_segment(dt)
            self._step(0.0, lat0, lon0, sp0, hd0)
            self._step(dt, lat_f, lon_f, sp, hd)
        else:
            self._step(dt, lat_f, lon_f, sp, hd)
        self._seg_count += 1
        self._last_t = t_f
        o = self._out
        flag = int(o[O_FLAG])
        return PointResult(
            anomaly=flag,
            score=float(o[O_SCORE]),
            bias_type=self.model_.bias_classes[int(o[O_BIAS])],
            time_type=TIME_TYPES[int(o[O_TIME])],
            lat_clean=float(o[O_LAT]),
            lon_clean=float(o[O_LON]),
            alert=int(o[O_ALERT]),
        )

    def get_state(self) -> dict[str, Any]:
        """Everything needed to continue this stream elsewhere, as plain JSON-able data.

        Strict JSON: non-finite numbers (a missing speed, the time
        classifier's "no earlier run" gap) are written as the strings
        ``"nan"``, ``"inf"``, ``"-inf"``, so ``json.dumps(state,
        allow_nan=False)`` works and any JSON parser reads it back. For bytes,
        ``json.dumps(det.get_state()).encode()``; restoring gives the same
        outputs as an uninterrupted run, bit for bit (floats round-trip
        exactly through JSON).
        """

        return {
            "format": _STATE_FORMAT,
            "model_checksum": self.model_.checksum,
            "threshold": self.model_.params.threshold,
            "frame": None if self._frame is None else [self._frame.lat0, self._frame.lon0],
            "last_t": self._last_t,
            "segment_count": self._seg_count,
            "first": encode_floats(self._first),
            "P": encode_floats(self._P),
            "S": encode_floats(self._S),
            "H": encode_floats(self._H),
        }

    def set_state(self, state: Mapping[str, Any]) -> Detector:
        """Restore a state from :meth:`get_state` (same model); returns self."""
        try:
            if state["format"] != _STATE_FORMAT:
                raise ConfigError(
                    f"detector state format {state['format']!r} is not supported "
                    f"(this gradgps writes format {_STATE_FORMAT})"
                )
            if state["model_checksum"] != self.model_.checksum:
                raise ConfigError(
                    "detector state was saved with another model; "
                    "restore it into a Detector of the same model"
                )
            if float(state["threshold"]) != self.model_.params.threshold:
                raise ConfigError("detector state was saved with another threshold")

            def arr(values: Any, dtype: Any) -> Any:
                decoded = decode_floats(values)
                return None if decoded is None else np.array(decoded, dtype=dtype)

            frame = state["frame"]
            new_frame = None if frame is None else LocalFrame(float(frame[0]), float(frame[1]))
            last_t = None if state["last_t"] is None else float(state["last_t"])
            seg_count = int(state["segment_count"])
            first = state["first"]
            new_first = None if first is None else tuple(decode_floats(first) or ())
            if new_first is not None and len(new_first) != 5:
                raise ValueError(f"'first' holds {len(new_first)} values, expected 5")
            P, S, H = (
                arr(state["P"], np.float64),
                arr(state["S"], np.float64),
                arr(state["H"], np.float32),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise ConfigError(f"not a detector state: {exc}") from exc
        # Assigned only once everything parsed: a bad state leaves this detector as it was.
        self._frame, self._last_t, self._seg_count = new_frame, last_t, seg_count
        self._first = new_first
        self._P, self._S, self._H = P, S, H
        self._work = None
        return self

    # -- batch -------------------------------------------------------------

    def detect(
        self,
        data: Any,
        *,
        threads: int = 1,
        time: str | None = None,
        lat: str | None = None,
        lon: str | None = None,
        track: str | None = None,
        speed: str | None = None,
        heading: str | None = None,
        alt: str | None = None,
        hdop: str | None = None,
    ) -> Any:
        """Flag, classify and repair every fix of ``data``; one result row per input row.

        ``data``: a DataFrame of one or many tracks (canonical fixes, see
        :func:`gradgps.to_fixes`, or any table whose columns are found by
        name or named by keyword: ``time="ts"``, ``lat=``, ``lon=``,
        ``track=``, ``speed=``, ``heading=``; a ``DatetimeIndex`` is the time
        when no column is), a GeoPandas GeoDataFrame (point geometry, any
        CRS), or a movingpandas Trajectory/TrajectoryCollection.

        A DataFrame gives the result columns only (``anomaly``, ``score``,
        ``bias_type``, ``time_type``, ``lat_clean``, ``lon_clean``, ``alert``,
        ``invalid_reason``) on the caller's index, so ``df.join(result)``
        lines up; a GeoDataFrame or trajectory comes back as the same type
        with those columns added (:func:`gradgps.detect` does that for a
        DataFrame too).

        Every track is read in row order, exactly as the streaming
        :meth:`update` reads it: a fix whose time is not after the previous
        usable fix of its track (a repeated or backward timestamp) is
        unusable, flagged with its reason, and never merged or averaged, so
        the whole file, chunks, ``--follow`` and this method give the same
        rows flagged and the same clean positions. ``threads`` > 1 spreads
        segments over that many numba threads (same numbers).
        """
        from .._tracks.objects import add_columns, as_track_input

        columns = dict(
            time=time,
            lat=lat,
            lon=lon,
            track=track,
            speed=speed,
            heading=heading,
            alt=alt,
            hdop=hdop,
        )
        inp = as_track_input(data, columns)
        result = self.detect_fixes(inp.fixes, threads=threads)
        result.index = inp.index
        if inp.kind == "frame":
            return result
        return add_columns(inp, result)

    def detect_fixes(self, fixes: pd.DataFrame, *, threads: int = 1) -> pd.DataFrame:
        """:meth:`detect` on canonical fixes; the result has ``fixes``' index."""
        m = self.model_
        reason = stream_reasons(fixes, min_step_s=MIN_STEP_S)
        usable = np.flatnonzero(reason == "")
        prepared = grad_points(fixes.iloc[usable], m.params.max_gap_s)
        pts = prepared.points
        n = len(pts)
        out = np.zeros((n, N_POINT_OUT))
        t = pts["t"].to_numpy(np.float64)
        lat = pts["lat"].to_numpy(np.float64)
        lon = pts["lon"].to_numpy(np.float64)
        nan = np.full(n, np.nan)
        speed = _readings(pts["speed"].to_numpy(np.float64)) if "speed" in pts else nan
        heading = _readings(pts["heading"].to_numpy(np.float64)) if "heading" in pts else nan
        tracks = pts["track"].to_numpy(object)
        slices = [sl for _, sl in prepared.segment_slices()]
        if slices:
            starts = np.array([sl.start for sl in slices] + [slices[-1].stop], np.int64)
            frames = [prepared.frames[str(tracks[sl.start])] for sl in slices]
            out = grad_segments(
                m.params,
                frames,
                m.gru_params,
                m.dims,
                starts,
                t,
                lat,
                lon,
                speed,
                heading,
                threads=threads,
            )
        rows = np.full((len(fixes), N_POINT_OUT), np.nan)
        rows[usable] = prepared.to_rows(out)
        return self._rows(rows, reason, fixes.index)

    def clean(
        self,
        data: Any,
        *,
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
        """``data`` with every position replaced by the repaired one, in the same type.

        Like movingpandas' cleaners: the rows come back in order with
        ``lat_clean``/``lon_clean`` as their position (the geometry, in the
        caller's CRS, for a GeoDataFrame or trajectory). Unusable fixes
        (``invalid_reason`` set: no time, a repeated timestamp...) have no
        repaired position and are dropped unless ``keep_invalid`` (then
        their position is missing). Columns by keyword as in :meth:`detect`.
        """
        from .._tracks.objects import as_track_input, replace_positions

        columns = dict(
            time=time,
            lat=lat,
            lon=lon,
            track=track,
            speed=speed,
            heading=heading,
            alt=alt,
            hdop=hdop,
        )
        inp = as_track_input(data, columns)
        result = self.detect_fixes(inp.fixes)
        keep = (result["invalid_reason"].to_numpy() == "") | keep_invalid
        return replace_positions(
            inp,
            result["lat_clean"].to_numpy(np.float64),
            result["lon_clean"].to_numpy(np.float64),
            keep,
        )

    def events(
        self,
        result: Any,
        *,
        time: str | None = None,
        lat: str | None = None,
        lon: str | None = None,
        track: str | None = None,
        speed: str | None = None,
        heading: str | None = None,
        alt: str | None = None,
        hdop: str | None = None,
    ) -> pd.DataFrame:
        """Fault events of a result (see :mod:`gradgps._grad.events`), one row per event.

        ``result``: what :func:`gradgps.detect` (or :meth:`detect` on a
        GeoDataFrame/trajectory) returned, i.e. the input with the result
        columns added. Columns: ``track``, ``start``, ``end`` (in the input's
        own time form: Timestamps for datetime input, else seconds),
        ``duration_s``, ``fixes``, ``bias_type``, ``time_type``,
        ``peak_offset_m``, ``peak_score``, ``alert``, ``first_row``,
        ``last_row`` (0-based positions of the rows in ``result``).
        """
        from .._tracks.objects import as_track_input, time_values

        columns = dict(
            time=time,
            lat=lat,
            lon=lon,
            track=track,
            speed=speed,
            heading=heading,
            alt=alt,
            hdop=hdop,
        )
        inp = as_track_input(result, columns)
        missing = [c for c in RESULT_DTYPES if c not in inp.flat.columns]
        if missing:
            raise ConfigError(
                f"events() needs a detection result with the input's columns; {missing} "
                "are missing: pass what gradgps.detect(data) returned"
            )
        res = pd.DataFrame({c: inp.flat[c].to_numpy() for c in RESULT_DTYPES})
        events = fault_events(inp.fixes, res)
        form = time_values(inp)
        events["start"] = form(events["start"].to_numpy(np.float64))
        events["end"] = form(events["end"].to_numpy(np.float64))
        return events

    def _rows(
        self, out: NDArray[np.float64], reason: NDArray[Any], index: pd.Index
    ) -> pd.DataFrame:
        invalid = reason != ""
        bias_names = np.array(self.model_.bias_classes, dtype=object)
        time_names = np.array(TIME_TYPES, dtype=object)
        codes_b = np.where(invalid, 0, np.nan_to_num(out[:, O_BIAS])).astype(np.int64)
        codes_t = np.where(invalid, 0, np.nan_to_num(out[:, O_TIME])).astype(np.int64)
        return result_frame(
            index,
            reason,
            anomaly=out[:, O_FLAG],
            score=out[:, O_SCORE],
            bias_type=bias_names[codes_b],
            time_type=time_names[codes_t],
            lat_clean=out[:, O_LAT],
            lon_clean=out[:, O_LON],
            alert=np.nan_to_num(out[:, O_ALERT]),
        )


class MultiTrackDetector:
    """GRAD for many vehicles at once: one streaming :class:`Detector` per track id.

    The one registry of per-track detectors (chunked files, follow mode): a
    track's Detector is made on first sight and kept across calls.
    ``model`` and ``threshold`` are passed to every Detector.
    """

    def __init__(
        self, model: str | os.PathLike[str] | None = None, *, threshold: float | None = None
    ) -> None:
        self.model = model
        self.threshold = threshold
        self.detectors: dict[str, Detector] = {}

    def detector(self, track: str) -> Detector:
        """The streaming Detector of ``track`` (made on first sight)."""
        det = self.detectors.get(track)
        if det is None:
            det = Detector(self.model, threshold=self.threshold)
            self.detectors[track] = det
        return det

    def get_state(self) -> dict[str, Any]:
        """Every track's detector state, as plain JSON-able data (see :meth:`Detector.get_state`)."""
        return {"tracks": {track: det.get_state() for track, det in self.detectors.items()}}

    def set_state(self, state: Mapping[str, Any]) -> MultiTrackDetector:
        """Restore :meth:`get_state` output (same model and threshold); returns self."""
        try:
            tracks = dict(state["tracks"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not a multi-track detector state: {exc}") from exc
        self.detectors = {
            str(track): Detector(self.model, threshold=self.threshold).set_state(s)
            for track, s in tracks.items()
        }
        return self

    def update_fixes(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """Feed canonical fixes to their tracks' detectors in row order; one result row per row.

        The result has the batch result columns (``anomaly`` ... ``invalid_reason``)
        and ``fixes``' index.
        """
        n = len(fixes)
        nan = [float("nan")] * n
        tracks = fixes["track"].to_numpy(object)
        t = fixes["t"].to_numpy(np.float64).tolist()
        lat = fixes["lat"].to_numpy(np.float64).tolist()
        lon = fixes["lon"].to_numpy(np.float64).tolist()
        speed = fixes["speed"].to_numpy(np.float64).tolist() if "speed" in fixes else nan
        heading = fixes["heading"].to_numpy(np.float64).tolist() if "heading" in fixes else nan
        results = (
            self.detector(str(tracks[i])).update(t[i], lat[i], lon[i], speed[i], heading[i])
            for i in range(n)
        )
        return results_frame(results, fixes.index)


#: Deprecated name of :class:`MultiTrackDetector` (kept so old code still imports).
TrackStreams = MultiTrackDetector
