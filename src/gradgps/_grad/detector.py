"""``gradgps.Detector``: GRAD for one vehicle's live stream, or for whole tables of tracks.

Two faces, one computation (:mod:`gradgps._grad.pipeline`):

* streaming, river style: ``update(t, lat, lon, speed=None, heading=None,
  fix_quality=None, satellites=None)``
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
range; a repeated or backward time; a fix the receiver itself reports as no
fix, where its fix quality or satellite count is given) come back with
``anomaly=1``, ``invalid_reason`` saying why, NaN score and clean position,
and never touch the detector's state, with one exception: a fix set aside for
its time at a position other than the last usable fix's says the time column
could not time the step to the next usable fix (it covers two fixes' motion),
so that next fix begins a new segment, as after a gap
(:func:`gradgps._tracks.preprocess.time_glitch_breaks`; a fix repeated exactly
breaks nothing). Speed and heading are optional: a
missing, non-numeric or infinite reading is treated as absent (NaN), and the
fix is still used. A gap longer than the model's
``max_gap_s`` starts a new segment: every state is reset, because nothing
learnt before a long dropout says anything about the fixes after it.

A segment's sampling period is the median of its first 5 time steps; until
they have arrived it is provisional, and the segment is rebuilt and its
fixes so far replayed whenever the estimate changes (see
:mod:`gradgps._grad.pipeline`; batch does exactly the same).

Each segment is measured in its own local frame, centred on its first fix: a
new segment starts after a gap longer than ``max_gap_s`` *or* at a fix more
than :data:`FRAME_RADIUS_M` (100 km) from the segment's first fix. So a
track whose first fix is bogus, that jumps to another place and drives on
there, or that drives across a country, is never measured (and repaired)
through a tangent plane thousands of kilometres away. A fix at exactly
(0, 0), what receivers report before they have a position, is invalid.

The state (:meth:`Detector.get_state`) holds only what cannot be derived:
the segment's parameters are rebuilt from the model, the frame and the
period, and :meth:`Detector.set_state` checks every array's size and every
counter that the compiled step uses as an index against the model, so a
damaged or foreign state is refused (``ConfigError``), never run.

``gradgps.MultiTrackDetector`` (below) keeps one streaming Detector per track id;
``gradgps.FleetDetector`` (below) holds many vehicles' states in shared arrays and
scores a batch of any vehicles' fixes in one compiled call, with the same results.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import astuple, dataclass, replace
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Unpack

import numba
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._exceptions import ConfigError, GradGPSError, InputWarning, ModelError
from .._result import (
    RESULT_DTYPES,
    STEP_TOLERANCE_S,
    PointResult,
    as_number,
    decode_floats,
    encode_floats,
    fix_quality_code,
    fix_reason,
    reading,
    result_frame,
    results_frame,
    shown,
    usable_point,
)
from .._tracks.geo import LocalFrame, far_apart_scalar
from .._tracks.input_checks import input_warnings, validated_rates
from .._tracks.preprocess import Prepared, stream_reasons, time_glitch_breaks
from .._tracks.track import ColumnKeywords, ColumnMap, check_keywords, datetime_seconds
from .core import N_CORE_PARAMS, _layout
from .defaults import FRAME_RADIUS_M, MIN_STEP_S, grad_points
from .drift import DRIFT_BIAS
from .events import fault_events
from .model_io import CONFIG_FILE, WEIGHTS_FILE, gru_model, load_model
from .motion import N_MOTION_STATE
from .offset import N_OFFSET_STATE, check_state
from .pipeline import (
    _N_OFF_OUT,
    _N_TAIL_STATE,
    LANES,
    N_NETWORK_DIMS,
    N_POINT_OUT,
    O_ALERT,
    O_BIAS,
    O_FLAG,
    O_LAT,
    O_LON,
    O_SCORE,
    O_TIME,
    PERIOD_STEPS,
    PipelineParams,
    RateThresholds,
    _tail_end,
    grad_segments,
    grad_step,
    lanes_step,
    new_lane_work,
    new_state,
    new_work,
    pipeline_feature_names,
    warmup_periods,
)
from .recovery import N_RECOVERY_STATE
from .rema import N_STATE as N_REMA_STATE
from .rema import S_COUNT as REMA_COUNT
from .rema import S_NSTEPS as REMA_NSTEPS
from .time_classifier import N_TIME_STATE, TIME_TYPES

if TYPE_CHECKING:
    from .._tracks.objects import TrackInput

__all__ = [
    "DEFAULT_MODEL",
    "FRAME_RADIUS_M",
    "MIN_STEP_S",
    "REASONS",
    "Detector",
    "FleetDetector",
    "FleetResult",
    "GradModel",
    "MultiTrackDetector",
    "ReferenceFleet",
    "load_grad_model",
]

#: The shortest step a stored warm-up may hold (see :data:`gradgps._result.STEP_TOLERANCE_S`).
_MIN_STEP = MIN_STEP_S - STEP_TOLERANCE_S

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

    @property
    def output_bias_classes(self) -> tuple[str, ...]:
        """The bias types a verdict can name: the GRU head's classes, then ``drift``
        (the drift witness's verdict, :mod:`gradgps._grad.drift`; code ``len(bias_classes)``)."""
        return (*self.bias_classes, DRIFT_BIAS)


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
            "retrain it with this version's gradgps train"
        ) from exc
    names = pipeline_feature_names(params)
    if list(config["features"]["names"]) != names:
        raise ModelError(
            f"{path}/config.json: its features {config['features']['names']} are not "
            f"the ones this version computes ({names}); retrain the model"
        )
    threshold = float(config["thresholds"]["anomaly"])
    confirm = config["thresholds"].get("confirm")
    try:
        bands = tuple(
            RateThresholds(
                float(b["from_period_s"]), float(b["anomaly"]), float(b["confirm"])
            ).checked()
            for b in config["thresholds"].get("by_rate", [])
        )
    except (GradGPSError, KeyError, TypeError, ValueError) as exc:
        raise ModelError(
            f"{path}/config.json: thresholds.by_rate is not a list of "
            f"{{from_period_s, anomaly, confirm}} ({exc}); recalibrate the model"
        ) from exc
    params = PipelineParams(
        **{
            **params.__dict__,
            "threshold": threshold,
            "confirm_threshold": None if confirm is None else float(confirm),
            "rate_thresholds": bands,
        }
    )
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
    P = params.array(MIN_STEP_S, LocalFrame(0.0, 0.0), np.ones(N_NETWORK_DIMS, np.int64))
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
    # Only the model's own files count: an editor's lock file (a dangling symlink) or an
    # unreadable stray file in the folder must not stop the load.
    stamps = []
    for name in (CONFIG_FILE, WEIGHTS_FILE):
        try:
            stamps.append((path / name).stat().st_mtime_ns)
        except OSError:
            stamps.append(0)
    return _load_cached(resolved, max(stamps))


#: 4: the time-glitch rule's ``last_fix`` and ``glitch`` (2026-12-03); a state of an
#: earlier format is refused with a message to start afresh.
_STATE_FORMAT = 4
_NON_FINITE = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def _decode_float(value: Any) -> float:
    """One number of a stored state (see :func:`gradgps._result.decode_floats`)."""
    decoded = decode_floats([value])
    assert decoded is not None
    return decoded[0]


def _decode_list(values: Any) -> list[float]:
    """A stored list of numbers; ``TypeError`` for anything else (``None`` included)."""
    decoded = decode_floats(values)
    if decoded is None:
        raise TypeError("a list of numbers is missing")
    return decoded


def _settings_checksum(model: GradModel) -> str:
    """SHA-256 of everything besides the weights that shapes a detector's state and verdicts."""
    settings = {
        "weights": model.checksum,
        "pipeline": model.params.to_dict(),
        # [F, H1, H2, K]: a confirm head (dims[4]) changes the weights' checksum already,
        # and states saved before the head existed stay valid.
        "dims": [int(d) for d in model.dims[:4]],
        "bias_classes": list(model.bias_classes),
        "state_format": _STATE_FORMAT,
    }
    if model.params.confirm_threshold is not None:
        # It decides the pending fix a state holds; absent from older states' settings.
        settings["confirm_threshold"] = model.params.confirm_threshold
    if model.params.rate_thresholds:
        # So do a slow segment's; absent from the states of models without them.
        settings["rate_thresholds"] = [b.__dict__ for b in model.params.rate_thresholds]
    text = json.dumps(settings, sort_keys=True, default=str, allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _check_counters(P: NDArray[np.float64], S: NDArray[np.float64], seg_count: int) -> None:
    """Refuse a state whose counters (used by the compiled step as ring indices) are not
    what ``seg_count`` fixes leave: the step has no bounds checks."""

    def count(name: str, value: float, low: float, high: float) -> None:
        if not (math.isfinite(value) and value == int(value) and low <= value <= high):
            raise ValueError(f"state counter {name} = {value!r}, expected {low:g}..{high:g}")

    rs_e, _, rs_n, _, _, _, cnt, _, _ = _layout(P[:N_CORE_PARAMS])
    count("points", S[cnt], seg_count, seg_count)
    for name, at in (("east", rs_e), ("north", rs_n)):
        count(f"rema {name} points", S[at + REMA_COUNT], seg_count, seg_count)
        count(f"rema {name} steps", S[at + REMA_NSTEPS], 0, seg_count)
    end = _tail_end(P, S)
    tail = end - _N_TAIL_STATE
    count("offset points", S[tail], 0, seg_count)
    check_state(S[tail : tail + N_OFFSET_STATE])
    time_at = tail + N_OFFSET_STATE
    for k in (0, 2):  # run length, bursts
        count(f"time classifier [{k}]", S[time_at + k], 0, seg_count)
    rec_count = time_at + N_TIME_STATE + N_RECOVERY_STATE - 1
    count("recovery points", S[rec_count], 0, seg_count)
    count("motion points", S[end - N_MOTION_STATE], 0, seg_count)
    if N_REMA_STATE <= REMA_NSTEPS:
        raise AssertionError("REMA state layout changed")


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
        try:
            return float(stamp.value) / 1e9
        except OverflowError:  # no nanoseconds since 1970 (before 1677, after 2262): still a time
            utc = pd.Series(np.array([stamp.asm8])).dt.tz_localize("UTC")  # in its own unit
            return float(datetime_seconds(utc)[0])
    return as_number(value)


def _readings(values: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`gradgps._result.reading` for a whole column."""
    return np.where(np.isfinite(values), values, np.nan)


#: One usable fix as a stream keeps it while its segment's period is provisional:
#: ``(t, lat, lon, speed, heading)``.
Fix = tuple[float, float, float, float, float]


def _follow_segment(
    fix: Fix,
    last_t: float | None,
    origin: tuple[float, float],
    period: float,
    warm: list[Fix],
    max_gap_s: float,
    new_segment: Callable[[float, float, float], None],
    step: Callable[[float, float, float, float, float], None],
) -> tuple[list[Fix], bool]:
    """The segment rule of one stream for one usable ``fix`` (see the module docstring),
    shared by :meth:`Detector.update` and :class:`FleetDetector`'s per-fix path.

    ``last_t``: the previous usable fix's time (``None``: the stream's first fix);
    ``origin``, ``period``: the segment's frame origin and sampling period; ``warm``:
    its fixes so far while the period is provisional. ``new_segment(period, lat0, lon0)``
    makes a fresh segment state; ``step(dt, lat, lon, speed, heading)`` advances it.
    Returns the warm-up fixes to keep and whether ``fix`` began a new segment.
    """
    t, lat, lon = fix[0], fix[1], fix[2]
    dt = 0.0 if last_t is None else t - last_t
    if (
        last_t is None
        or dt > max_gap_s
        or far_apart_scalar(origin[0], origin[1], lat, lon, FRAME_RADIUS_M)
    ):
        new_segment(1.0, lat, lon)
        step(0.0, lat, lon, fix[3], fix[4])
        return [fix], True
    if not warm:
        step(dt, lat, lon, fix[3], fix[4])
        return warm, False
    warm.append(fix)
    provisional = warmup_periods([w[0] for w in warm])[-1]
    if provisional != period:
        new_segment(provisional, origin[0], origin[1])
        for j, w in enumerate(warm):
            step(w[0] - warm[j - 1][0] if j else 0.0, w[1], w[2], w[3], w[4])
    else:
        step(dt, lat, lon, fix[3], fix[4])
    return ([] if len(warm) > PERIOD_STEPS else warm), False  # past PERIOD_STEPS: final


def _state(
    det: Detector,
    seg_count: int,
    frame: tuple[float, float] | None,
    last_t: float | None,
    period: float,
    warm: Iterable[Fix],
    S: NDArray[Any] | None,
    H: NDArray[Any] | None,
    last_fix: tuple[float, float] | None = None,
    glitch: bool = False,
) -> dict[str, Any]:
    """A stream's state as :meth:`Detector.get_state` writes it (``det``: its model and
    settings), for a Detector and for one vehicle of a :class:`FleetDetector` alike."""
    return {
        "format": _STATE_FORMAT,
        "model_checksum": det.model_.checksum,
        "settings_checksum": det._settings,
        "threshold": det.model_.params.threshold,
        "frame": None if frame is None else list(frame),
        "last_t": last_t,
        "segment_count": seg_count,
        "period": period,
        "warm": [encode_floats(w) for w in warm],
        "S": encode_floats(S),
        "H": encode_floats(H),
        "last_fix": None if last_fix is None else encode_floats(last_fix),
        "glitch": glitch,
    }


def track_input(data: Any, **columns: Unpack[ColumnKeywords]) -> TrackInput:
    """``data`` as a :class:`~gradgps._tracks.objects.TrackInput`, its columns named by the
    keywords that :func:`gradgps.detect`, :func:`gradgps.clean` and :class:`Detector`'s
    ``detect``/``clean``/``events`` take (``None``: found by name).

    A keyword that is not a column role is a ``TypeError`` (:func:`check_keywords`).
    """
    from .._tracks.objects import as_track_input

    check_keywords(columns, ColumnKeywords)
    return as_track_input(data, ColumnMap(**columns).as_dict())


class Detector:
    """GRAD anomaly detector, classifier and repairer (see the module docstring).

    ``model``: a model directory written by ``gradgps train``; ``None`` uses
    the default model shipped with gradgps (trained on simulated drives).
    ``threshold`` overrides the model's anomaly threshold (P(anomaly) at or
    above it is an anomaly; lower finds more faults and raises more false
    alarms); where the model's verdicts settle one fix late (a confirm head),
    its confirm threshold too, so the final verdicts move with it.
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
            # The user's threshold holds at every rate.
            given: dict[str, Any] = {"threshold": float(threshold), "rate_thresholds": ()}
            if loaded.params.confirm_threshold is not None:
                given["confirm_threshold"] = float(threshold)
            loaded = GradModel(
                **{
                    **loaded.__dict__,
                    "params": PipelineParams(**{**loaded.params.__dict__, **given}),
                }
            )
        self.model_ = loaded
        self._settings = _settings_checksum(loaded)
        self._settles = loaded.params.settles(loaded.dims)
        self._out = np.zeros(N_POINT_OUT)
        self._settled = np.full(N_POINT_OUT, np.nan)
        self._reset()

    # -- streaming ---------------------------------------------------------

    def _reset(self) -> None:
        self._frame: LocalFrame | None = None
        self._last_t: float | None = None
        self._period = 1.0
        self._P: NDArray[np.float64] | None = None
        self._S: NDArray[np.float64] | None = None
        self._H: NDArray[np.float32] | None = None
        self._work: Any = None
        self._seg_count = 0
        # The segment's fixes while its period is provisional.
        self._warm: list[Fix] = []
        # The last usable fix's position, and whether a fix set aside for its time at
        # another position came since (the next usable fix then begins a segment:
        # :func:`gradgps._tracks.preprocess.time_glitch_breaks`).
        self._last_fix: tuple[float, float] | None = None
        self._glitch = False

    def _new_segment(self, period: float, lat0: float, lon0: float) -> None:
        if self._frame is None or (self._frame.lat0, self._frame.lon0) != (lat0, lon0):
            self._frame = LocalFrame(lat0, lon0)
        m = self.model_
        self._period = period
        self._P = m.params.array(period, self._frame, m.dims)
        self._S = new_state(self._P)
        self._H = np.zeros(int(m.dims[1] + m.dims[2]), np.float32)
        self._make_work()

    def _make_work(self) -> None:
        """The segment's work arrays (:func:`new_work`) and outputs, as views into two
        buffers that :func:`_stream_fix` carves the same way (few arrays to pass)."""
        assert self._P is not None
        work = new_work(self._P)
        self._w64 = np.concatenate([*work[1:4], np.zeros(2 * N_POINT_OUT)])
        self._w32 = np.concatenate(work[4:])
        views = []
        for buffer, parts in ((self._w64, work[1:4]), (self._w32, work[4:])):
            at = 0
            for part in parts:
                views.append(buffer[at : at + part.size])
                at += part.size
        self._work = (work[0], *views)
        self._out = self._w64[-2 * N_POINT_OUT : -N_POINT_OUT]
        self._settled = self._w64[-N_POINT_OUT:]
        self._settled[O_FLAG] = np.nan

    def _step(self, dt: float, lat: float, lon: float, speed: float, heading: float) -> None:
        assert self._P is not None
        assert self._S is not None
        if self._work is None:  # restored by set_state: made on the first step
            self._make_work()
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
            self._settled,
        )

    def update(
        self,
        t: Any,
        lat: float,
        lon: float,
        speed: float | None = None,
        heading: float | None = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
        **channels: float,
    ) -> PointResult:
        """Score one fix of this detector's track; returns at once, never raises on bad values.

        ``t``: seconds (unix or relative), or a datetime, ``pandas.Timestamp``
        or ISO-8601 string (naive ones read as UTC).

        ``fix_quality`` (GGA quality, RMC status ``"A"``/``"V"``, GPX fix
        ``"none"``/``"3d"``...) and ``satellites``: what the receiver says
        about this fix, when it says it. A fix it reports as no fix (quality
        0, ``"V"``, ``"none"``, 0 satellites) comes back flagged with
        ``invalid_reason`` ``"receiver reports no fix"`` and never touches
        the detector's state; ``None`` or an unreadable value: not reported.

        ``channels`` (other sensor readings) are accepted for interface
        compatibility and ignored by the position model.

        A model with a confirm head settles each verdict one fix late
        (:attr:`settled`): what this returns is then the fix's verdict at once,
        final only if no later fix of its segment comes; :meth:`detect` gives the
        final ones.
        """
        t_f = t if type(t) is float else _time_number(t)
        lat_f, lon_f = as_number(lat), as_number(lon)
        if self._settles:
            self._settled[O_FLAG] = math.nan  # none until a step settles one
        if (
            self._seg_count > PERIOD_STEPS  # the period is final, no warm-up kept
            and self._work is not None
            and fix_quality is None
            and satellites is None
            and not self._glitch
        ):
            # The common case in one compiled call; it declines (-1) whatever needs the
            # segment rule below (a gap, a far jump) before touching the state.
            frame, P, S, last_t = self._frame, self._P, self._S, self._last_t
            assert frame is not None
            assert P is not None
            assert S is not None
            assert last_t is not None
            code = _stream_fix(
                P,
                S,
                self._H,
                self.model_.gru_params,
                self._work[0],
                self._w64,
                self._w32,
                t_f,
                lat_f,
                lon_f,
                reading(speed),
                reading(heading),
                last_t,
                frame.lat0,
                frame.lon0,
                self.model_.params.max_gap_s,
            )
            if code > 0:
                self._glitch |= _time_glitch(code, *self._last_position(), lat_f, lon_f)
                return PointResult.invalid(REASONS[code])
            if code == 0:
                self._seg_count += 1
                self._last_t = t_f
                self._last_fix = (lat_f, lon_f)
                return self._point()
        reason = fix_reason(
            t_f,
            lat_f,
            lon_f,
            self._last_t,
            MIN_STEP_S,
            fix_quality=fix_quality,
            satellites=satellites,
        )
        if reason:
            code = _REASON_CODES.get(reason, 0)
            self._glitch |= _time_glitch(code, *self._last_position(), lat_f, lon_f)
            return PointResult.invalid(reason)
        frame = self._frame
        self._warm, restarted = _follow_segment(
            (t_f, lat_f, lon_f, reading(speed), reading(heading)),
            None if self._glitch else self._last_t,
            (math.nan, math.nan) if frame is None else (frame.lat0, frame.lon0),
            self._period,
            self._warm,
            self.model_.params.max_gap_s,
            self._new_segment,
            self._step,
        )
        self._seg_count = 1 if restarted else self._seg_count + 1
        self._last_t = t_f
        self._last_fix = (lat_f, lon_f)
        self._glitch = False
        return self._point()

    def _last_position(self) -> tuple[float, float]:
        """The last usable fix's latitude and longitude; NaN before the first."""
        return (math.nan, math.nan) if self._last_fix is None else self._last_fix

    @property
    def settled(self) -> PointResult | None:
        """The final verdict of the usable fix before the one :meth:`update` just read,
        where this model's verdicts settle one fix late (it has a confirm head: the head
        judges a fix once the next fix of its segment has been read; the time type and
        repair follow that verdict). ``None`` when the last update settled none: its fix
        began a segment or was not used, or the model decides at once. A stream's final
        verdicts are these, plus the verdict at once of each segment's last fix: what
        :meth:`detect` gives for the same fixes."""
        if np.isnan(self._settled[O_FLAG]):
            return None
        return self._result(self._settled)

    def _point(self) -> PointResult:
        """The verdict the last step wrote into ``self._out``."""
        return self._result(self._out)

    def _result(self, row: NDArray[np.float64]) -> PointResult:
        flag, score, bias, kind, lat_c, lon_c, alert, _confirm = row.tolist()
        return usable_point(
            int(flag),
            score,
            self.model_.output_bias_classes[int(bias)],
            TIME_TYPES[int(kind)],
            lat_c,
            lon_c,
            int(alert),
        )

    def get_state(self) -> dict[str, Any]:
        """Everything needed to continue this stream elsewhere, as plain JSON-able data.

        Strict JSON: non-finite numbers (a missing speed, the time
        classifier's "no earlier run" gap) are written as the strings
        ``"nan"``, ``"inf"``, ``"-inf"``, so ``json.dumps(state,
        allow_nan=False)`` works and any JSON parser reads it back. For bytes,
        ``json.dumps(det.get_state()).encode()``; restoring gives the same
        outputs as an uninterrupted run, bit for bit (floats round-trip
        exactly through JSON). The segment's parameters are not stored: they
        follow from the model, ``frame`` and ``period``.
        """
        frame = self._frame
        return _state(
            self,
            self._seg_count,
            None if frame is None else (frame.lat0, frame.lon0),
            self._last_t,
            self._period,
            self._warm,
            self._S,
            self._H,
            self._last_fix,
            self._glitch,
        )

    def set_state(self, state: Mapping[str, Any]) -> Detector:
        """Restore a state from :meth:`get_state` (same model and settings); returns self.

        A state that is not one this detector could have written (another
        model, configuration or threshold; a wrong size, a counter out of
        range, inconsistent fields) raises :class:`ConfigError` and leaves
        the detector as it was.
        """
        restored = self._checked_state(state)
        # Assigned only once everything checked out: a bad state leaves this detector as it was.
        (
            self._frame,
            self._last_t,
            self._seg_count,
            self._period,
            self._warm,
            self._P,
            self._S,
            self._H,
            self._last_fix,
            self._glitch,
        ) = restored
        self._work = None  # made for the restored P on the first step
        return self

    def _checked_state(self, state: Mapping[str, Any]) -> tuple[Any, ...]:
        """:meth:`_parse_state`, every refusal a :class:`ConfigError` (also used by
        :class:`gradgps.FleetDetector`, so both refuse the same states alike)."""
        try:
            return self._parse_state(state)
        except ConfigError:
            raise
        except (
            KeyError,
            TypeError,
            ValueError,
            IndexError,
            OverflowError,
            RecursionError,  # junk nested thousands deep
            GradGPSError,
        ) as exc:
            raise ConfigError(f"not a detector state: {exc}") from exc

    def _parse_state(self, state: Mapping[str, Any]) -> tuple[Any, ...]:
        if not isinstance(state, Mapping):
            raise TypeError(f"expected a mapping, got {type(state).__name__}")
        if state["format"] != _STATE_FORMAT:
            raise ConfigError(
                f"not a detector state of this gradgps: format {shown(state['format'])} "
                f"(this gradgps writes format {_STATE_FORMAT}); start a fresh detector"
            )
        if state["model_checksum"] != self.model_.checksum:
            raise ConfigError(
                "detector state was saved with another model; "
                "restore it into a Detector of the same model"
            )
        if state["settings_checksum"] != self._settings:
            raise ConfigError(
                "detector state was saved with the same weights but other settings "
                "(another config.json or threshold); restore it into a Detector of that model"
            )
        if _decode_float(state["threshold"]) != self.model_.params.threshold:
            raise ConfigError("detector state was saved with another threshold")
        m = self.model_
        seg_count = state["segment_count"]
        if isinstance(seg_count, bool) or not isinstance(seg_count, int) or seg_count < 0:
            raise ValueError(f"segment_count {shown(seg_count)} is not a count")
        if seg_count == 0:
            stored = ("frame", "last_t", "warm", "S", "H", "last_fix")
            if any(state[k] not in (None, []) for k in stored) or state["glitch"] is not False:
                raise ValueError("segment_count 0 (a fresh detector) with a stored segment")
            return None, None, 0, 1.0, [], None, None, None, None, False
        frame_values = [_decode_float(v) for v in state["frame"]]
        if len(frame_values) != 2:
            raise ValueError("'frame' must hold latitude and longitude")
        frame = LocalFrame(frame_values[0], frame_values[1])
        last_t = _decode_float(state["last_t"])
        if not math.isfinite(last_t):
            raise ValueError("'last_t' is not a finite time")
        warm = [tuple(_decode_float(v) for v in w) for w in state["warm"]]
        if seg_count <= PERIOD_STEPS and len(warm) != seg_count:
            raise ValueError(f"{seg_count} fixes in the segment but {len(warm)} kept")
        if seg_count > PERIOD_STEPS and warm:
            raise ValueError(f"{seg_count} fixes in the segment: none should be kept")
        for w in warm:
            if len(w) != 5:
                raise ValueError(f"a kept fix holds {len(w)} values, expected 5")
            if fix_reason(w[0], w[1], w[2]) or not all(
                math.isnan(v) or math.isfinite(v) for v in w[3:]
            ):
                raise ValueError(f"a kept fix {w} is not a usable fix")
            if far_apart_scalar(frame.lat0, frame.lon0, w[1], w[2], FRAME_RADIUS_M):
                raise ValueError("a kept fix lies outside the segment's frame")
        if warm:
            times = [w[0] for w in warm]
            steps = [b - a for a, b in itertools.pairwise(times)]
            if any(not (_MIN_STEP <= d <= m.params.max_gap_s) for d in steps):
                raise ValueError("the kept fixes are not one segment in time order")
            if times[-1] != last_t or (warm[0][1], warm[0][2]) != (frame.lat0, frame.lon0):
                raise ValueError("the kept fixes do not match 'last_t' and 'frame'")
            period = warmup_periods(times)[-1]
        else:
            period = _decode_float(state["period"])
            if not (_MIN_STEP <= period <= m.params.max_gap_s):
                raise ValueError(f"period {period!r} is not a possible sampling period")
        if _decode_float(state["period"]) != period:
            raise ValueError("'period' does not follow from the kept fixes")
        P = m.params.array(period, frame, m.dims)
        S = np.array(_decode_list(state["S"]), np.float64)
        H64 = np.array(_decode_list(state["H"]), np.float64)
        expected = new_state(P).size
        if S.shape != (expected,):
            raise ValueError(f"'S' holds {S.size} values, this model's state has {expected}")
        h_len = int(m.dims[1] + m.dims[2])
        if H64.shape != (h_len,):
            raise ValueError(f"'H' holds {H64.size} values, this model's GRU has {h_len}")
        if not np.all(np.abs(H64) <= 1.0):  # NaN compares False
            raise ValueError("'H' is not a GRU hidden state (values outside [-1, 1])")
        H = H64.astype(np.float32)
        _check_counters(P, S, seg_count)
        last_fix = None
        if state["last_fix"] is not None:
            lat, lon = _decode_list(state["last_fix"])
            if fix_reason(0.0, lat, lon):
                raise ValueError("'last_fix' is not a usable position")
            last_fix = (lat, lon)
        glitch = state["glitch"]
        if not isinstance(glitch, bool) or (glitch and last_fix is None):
            raise ValueError(f"'glitch' {shown(glitch)} is not a flag after a usable fix")
        return frame, last_t, seg_count, period, warm, P, S, H, last_fix, glitch

    # -- batch -------------------------------------------------------------

    def detect(self, data: Any, *, threads: int = 1, **columns: Unpack[ColumnKeywords]) -> Any:
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
        from .._tracks.objects import add_columns

        inp = track_input(data, **columns)
        self._warn_about(inp.fixes)
        result = self._detect_input(inp, threads=threads)
        if inp.kind == "frame":
            return result
        return add_columns(inp, result)

    def _warn_about(self, fixes: pd.DataFrame) -> None:
        """An :class:`InputWarning` for each way ``fixes`` lie outside what the model was
        validated on (:func:`gradgps._tracks.input_checks.input_warnings`): the sentences
        the command line prints. The caller of the public method is the one warned."""
        import warnings

        lowest, highest = validated_rates(self.model_.config)
        for text in input_warnings(fixes, min_rate_hz=lowest, max_rate_hz=highest):
            warnings.warn(text, InputWarning, stacklevel=3)

    def _detect_input(self, inp: TrackInput, *, threads: int = 1) -> pd.DataFrame:
        """The result columns of :meth:`detect` for an input already read by
        :func:`track_input`, on the caller's index: what :meth:`detect` and
        :func:`gradgps.detect` both add to the caller's data."""
        result = self.detect_fixes(inp.fixes, threads=threads)
        result.index = inp.index
        return result

    def detect_fixes(self, fixes: pd.DataFrame, *, threads: int = 1) -> pd.DataFrame:
        """:meth:`detect` on canonical fixes; the result has ``fixes``' index."""
        reason, usable, prepared, out = self._point_outputs(fixes, threads=threads)
        rows = np.full((len(fixes), N_POINT_OUT), np.nan)
        rows[usable] = prepared.to_rows(out)
        return self._rows(rows, reason, fixes.index)

    def _point_outputs(
        self, fixes: pd.DataFrame, *, threads: int = 1
    ) -> tuple[NDArray[Any], NDArray[np.int64], Prepared, NDArray[np.float64]]:
        """The compiled pipeline's raw outputs on canonical fixes, before they become rows:
        ``(reason per row, the usable rows, their points, per-point outputs)``, the
        outputs (``N_POINT_OUT`` wide, :data:`gradgps._grad.pipeline.O_FLAG` ...) one row
        per point of ``prepared.points`` (``prepared.to_rows`` maps them back to the usable rows).
        For tools that need what the rows drop (the confirm head's ``O_CONFIRM``)."""
        m = self.model_
        reason = stream_reasons(fixes, min_step_s=MIN_STEP_S)
        usable = np.flatnonzero(reason == "")
        breaks = time_glitch_breaks(fixes, reason)[usable]
        prepared = grad_points(fixes.iloc[usable], m.params.max_gap_s, breaks)
        pts = prepared.points
        n = len(pts)
        out = np.zeros((n, N_POINT_OUT))
        t = pts["t"].to_numpy(np.float64)
        lat = pts["lat"].to_numpy(np.float64)
        lon = pts["lon"].to_numpy(np.float64)
        nan = np.full(n, np.nan)
        speed = _readings(pts["speed"].to_numpy(np.float64)) if "speed" in pts else nan
        heading = _readings(pts["heading"].to_numpy(np.float64)) if "heading" in pts else nan
        segments = list(prepared.segment_slices())
        if segments:
            slices = [sl for _, sl in segments]
            starts = np.array([sl.start for sl in slices] + [slices[-1].stop], np.int64)
            frames = [prepared.segment_frames[k] for k, _ in segments]
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
        return reason, usable, prepared, out

    def clean(
        self, data: Any, *, keep_invalid: bool = False, **columns: Unpack[ColumnKeywords]
    ) -> Any:
        """``data`` with every position replaced by the repaired one, in the same type.

        Like movingpandas' cleaners: the rows come back in order with
        ``lat_clean``/``lon_clean`` as their position (the geometry, in the
        caller's CRS, for a GeoDataFrame or trajectory). Unusable fixes
        (``invalid_reason`` set: no time, a repeated timestamp...) have no
        repaired position and are dropped unless ``keep_invalid`` (then
        their position is missing). Columns by keyword as in :meth:`detect`.
        """
        from .._tracks.objects import replace_positions

        inp = track_input(data, **columns)
        self._warn_about(inp.fixes)
        result = self.detect_fixes(inp.fixes)
        keep = (result["invalid_reason"].to_numpy() == "") | keep_invalid
        return replace_positions(
            inp,
            result["lat_clean"].to_numpy(np.float64),
            result["lon_clean"].to_numpy(np.float64),
            keep,
        )

    def events(self, result: Any, **columns: Unpack[ColumnKeywords]) -> pd.DataFrame:
        """Fault events of a result (see :mod:`gradgps._grad.events`), one row per event.

        ``result``: what :func:`gradgps.detect` (or :meth:`detect` on a
        GeoDataFrame/trajectory) returned, i.e. the input with the result
        columns added. Columns: ``track``, ``start``, ``end`` (in the input's
        own time form: Timestamps for datetime input, else seconds),
        ``duration_s``, ``fixes``, ``bias_type``, ``time_type``,
        ``peak_offset_m``, ``peak_score``, ``alert``, ``first_row``,
        ``last_row`` (0-based positions of the rows in ``result``).
        """
        from .._tracks.objects import time_values

        inp = track_input(result, **columns)
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
        bias_names = np.array(self.model_.output_bias_classes, dtype=object)
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
        self.detectors: dict[Hashable, Detector] = {}
        # Where verdicts settle one fix late: per track, the frame last returned by
        # update_fixes that holds its pending fix, and the fix's row in it.
        self._pending: dict[Hashable, tuple[pd.DataFrame, int]] = {}
        loaded = load_grad_model(model)
        self.settles = loaded.params.settles(loaded.dims)

    def detector(self, track: Hashable) -> Detector:
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
            tracks = {str(track): s for track, s in dict(state["tracks"]).items()}
        except (KeyError, TypeError, ValueError, RecursionError) as exc:
            raise ConfigError(f"not a multi-track detector state: {exc}") from exc
        self.detectors = {
            track: Detector(self.model, threshold=self.threshold).set_state(s)
            for track, s in tracks.items()
        }
        return self

    def update_fixes(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """Feed canonical fixes to their tracks' detectors in row order; one result row per row.

        The result has the batch result columns (``anomaly`` ... ``invalid_reason``)
        and ``fixes``' index.

        Where the model's verdicts settle one fix late (:attr:`Detector.settled`), each
        row holds its final verdict, except each track's last usable fix, whose verdict
        at once stands until that track's next fix arrives: the next call then writes
        the settled verdict into the row of the frame this call returned. So write a
        frame once the next call has returned (or at the end of the input, when the
        verdicts at once are final): what the chunked reader does.
        """
        n = len(fixes)
        nan = [float("nan")] * n
        tracks = fixes["track"].to_numpy(object)
        t = fixes["t"].to_numpy(np.float64).tolist()
        lat = fixes["lat"].to_numpy(np.float64).tolist()
        lon = fixes["lon"].to_numpy(np.float64).tolist()
        speed = fixes["speed"].to_numpy(np.float64).tolist() if "speed" in fixes else nan
        heading = fixes["heading"].to_numpy(np.float64).tolist() if "heading" in fixes else nan
        quality = (
            fixes["fix_quality"].to_numpy(np.float64).tolist() if "fix_quality" in fixes else nan
        )
        sats = fixes["satellites"].to_numpy(np.float64).tolist() if "satellites" in fixes else nan
        results: list[PointResult] = []
        here: dict[str, int] = {}  # settling: track -> its pending fix's row in this call
        late: list[tuple[pd.DataFrame, int, PointResult]] = []
        for i in range(n):
            track = str(tracks[i])
            det = self.detector(track)
            results.append(
                det.update(
                    t[i],
                    lat[i],
                    lon[i],
                    speed[i],
                    heading[i],
                    fix_quality=quality[i],
                    satellites=sats[i],
                )
            )
            if not self.settles:
                continue
            settled = det.settled
            if settled is not None:
                if track in here:
                    results[here[track]] = settled
                elif track in self._pending:  # else its frame was released, written
                    frame, row = self._pending.pop(track)
                    late.append((frame, row, settled))
            if results[-1].invalid_reason == "":
                here[track] = i
        for frame, row, settled in late:
            for j, value in enumerate(astuple(settled)):
                frame.iat[row, j] = value
        out = results_frame(results, fixes.index)
        for name, i in here.items():
            self._pending[name] = (out, i)
        return out

    def pending_frames(self) -> set[int]:
        """The ``id`` of every frame :meth:`update_fixes` returned that still holds a fix
        whose verdict has not settled (empty where verdicts come at once)."""
        return {id(frame) for frame, _ in self._pending.values()}

    def release(self, frame: pd.DataFrame) -> int:
        """Stop settling the fixes of ``frame`` (it is being written): they keep their
        verdicts at once. Returns how many there were."""
        gone = [track for track, (held, _) in self._pending.items() if held is frame]
        for track in gone:
            del self._pending[track]
        return len(gone)


#: Deprecated name of :class:`MultiTrackDetector` (kept so old code still imports).
TrackStreams = MultiTrackDetector


# -- FleetDetector -----------------------------------------------------------------
#
# ``gradgps.FleetDetector``: many vehicles' streams, one compiled call per batch of fixes.
#
# A :class:`~gradgps._grad.detector.Detector` per vehicle costs a Python call
# per fix (several microseconds of dispatch around a step of about 1.5 µs).
# :class:`FleetDetector` keeps every vehicle's state in contiguous arrays (the
# segment parameters ``P`` one row per vehicle, the GRU hidden states one row
# per vehicle, the pipeline states ``S`` end to end in one buffer, and the
# counters, last times and frame origins as columns) and scores a whole batch
# of fixes of any mix of vehicles with :meth:`FleetDetector.update_many`.
#
# The rule is the Detector's, fix by fix, bit for bit (tested against
# :class:`ReferenceFleet`, one Detector per vehicle, on random interleavings):
#
# * the *common case*, a valid fix of a vehicle whose segment's period is
#   final (more than ``PERIOD_STEPS`` fixes in) that continues that segment
#   (no gap over ``max_gap_s``, within :data:`FRAME_RADIUS_M` of the segment's
#   first fix), and every invalid fix, are handled by one numba loop over the
#   batch (:func:`_fleet_kernel`): the same :func:`grad_step` and the same
#   validity rule as the Detector;
# * the *rare cases* (a vehicle's first fix, a new segment, the warm-up while
#   the period is provisional, with its rebuilds and replays) stop that
#   vehicle in the loop; its remaining fixes go through
#   :meth:`FleetDetector._update_one`, the Detector's ``update`` written on the
#   arrays, until the vehicle's period is final again, and then back through
#   the loop. Other vehicles are not held up: each vehicle's fixes are
#   processed in its own order, and vehicles do not share state.
#
# States move between the two classes: :meth:`FleetDetector.get_state` of a
# vehicle is exactly :meth:`Detector.get_state` of a Detector that saw the same
# fixes, and either's state can be restored into the other.

FloatArray = NDArray[np.float64]

#: The invalid-fix reasons by the code :func:`_reason_code` gives, each written by
#: :func:`gradgps._result.fix_reason` itself (so the two can never word one differently).
REASONS: tuple[str, ...] = (
    "",
    fix_reason(math.nan, 1.0, 1.0),
    fix_reason(0.0, 1.0, 1.0, fix_quality=0),
    fix_reason(0.0, 1.0, 1.0, satellites=0),
    fix_reason(0.0, math.nan, 1.0),
    fix_reason(0.0, 91.0, 1.0),
    fix_reason(0.0, 1.0, math.nan),
    fix_reason(0.0, 1.0, 181.0),
    fix_reason(0.0, 0.0, 0.0),
    fix_reason(1.0, 1.0, 1.0, 1.0, MIN_STEP_S),
    fix_reason(1.0 + MIN_STEP_S / 2, 1.0, 1.0, 1.0, MIN_STEP_S),
)
# Kernel rounds per batch before the rest of it goes through the per-fix path (a vehicle
# that starts a new segment every few fixes would otherwise cost a round per segment).
_MAX_ROUNDS = 8

#: Each reason of :data:`REASONS` to its code.
_REASON_CODES = {reason: code for code, reason in enumerate(REASONS)}


@numba.njit(cache=True)
def _time_glitch(code: int, last_lat: float, last_lon: float, lat: float, lon: float) -> bool:
    """Whether a fix set aside with reason code ``code`` is one the time column could not
    time: set aside for its time (codes 9, 10) at a position other than the last usable
    fix's (``last_lat`` NaN: none yet). The one rule of the Detector, the fleet kernel and
    its per-fix path; :func:`gradgps._tracks.preprocess.time_glitch_breaks` is its batch
    form."""
    return (
        (code == 9 or code == 10)
        and not math.isnan(last_lat)
        and (lat != last_lat or lon != last_lon)
    )


@numba.njit(cache=True)
def _reason_code(
    t: float, lat: float, lon: float, fresh: bool, last_t: float, receiver: int
) -> int:
    """:func:`gradgps._result.fix_reason` with ``min_step_s`` = MIN_STEP_S, as an index
    into :data:`REASONS` (``receiver``: 0, or 1 no fix, 2 no satellites)."""
    if not math.isfinite(t):
        return 1
    if receiver != 0:
        return 1 + receiver
    if not math.isfinite(lat):
        return 4
    if abs(lat) > 90.0:
        return 5
    if not math.isfinite(lon):
        return 6
    if abs(lon) > 180.0:
        return 7
    if lat == 0.0 and lon == 0.0:
        return 8
    if not fresh:
        if t <= last_t:
            return 9
        if t - last_t < _MIN_STEP:
            return 10
    return 0


@numba.njit(cache=True)
def _stream_fix(
    P: FloatArray,
    S: FloatArray,
    H: Any,
    gp: Any,
    dims: NDArray[np.int64],
    w64: FloatArray,
    w32: Any,
    t: float,
    lat: float,
    lon: float,
    speed: float,
    heading: float,
    last_t: float,
    lat0: float,
    lon0: float,
    max_gap_s: float,
) -> int:
    """:meth:`Detector.update`'s common case (a segment whose period is final, no receiver
    fields) in one compiled call: :func:`_reason_code` of the fix (returned when it is
    invalid), -1 without touching the state when the segment rule must decide (a gap
    over ``max_gap_s``, a fix beyond :data:`FRAME_RADIUS_M`), else :func:`grad_step` with
    the work arrays carved from ``w64``/``w32`` as :meth:`Detector._make_work` lays them
    out (the fix's outputs, then a settled verdict of the fix before, in the last
    2 x :data:`N_POINT_OUT` of ``w64``) and 0.

    Fewer, flat arguments than ``grad_step``'s: numba unboxes every array of a call
    (about 70 ns each), and the work tuple held seven."""
    c = _reason_code(t, lat, lon, False, last_t, 0)
    if c != 0:
        return c
    dt = t - last_t
    if dt > max_gap_s or far_apart_scalar(lat0, lon0, lat, lon, FRAME_RADIUS_M):
        return -1
    n_core = w64.size - _N_OFF_OUT - 3 - 2 * N_POINT_OUT
    n_x = dims[0]
    n_scratch = w32.size - n_x - 1 - dims[3] - dims[4]
    work = (
        dims,
        w64[:n_core],
        w64[n_core : n_core + _N_OFF_OUT],
        w64[n_core + _N_OFF_OUT : n_core + _N_OFF_OUT + 3],
        w32[:n_x],
        w32[n_x : n_x + n_scratch],
        w32[n_x + n_scratch :],
    )
    n = w64.size
    grad_step(
        P,
        S,
        H,
        gp,
        work,
        dt,
        lat,
        lon,
        speed,
        heading,
        w64[n - 2 * N_POINT_OUT : n - N_POINT_OUT],
        w64[n - N_POINT_OUT :],
    )
    return 0


@numba.njit(cache=True)
def _fleet_kernel(
    Ps: FloatArray,
    Ss: FloatArray,
    s_off: NDArray[np.int64],
    s_len: NDArray[np.int64],
    Hs: Any,
    seg: NDArray[np.int64],
    last_t: FloatArray,
    last_lat: FloatArray,
    last_lon: FloatArray,
    glitch: NDArray[np.bool_],
    lat0: FloatArray,
    lon0: FloatArray,
    gp: Any,
    work: Any,
    max_gap_s: float,
    slots: NDArray[np.int64],
    t: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    receiver: NDArray[np.int64],
    todo: NDArray[np.int64],
    out: FloatArray,
    settled: FloatArray,
    code: NDArray[np.int64],
    deferred: NDArray[np.int64],
) -> int:
    """Fixes ``todo`` (batch positions, in order) of vehicles ``slots``: the common case and
    invalid fixes scored here, into ``out``/``code``; a vehicle's first rare fix and all its
    later ones are listed in ``deferred`` (returns how many).

    Common-case fixes are gathered into blocks of up to :data:`LANES` vehicles, each
    vehicle at most once per block, and each block is scored by one :func:`lanes_step`
    (a vehicle's next fix waits for its block to be scored)."""
    blocked = np.zeros(seg.size, np.bool_)
    in_block = np.zeros(seg.size, np.bool_)
    lanes = work[1].shape[0]
    block_slots = np.empty(lanes, np.int64)
    block_rows = np.empty(lanes, np.int64)
    dt = np.empty(t.size)
    # lanes_step's arguments but the block's size
    block = (
        Ps,
        Ss,
        s_off,
        s_len,
        Hs,
        gp,
        work,
        block_slots,
        block_rows,
        dt,
        lat,
        lon,
        speed,
        heading,
        out,
        settled,
    )
    n_block = 0
    n_def = 0
    for j in range(todo.size):
        i = todo[j]
        s = slots[i]
        if blocked[s]:
            deferred[n_def] = i
            n_def += 1
            continue
        fresh = seg[s] == 0
        c = _reason_code(t[i], lat[i], lon[i], fresh, last_t[s], receiver[i])
        if c != 0:
            code[i] = c
            # for the per-fix path to act on at the vehicle's next fix
            glitch[s] |= _time_glitch(c, last_lat[s], last_lon[s], lat[i], lon[i])
            continue
        dt[i] = t[i] - last_t[s]
        if (
            glitch[s]
            or seg[s] <= PERIOD_STEPS
            or dt[i] > max_gap_s
            or far_apart_scalar(lat0[s], lon0[s], lat[i], lon[i], FRAME_RADIUS_M)
        ):
            blocked[s] = True
            deferred[n_def] = i
            n_def += 1
            continue
        if in_block[s] or n_block == lanes:
            _score_block(block, n_block, in_block)
            n_block = 0
        block_slots[n_block] = s
        block_rows[n_block] = i
        in_block[s] = True
        n_block += 1
        seg[s] += 1
        last_t[s] = t[i]
        last_lat[s] = lat[i]
        last_lon[s] = lon[i]
    _score_block(block, n_block, in_block)
    return n_def


@numba.njit(cache=True)
def _score_block(block: Any, n: int, in_block: NDArray[np.bool_]) -> None:
    """Score the first ``n`` fixes of one block of :func:`_fleet_kernel` (``block``:
    :func:`lanes_step`'s arguments but ``n``) and mark its vehicles free again."""
    if n == 0:
        return
    Ps, Ss, s_off, s_len, Hs, gp, work, slots, rows, dt, lat, lon, speed, heading, out, done = block
    lanes_step(
        Ps, Ss, s_off, s_len, Hs, gp, work, slots, rows, n, dt, lat, lon, speed, heading, out, done
    )
    for v in range(n):
        in_block[slots[v]] = False


@dataclass(frozen=True)
class FleetResult:
    """Verdicts of :meth:`FleetDetector.update_many`, one entry per fix, in input order.

    The arrays hold what :class:`~gradgps._result.PointResult` holds per fix
    (``anomaly``, ``alert`` int8; ``score``, ``lat_clean``, ``lon_clean``
    float64; ``bias_type``, ``time_type``, ``invalid_reason`` str objects).
    """

    anomaly: NDArray[np.int8]
    score: FloatArray
    bias_type: NDArray[np.object_]
    time_type: NDArray[np.object_]
    lat_clean: FloatArray
    lon_clean: FloatArray
    alert: NDArray[np.int8]
    invalid_reason: NDArray[np.object_]
    settled: FleetResult | None = None
    """Where the model's verdicts settle one fix late (a confirm head,
    :attr:`Detector.settled`): entry ``i`` is the final verdict of the usable fix of
    vehicle ``i`` read before fix ``i``, where fix ``i`` settled one
    (``has_settled[i]``; elsewhere the entry means nothing). ``None``: verdicts at once."""
    has_settled: NDArray[np.bool_] | None = None

    def __len__(self) -> int:
        return int(self.score.size)

    def settled_point(self, i: int) -> PointResult | None:
        """The verdict fix ``i`` settled, as :attr:`Detector.settled` gives it after that
        fix (``None``: it settled none)."""
        if self.settled is None or self.has_settled is None or not self.has_settled[i]:
            return None
        return self.settled.point(i)

    def point(self, i: int) -> PointResult:
        """Fix ``i``'s verdict as the :class:`PointResult` a Detector returns."""
        return PointResult(
            anomaly=int(self.anomaly[i]),
            score=float(self.score[i]),
            bias_type=str(self.bias_type[i]),
            time_type=str(self.time_type[i]),
            lat_clean=float(self.lat_clean[i]),
            lon_clean=float(self.lon_clean[i]),
            alert=int(self.alert[i]),
            invalid_reason=str(self.invalid_reason[i]),
        )

    def to_frame(self, index: pd.Index | None = None) -> pd.DataFrame:
        """The verdicts as a DataFrame of the batch result columns (``anomaly`` ... ``invalid_reason``)."""
        return result_frame(
            pd.RangeIndex(len(self)) if index is None else index,
            self.invalid_reason,
            anomaly=self.anomaly,
            score=self.score,
            bias_type=self.bias_type,
            time_type=self.time_type,
            lat_clean=self.lat_clean,
            lon_clean=self.lon_clean,
            alert=self.alert,
        )


def _numbers(values: Any, n: int, convert: Any = as_number) -> FloatArray:
    """``values`` (one per fix) as float64, each read as ``convert`` reads one value."""
    if values is None:
        return np.full(n, np.nan)
    arr = np.asarray(values)
    if arr.shape != (n,):
        raise ValueError(f"expected {n} values, got an array of shape {arr.shape}")
    if arr.dtype.kind in "fiub":
        return arr.astype(np.float64)
    return np.array([convert(v) for v in arr.tolist()], np.float64)


def _times(values: Any, n: int) -> FloatArray:
    """Fix times as seconds, exactly as :meth:`Detector.update` reads each one."""
    arr = np.asarray(values)
    if arr.shape == (n,) and arr.dtype.kind == "M":
        ns = arr.astype("datetime64[ns]")
        out = ns.astype(np.int64).astype(np.float64) / 1e9
        out[np.isnat(ns)] = np.nan
        # Times nanoseconds do not hold exactly (years outside 1677-2262, finer units)
        # wrapped around or were cut: those one by one, as the Detector reads them.
        for k in np.flatnonzero((ns.astype(arr.dtype) != arr) & ~np.isnat(arr)).tolist():
            out[k] = _time_number(arr[k])
        return out
    return _numbers(values, n, _time_number)


def _reading_column(values: Any, n: int) -> FloatArray:
    return _readings(_numbers(values, n))


def _receiver_codes(fix_quality: Any, satellites: Any, n: int) -> NDArray[np.int64]:
    """Per fix: 0, or 1 (receiver reports no fix), 2 (0 satellites), as
    :func:`gradgps._result.receiver_reason` decides."""
    codes = np.zeros(n, np.int64)
    if satellites is not None:
        codes[_numbers(satellites, n) == 0.0] = 2
    if fix_quality is not None:
        q = np.asarray(fix_quality, dtype=object)
        if q.shape != (n,):
            raise ValueError(f"expected {n} fix qualities, got shape {q.shape}")
        no_fix = np.array([fix_quality_code(v) == 0.0 for v in q.tolist()], bool)
        codes[no_fix] = 1
    return codes


class FleetDetector:
    """GRAD for a fleet: every vehicle's streaming state in contiguous arrays, one compiled
    call per batch of fixes (see the module docstring).

    ``model``, ``threshold``: as for :class:`Detector`. Vehicles are any hashable ids
    (compared as Python objects: ``"7"`` and ``7`` are two vehicles); a vehicle is made
    on first sight and kept until :meth:`drop`.
    """

    def __init__(
        self,
        model: str | os.PathLike[str] | None = None,
        *,
        threshold: float | None = None,
        capacity: int = 64,
    ) -> None:
        self.model = model
        self.threshold = threshold
        self._template = Detector(model, threshold=threshold)
        m = self._template.model_
        self.model_ = m
        self._settles = m.params.settles(m.dims)
        self._gp = m.gru_params
        self._max_gap = float(m.params.max_gap_s)
        self._h_len = int(m.dims[1] + m.dims[2])
        P0 = m.params.array(1.0, LocalFrame(0.0, 0.0), m.dims)
        self._n_p = int(P0.size)
        self._work = new_work(P0)
        self._lane_work = new_lane_work(P0, LANES)
        self._bias_names = np.array([*m.output_bias_classes, "none"], dtype=object)
        self._time_names = np.array([*TIME_TYPES, "none"], dtype=object)
        self._reasons = np.array(REASONS, dtype=object)
        self._index: dict[Hashable, int] = {}
        self._free: list[int] = []
        cap = max(int(capacity), 1)
        self._seg = np.zeros(cap, np.int64)
        self._last = np.full(cap, np.nan)
        # The last usable fix's position (NaN: none) and the time-glitch flag (see Detector).
        self._last_lat = np.full(cap, np.nan)
        self._last_lon = np.full(cap, np.nan)
        self._glitch = np.zeros(cap, np.bool_)
        self._lat0 = np.full(cap, np.nan)
        self._lon0 = np.full(cap, np.nan)
        self._period = np.ones(cap)
        self._P = np.zeros((cap, self._n_p))
        self._H = np.zeros((cap, self._h_len), np.float32)
        self._s_off = np.zeros(cap, np.int64)
        self._s_len = np.zeros(cap, np.int64)
        self._s_cap = np.zeros(cap, np.int64)
        self._S = np.zeros(cap * int(new_state(P0).size))
        self._s_used = 0
        # The segment's fixes while its period is provisional, per slot (see Detector).
        self._warm: list[list[Fix]] = []

    # -- vehicles --------------------------------------------------------------

    def __len__(self) -> int:
        return len(self._index)

    def __contains__(self, vehicle: object) -> bool:
        return vehicle in self._index

    @property
    def vehicles(self) -> list[Hashable]:
        """The vehicles held, in order of first sight."""
        return list(self._index)

    def _grow(self, need: int) -> None:
        cap = self._seg.size
        if need <= cap:
            return
        new = max(need, 2 * cap)

        def grown(a: NDArray[Any], fill: float) -> NDArray[Any]:
            b = np.full((new, *a.shape[1:]), fill, a.dtype)
            b[:cap] = a
            return b

        self._seg = grown(self._seg, 0)
        self._last = grown(self._last, np.nan)
        self._last_lat = grown(self._last_lat, np.nan)
        self._last_lon = grown(self._last_lon, np.nan)
        self._glitch = grown(self._glitch, False)
        self._lat0 = grown(self._lat0, np.nan)
        self._lon0 = grown(self._lon0, np.nan)
        self._period = grown(self._period, 1.0)
        self._P = grown(self._P, 0.0)
        self._H = grown(self._H, 0.0)
        self._s_off = grown(self._s_off, 0)
        self._s_len = grown(self._s_len, 0)
        self._s_cap = grown(self._s_cap, 0)

    def _slot(self, vehicle: Hashable) -> int:
        """The slot of ``vehicle``, made (fresh) on first sight."""
        s = self._index.get(vehicle)
        if s is not None:
            return s
        if self._free:
            s = self._free.pop()
        else:
            s = len(self._warm)  # one warm-up list per slot ever made
            self._grow(s + 1)
            self._warm.append([])
        self._index[vehicle] = s
        self._clear(s)
        return s

    def _clear(self, s: int) -> None:
        self._seg[s] = 0
        self._last[s] = np.nan
        self._last_lat[s] = self._last_lon[s] = np.nan
        self._glitch[s] = False
        self._lat0[s] = self._lon0[s] = np.nan
        self._period[s] = 1.0
        self._s_len[s] = 0
        self._warm[s] = []

    def drop(self, vehicle: Hashable) -> None:
        """Forget ``vehicle`` (its next fix starts it afresh); nothing happens for an unknown one."""
        s = self._index.pop(vehicle, None)
        if s is not None:
            self._clear(s)
            self._free.append(s)

    def _slots(self, vehicle_ids: Iterable[Hashable]) -> NDArray[np.int64]:
        get = self._index.get
        ids = list(vehicle_ids)
        found = [get(v, -1) for v in ids]
        if -1 in found:
            found = [s if s >= 0 else self._slot(v) for v, s in zip(ids, found, strict=True)]
        return np.array(found, np.int64)

    # -- one vehicle's segment ---------------------------------------------------

    def _store_segment(self, s: int, P: FloatArray, S: FloatArray) -> None:
        """Make ``P``/``S`` slot ``s``'s segment (its S region reused when big enough)."""
        n = S.size
        if n > self._s_cap[s]:
            if self._s_used + n > self._S.size:
                self._compact(n)
            self._s_off[s] = self._s_used
            self._s_cap[s] = n
            self._s_used += n
        a = int(self._s_off[s])
        self._S[a : a + n] = S
        self._s_len[s] = n
        self._P[s] = P

    def _compact(self, extra: int) -> None:
        """Lay the live S regions end to end in a buffer with room for ``extra`` more."""
        free = set(self._free)
        live = [s for s in range(len(self._warm)) if s not in free and self._s_cap[s] > 0]
        used = int(sum(int(self._s_cap[s]) for s in live))
        buf = np.zeros(max(2 * (used + extra), 1024))
        at = 0
        for s in live:
            a, n = int(self._s_off[s]), int(self._s_cap[s])
            buf[at : at + n] = self._S[a : a + n]
            self._s_off[s] = at
            at += n
        for s in free:
            self._s_cap[s] = 0
        self._S = buf
        self._s_used = at

    def _new_segment(self, s: int, period: float, lat0: float, lon0: float) -> None:
        m = self.model_
        self._lat0[s], self._lon0[s] = lat0, lon0
        self._period[s] = period
        P = m.params.array(period, LocalFrame(float(self._lat0[s]), float(self._lon0[s])), m.dims)
        self._store_segment(s, P, new_state(P))
        self._H[s] = 0.0

    def _step(
        self,
        s: int,
        dt: float,
        lat: float,
        lon: float,
        speed: float,
        heading: float,
        out: Any,
        settled: Any,
    ) -> None:
        a = int(self._s_off[s])
        grad_step(
            self._P[s],
            self._S[a : a + int(self._s_len[s])],
            self._H[s],
            self._gp,
            self._work,
            dt,
            lat,
            lon,
            speed,
            heading,
            out,
            settled,
        )

    def _update_one(
        self, s: int, fix: Fix, receiver: int, out: FloatArray, settled: FloatArray
    ) -> int:
        """:meth:`Detector.update` of ``fix`` on slot ``s``: writes the outputs into ``out``
        (and a settled verdict of the vehicle's previous fix into ``settled``),
        returns the invalid reason's code in :data:`REASONS` (0 for a usable fix;
        ``receiver``: the receiver's verdict as :func:`_receiver_codes` gives it)."""
        t = fix[0]
        seg = int(self._seg[s])
        last = None if seg == 0 else float(self._last[s])
        code = _reason_code(
            t, fix[1], fix[2], seg == 0, math.nan if last is None else last, receiver
        )
        if code:
            last_lat, last_lon = float(self._last_lat[s]), float(self._last_lon[s])
            self._glitch[s] |= _time_glitch(code, last_lat, last_lon, fix[1], fix[2])
            return code
        self._warm[s], restarted = _follow_segment(
            fix,
            None if self._glitch[s] else last,
            (float(self._lat0[s]), float(self._lon0[s])),
            float(self._period[s]),
            self._warm[s],
            self._max_gap,
            lambda period, lat0, lon0: self._new_segment(s, period, lat0, lon0),
            lambda dt, la, lo, sp, hd: self._step(s, dt, la, lo, sp, hd, out, settled),
        )
        self._seg[s] = 1 if restarted else seg + 1
        self._last[s] = t
        self._last_lat[s], self._last_lon[s] = fix[1], fix[2]
        self._glitch[s] = False
        return 0

    # -- batches -------------------------------------------------------------------

    def update(
        self,
        vehicle: Hashable,
        t: Any,
        lat: float,
        lon: float,
        speed: float | None = None,
        heading: float | None = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> PointResult:
        """One fix of one vehicle, as :meth:`Detector.update` scores it."""
        return self.update_many(
            [vehicle],
            [t],
            [lat],
            [lon],
            None if speed is None else [speed],
            None if heading is None else [heading],
            fix_quality=None if fix_quality is None else [fix_quality],
            satellites=None if satellites is None else [satellites],
        ).point(0)

    def update_many(
        self,
        vehicle_ids: Sequence[Hashable] | NDArray[Any],
        t: Any,
        lat: Any,
        lon: Any,
        speed: Any = None,
        heading: Any = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> FleetResult:
        """Score a batch of fixes of any vehicles; fix ``i`` is ``vehicle_ids[i]``'s next fix.

        Each argument holds one value per fix (``speed``, ``heading``,
        ``fix_quality``, ``satellites`` may be ``None``: not reported), read as
        :meth:`Detector.update` reads one value: times are seconds or
        datetimes; a missing or non-numeric value is NaN. Each vehicle's
        fixes are taken in batch order, and its verdicts are those of one
        Detector that saw its fixes one by one, bit for bit. Never raises on
        bad values (they come back flagged with ``invalid_reason``).
        """
        slots = self._slots(vehicle_ids)
        n = slots.size
        t_f = _times(t, n)
        lat_f = _numbers(lat, n)
        lon_f = _numbers(lon, n)
        speed_f = _reading_column(speed, n)
        heading_f = _reading_column(heading, n)
        receiver = _receiver_codes(fix_quality, satellites, n)
        out = np.full((n, N_POINT_OUT), np.nan)
        settled = np.full((n, N_POINT_OUT), np.nan)
        code = np.zeros(n, np.int64)
        todo = np.arange(n, dtype=np.int64)
        deferred = np.empty(n, np.int64)
        columns = (t_f, lat_f, lon_f, speed_f, heading_f)
        for round_ in range(_MAX_ROUNDS + 1):
            if round_ < _MAX_ROUNDS:
                n_def = _fleet_kernel(
                    self._P,
                    self._S,
                    self._s_off,
                    self._s_len,
                    self._H,
                    self._seg,
                    self._last,
                    self._last_lat,
                    self._last_lon,
                    self._glitch,
                    self._lat0,
                    self._lon0,
                    self._gp,
                    self._lane_work,
                    self._max_gap,
                    slots,
                    t_f,
                    lat_f,
                    lon_f,
                    speed_f,
                    heading_f,
                    receiver,
                    todo,
                    out,
                    settled,
                    code,
                    deferred,
                )
                rest = deferred[:n_def].tolist()
            else:
                rest = todo.tolist()  # the last round: all through the per-fix path
            if not rest:
                break
            back: list[int] = []
            final: set[int] = set()
            for i in rest:
                s = int(slots[i])
                if s in final:
                    back.append(i)  # its period is final again: back to the kernel
                    continue
                t_i, lat_i, lon_i, speed_i, heading_i = (float(c[i]) for c in columns)
                fix = (t_i, lat_i, lon_i, speed_i, heading_i)
                code[i] = self._update_one(s, fix, int(receiver[i]), out[i], settled[i])
                if round_ < _MAX_ROUNDS and self._seg[s] > PERIOD_STEPS:
                    final.add(s)
            if not back:
                break
            todo = np.array(back, np.int64)
        result = self._result(out, code)
        if not self._settles:
            return result
        has = ~np.isnan(settled[:, O_FLAG])
        # Entries that settled none are built as unusable fixes (code 1): they mean nothing.
        previous = self._result(np.where(has[:, None], settled, np.nan), np.where(has, 0, 1))
        return replace(result, settled=previous, has_settled=has)

    def _result(self, out: FloatArray, code: NDArray[np.int64]) -> FleetResult:
        reasons = self._reasons[code]
        ok = code == 0
        bias = np.full(code.size, len(self._bias_names) - 1, np.int64)
        bias[ok] = out[ok, O_BIAS].astype(np.int64)
        kind = np.full(code.size, len(self._time_names) - 1, np.int64)
        kind[ok] = out[ok, O_TIME].astype(np.int64)
        anomaly = np.ones(code.size, np.int8)
        anomaly[ok] = out[ok, O_FLAG].astype(np.int8)
        alert = np.zeros(code.size, np.int8)
        alert[ok] = out[ok, O_ALERT].astype(np.int8)
        return FleetResult(
            anomaly=anomaly,
            score=out[:, O_SCORE].copy(),
            bias_type=self._bias_names[bias],
            time_type=self._time_names[kind],
            lat_clean=out[:, O_LAT].copy(),
            lon_clean=out[:, O_LON].copy(),
            alert=alert,
            invalid_reason=reasons,
        )

    # -- states ----------------------------------------------------------------------

    def get_state(self, vehicle: Hashable) -> dict[str, Any]:
        """``vehicle``'s state, exactly as :meth:`Detector.get_state` of a Detector that saw its
        fixes (restore it in either class). A vehicle not held is a fresh detector."""
        det = self._template  # never fed: its state is a fresh detector's
        s = self._index.get(vehicle)
        if s is None or self._seg[s] == 0:
            return det.get_state()
        a, n = int(self._s_off[s]), int(self._s_len[s])
        return _state(
            det,
            int(self._seg[s]),
            (float(self._lat0[s]), float(self._lon0[s])),
            float(self._last[s]),
            float(self._period[s]),
            self._warm[s],
            self._S[a : a + n],
            self._H[s],
            None
            if np.isnan(self._last_lat[s])
            else (float(self._last_lat[s]), float(self._last_lon[s])),
            bool(self._glitch[s]),
        )

    def set_state(self, vehicle: Hashable, state: Mapping[str, Any]) -> None:
        """Restore ``vehicle`` from a :meth:`get_state` (or :meth:`Detector.get_state`) state of
        the same model and settings. A state the Detector would refuse raises
        :class:`~gradgps.ConfigError` and leaves the vehicle as it was."""
        restored = self._template._checked_state(state)
        frame, last_t, seg, period, warm, P, S, H, last_fix, glitch = restored
        s = self._slot(vehicle)
        self._clear(s)
        if last_fix is not None:
            self._last_lat[s], self._last_lon[s] = last_fix
        self._glitch[s] = glitch
        if seg:
            self._lat0[s], self._lon0[s] = frame.lat0, frame.lon0
            self._last[s] = last_t
            self._seg[s] = seg
            self._period[s] = period
            self._warm[s] = [tuple(w) for w in warm]
            self._store_segment(s, P, S)
            self._H[s] = H


def _fleet_result(results: Sequence[PointResult]) -> FleetResult:
    """Per-fix results as one :class:`FleetResult`."""

    def column(name: str, dtype: Any) -> NDArray[Any]:
        return np.array([getattr(r, name) for r in results], dtype)

    return FleetResult(
        anomaly=column("anomaly", np.int8),
        score=column("score", np.float64),
        bias_type=column("bias_type", object),
        time_type=column("time_type", object),
        lat_clean=column("lat_clean", np.float64),
        lon_clean=column("lon_clean", np.float64),
        alert=column("alert", np.int8),
        invalid_reason=column("invalid_reason", object),
    )


class ReferenceFleet:
    """The readable reference of :class:`FleetDetector`: one :class:`Detector` per vehicle,
    fed fix by fix. Same interface (``update_many``, ``get_state``, ``set_state``, ``drop``)
    and, by test, the same verdicts and states bit for bit; slower."""

    def __init__(
        self, model: str | os.PathLike[str] | None = None, *, threshold: float | None = None
    ) -> None:
        self.tracks = MultiTrackDetector(model, threshold=threshold)

    @property
    def detectors(self) -> dict[Hashable, Detector]:
        """The vehicles' detectors, by vehicle id (those of :attr:`tracks`)."""
        return self.tracks.detectors

    def update_many(
        self,
        vehicle_ids: Sequence[Hashable] | NDArray[Any],
        t: Any,
        lat: Any,
        lon: Any,
        speed: Any = None,
        heading: Any = None,
        *,
        fix_quality: Any = None,
        satellites: Any = None,
    ) -> FleetResult:
        def at(values: Any, i: int) -> Any:
            return None if values is None else values[i]

        results = []
        settled: list[PointResult | None] = []
        for i, v in enumerate(vehicle_ids):
            det = self.tracks.detector(v)
            results.append(
                det.update(
                    t[i],
                    lat[i],
                    lon[i],
                    at(speed, i),
                    at(heading, i),
                    fix_quality=at(fix_quality, i),
                    satellites=at(satellites, i),
                )
            )
            settled.append(det.settled)
        result = _fleet_result(results)
        if not self.tracks.settles:
            return result
        has = np.array([r is not None for r in settled], np.bool_)
        none = PointResult.invalid("")
        previous = _fleet_result([r if r is not None else none for r in settled])
        return replace(result, settled=previous, has_settled=has)

    def get_state(self, vehicle: Hashable) -> dict[str, Any]:
        return self.detectors[vehicle].get_state()

    def set_state(self, vehicle: Hashable, state: Mapping[str, Any]) -> None:
        det = Detector(self.tracks.model, threshold=self.tracks.threshold).set_state(state)
        self.detectors[vehicle] = det

    def drop(self, vehicle: Hashable) -> None:
        self.detectors.pop(vehicle, None)
