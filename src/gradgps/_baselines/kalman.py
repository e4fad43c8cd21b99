"""Baseline ``kf``: constant-velocity Kalman filter with a chi-square test on the innovation.

What it follows: the Kalman filter + χ² detector of the sensor-fault
literature the paper compares with (van Wyk et al. 2020, "KF" column). Every
channel is a constant-velocity model, state ``[x, v]``, white-noise
acceleration of intensity ``q`` (process noise
``q·[[dt³/3, dt²/2], [dt²/2, dt]]``), reading noise variance ``r``. Per
reading the normalised innovation squared ``NIS = y²/S`` (``y`` the reading
minus the prediction, ``S`` its predicted variance) is compared with a
threshold; a flagged reading is **replaced by the prediction** (the filter
does not update on it), as the χ² detectors of that literature do.

* ``position`` input: east and north are two independent channels (same
  model), tested *jointly*: ``NIS_east + NIS_north`` against one threshold
  (χ² with 2 degrees of freedom); a flagged fix skips both updates.
* ``sensor`` input: speed, acceleration and yaw rate are tested one by one
  (χ² with 1 degree of freedom each); a reading is flagged when any channel
  is, and only the flagged channel skips its update.

Where it simplifies: ``q`` and ``r`` of each channel are fitted by maximum
likelihood on a grid over the *clean* training drives, and the threshold is
the value on a grid with the best anomaly F1 on the validation split with
injected faults (the papers tune by hand and do not say how). The filter
starts each segment at the first reading with velocity 0 and a diffuse
velocity variance, so the first few readings are never flagged. A missing
sensor reading (NaN) is neither used nor flagged.

``cnn-kf`` (:mod:`gradgps._baselines.cnn_kf`) reuses the kernel: readings its CNN
flags are *forced* -- flagged and never used to update.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._exceptions import ConfigError
from .._result import PointResult, decode_floats, encode_floats, f1_score, result_frame
from .._tracks.geo import LocalFrame
from .base import (
    Reading,
    Segment,
    StreamingBaseline,
    input_names,
    load_frame,
    load_time,
    segments,
    state_error,
)

__all__ = ["KalmanDetector", "KalmanParams", "kf_reference", "kf_segment"]

FloatArray = NDArray[np.float64]

#: Diffuse initial velocity variance (units²/s²): the first step decides the velocity.
INITIAL_VELOCITY_VAR = 1e4
# Per-channel state: x, v, P00, P01, P11, started (0/1).
_X, _V, _P00, _P01, _P11, _STARTED = range(6)
N_CHANNEL_STATE = 6
_Q_GRID = np.geomspace(1e-4, 1e2, 25)
_R_GRID = np.geomspace(1e-4, 1e2, 25)
_THRESHOLD_GRID = np.geomspace(1.0, 1e4, 81)


# ----------------------------------------------------------------------------
# Readable reference: matrices, one line per equation.
# ----------------------------------------------------------------------------


def kf_reference(
    values: FloatArray,
    dt: FloatArray,
    q: FloatArray,
    r: FloatArray,
    threshold: float,
    joint: bool,
    forced: NDArray[np.bool_] | None = None,
) -> FloatArray:
    """Per reading: ``[flag, max NIS, clean values (C)]``; the numba kernel must agree."""
    n, c = values.shape
    forced = np.zeros(n, bool) if forced is None else forced
    out = np.zeros((n, 2 + c))
    x = [np.zeros(2) for _ in range(c)]
    p = [np.zeros((2, 2)) for _ in range(c)]
    started = [False] * c
    h = np.array([1.0, 0.0])
    for i in range(n):
        nis = np.zeros(c)
        pred = np.full(c, np.nan)
        usable = np.isfinite(values[i])
        for k in range(c):
            if not started[k]:
                continue
            f = np.array([[1.0, dt[i]], [0.0, 1.0]])
            qm = q[k] * np.array([[dt[i] ** 3 / 3, dt[i] ** 2 / 2], [dt[i] ** 2 / 2, dt[i]]])
            x[k] = f @ x[k]
            p[k] = f @ p[k] @ f.T + qm
            pred[k] = x[k][0]
            if usable[k]:
                s = h @ p[k] @ h + r[k]
                nis[k] = (values[i, k] - pred[k]) ** 2 / s
        flagged_channel = np.zeros(c, bool)
        if joint:
            flagged_channel[:] = nis.sum() > threshold
            score = nis.sum()
        else:
            flagged_channel = nis > threshold
            score = nis.max() if c else 0.0
        if forced[i]:
            flagged_channel[:] = True
        for k in range(c):
            if not started[k]:
                if usable[k] and not forced[i]:
                    x[k] = np.array([values[i, k], 0.0])
                    p[k] = np.diag([r[k], INITIAL_VELOCITY_VAR])
                    started[k] = True
                out[i, 2 + k] = values[i, k]
                flagged_channel[k] = flagged_channel[k] and forced[i]
                continue
            if usable[k] and not flagged_channel[k]:
                s = h @ p[k] @ h + r[k]
                gain = p[k] @ h / s
                x[k] = x[k] + gain * (values[i, k] - pred[k])
                p[k] = (np.eye(2) - np.outer(gain, h)) @ p[k]
                out[i, 2 + k] = values[i, k]
            else:
                out[i, 2 + k] = pred[k] if flagged_channel[k] else values[i, k]
        out[i, 0] = float((flagged_channel & (usable | forced[i])).any())
        out[i, 1] = score
    return out


# ----------------------------------------------------------------------------
# numba kernels: the same filter, scalar algebra, state in one array.
# ----------------------------------------------------------------------------


@numba.njit(cache=True)
def kf_step(
    state: FloatArray,
    z: FloatArray,
    dt: float,
    q: FloatArray,
    r: FloatArray,
    threshold: float,
    joint: bool,
    forced: bool,
    out: FloatArray,
) -> None:
    """Advance every channel by one reading; ``out`` = ``[flag, max NIS, clean values]``."""
    c = z.size
    nis_sum = 0.0
    nis_max = 0.0
    pred = np.empty(c)
    nis = np.zeros(c)
    for k in range(c):
        st = state[k]
        if st[_STARTED] == 0.0:
            pred[k] = np.nan
            continue
        d = dt
        st[_X] += st[_V] * d
        p00 = st[_P00] + 2.0 * d * st[_P01] + d * d * st[_P11] + q[k] * d * d * d / 3.0
        p01 = st[_P01] + d * st[_P11] + q[k] * d * d / 2.0
        p11 = st[_P11] + q[k] * d
        st[_P00], st[_P01], st[_P11] = p00, p01, p11
        pred[k] = st[_X]
        if np.isfinite(z[k]):
            y = z[k] - st[_X]
            nis[k] = y * y / (p00 + r[k])
        nis_sum += nis[k]
        nis_max = max(nis_max, nis[k])
    any_flag = False
    for k in range(c):
        st = state[k]
        usable = np.isfinite(z[k])
        flagged = forced or (nis_sum > threshold if joint else nis[k] > threshold)
        if st[_STARTED] == 0.0:
            if usable and not forced:
                st[_X], st[_V] = z[k], 0.0
                st[_P00], st[_P01], st[_P11] = r[k], 0.0, INITIAL_VELOCITY_VAR
                st[_STARTED] = 1.0
            out[2 + k] = z[k]
            any_flag = any_flag or forced
            continue
        if usable and not flagged:
            s = st[_P00] + r[k]
            k0 = st[_P00] / s
            k1 = st[_P01] / s
            y = z[k] - st[_X]
            st[_X] += k0 * y
            st[_V] += k1 * y
            p00, p01, p11 = st[_P00], st[_P01], st[_P11]
            st[_P00] = p00 - k0 * p00
            st[_P01] = p01 - k0 * p01
            st[_P11] = p11 - k1 * p01
            out[2 + k] = z[k]
        else:
            out[2 + k] = pred[k] if flagged else z[k]
            any_flag = any_flag or (flagged and (usable or forced))
    out[0] = 1.0 if any_flag else 0.0
    out[1] = nis_sum if joint else nis_max


@numba.njit(cache=True)
def kf_segment_kernel(
    values: FloatArray,
    dt: FloatArray,
    q: FloatArray,
    r: FloatArray,
    threshold: float,
    joint: bool,
    forced: NDArray[np.bool_],
) -> FloatArray:
    n, c = values.shape
    state = np.zeros((c, N_CHANNEL_STATE))
    out = np.empty((n, 2 + c))
    for i in range(n):
        kf_step(state, values[i], dt[i], q, r, threshold, joint, forced[i], out[i])
    return out


@numba.njit(cache=True)
def _neg_log_likelihood(
    values: FloatArray, dt: FloatArray, q: float, r: float
) -> tuple[float, int]:
    """Sum of ``log S + y²/S`` over the innovations of one channel (no test, every reading used)."""
    x = v = p00 = p01 = p11 = 0.0
    started = False
    total = 0.0
    count = 0
    for i in range(values.size):
        z = values[i]
        if not np.isfinite(z):
            continue
        if not started:
            x, v, p00, p01, p11 = z, 0.0, r, 0.0, INITIAL_VELOCITY_VAR
            started = True
            continue
        d = dt[i]
        x += v * d
        p00, p01, p11 = (
            p00 + 2.0 * d * p01 + d * d * p11 + q * d * d * d / 3.0,
            p01 + d * p11 + q * d * d / 2.0,
            p11 + q * d,
        )
        s = p00 + r
        y = z - x
        if count > 0 or i > 2:  # the diffuse start says nothing about q and r
            total += math.log(s) + y * y / s
            count += 1
        k0, k1 = p00 / s, p01 / s
        x += k0 * y
        v += k1 * y
        p00, p01, p11 = p00 - k0 * p00, p01 - k0 * p01, p11 - k1 * p01
    return total, count


def _dt(t: FloatArray) -> FloatArray:
    return np.diff(t, prepend=t[:1]) if t.size else t.copy()


def kf_segment(
    segment: Segment,
    q: FloatArray,
    r: FloatArray,
    threshold: float,
    joint: bool,
    forced: NDArray[np.bool_] | None = None,
) -> FloatArray:
    """The filter over one segment: ``(n, 2 + C)`` rows of ``[flag, NIS, clean values]``."""
    n = len(segment.t)
    mask = np.zeros(n, bool) if forced is None else np.ascontiguousarray(forced, dtype=bool)
    return kf_segment_kernel(
        segment.values,
        _dt(segment.t),
        np.asarray(q, np.float64),
        np.asarray(r, np.float64),
        float(threshold),
        joint,
        mask,
    )


def fit_noise(segs: Sequence[Segment]) -> tuple[FloatArray, FloatArray]:
    """Per channel ``(q, r)`` with the highest innovation likelihood on clean segments (grid)."""
    if not segs:
        raise ConfigError("fitting the Kalman filter needs at least one clean segment")
    c = segs[0].values.shape[1]
    q_best, r_best = np.ones(c), np.ones(c)
    for k in range(c):
        best = math.inf
        for q in _Q_GRID:
            for r in _R_GRID:
                total = 0.0
                for seg in segs:
                    total += _neg_log_likelihood(
                        np.ascontiguousarray(seg.values[:, k]), _dt(seg.t), float(q), float(r)
                    )[0]
                if total < best:
                    best, q_best[k], r_best[k] = total, q, r
    return q_best, r_best


def tune_threshold(
    segs: Sequence[Segment],
    labels: Sequence[np.ndarray],
    q: FloatArray,
    r: FloatArray,
    joint: bool,
    forced: Sequence[NDArray[np.bool_]] | None = None,
) -> float:
    """The NIS threshold on a grid with the best anomaly F1 over labelled segments (ties: higher)."""
    truth = np.concatenate(labels).astype(bool)
    best_f1, best = -1.0, float(_THRESHOLD_GRID[-1])
    for threshold in _THRESHOLD_GRID[::-1]:
        flags = (
            np.concatenate(
                [
                    kf_segment(
                        seg, q, r, float(threshold), joint, None if forced is None else forced[i]
                    )[:, 0]
                    for i, seg in enumerate(segs)
                ]
            )
            == 1.0
        )
        f1 = f1_score(truth, flags)
        if f1 > best_f1:
            best_f1, best = f1, float(threshold)
    return best


@dataclass(frozen=True)
class KalmanParams:
    """A fitted filter: per-channel ``q``, ``r``, the NIS threshold, the input kind."""

    inputs: str
    q: tuple[float, ...]
    r: tuple[float, ...]
    threshold: float
    max_gap_s: float = 5.0

    @property
    def joint(self) -> bool:
        return self.inputs == "position"

    def to_dict(self) -> dict[str, Any]:
        return {
            "inputs": self.inputs,
            "q": list(self.q),
            "r": list(self.r),
            "threshold": self.threshold,
            "max_gap_s": self.max_gap_s,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> KalmanParams:
        try:
            return cls(
                str(data["inputs"]),
                tuple(float(v) for v in data["q"]),
                tuple(float(v) for v in data["r"]),
                float(data["threshold"]),
                float(data["max_gap_s"]),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not Kalman filter settings: {exc}") from exc


def detect_with_filter(
    fixes: pd.DataFrame, params: KalmanParams, forced: dict[str, Any] | None = None
) -> tuple[list[Segment], np.ndarray, list[FloatArray]]:
    """Segments, invalid reasons and per-segment filter outputs for a batch of fixes."""
    segs, reason = segments(fixes, params.inputs, params.max_gap_s)
    q, r = np.array(params.q), np.array(params.r)
    outs = [
        kf_segment(
            seg, q, r, params.threshold, params.joint, None if forced is None else forced[str(i)]
        )
        for i, seg in enumerate(segs)
    ]
    return segs, reason, outs


def filter_result(
    fixes: pd.DataFrame,
    params: KalmanParams,
    segs: Sequence[Segment],
    reason: np.ndarray,
    outs: Sequence[FloatArray],
    extra_flag: Sequence[np.ndarray] | None = None,
    extra_score: Sequence[np.ndarray] | None = None,
) -> pd.DataFrame:
    """The detector-interface frame from filter outputs (shared by ``kf`` and ``cnn-kf``)."""
    n = len(fixes)
    anomaly = np.zeros(n, np.int8)
    score = np.full(n, np.nan)
    lat_clean = fixes["lat"].to_numpy(dtype=np.float64).copy()
    lon_clean = fixes["lon"].to_numpy(dtype=np.float64).copy()
    for i, (seg, out) in enumerate(zip(segs, outs, strict=True)):
        flag = out[:, 0] == 1.0
        s = out[:, 1] / (out[:, 1] + params.threshold)
        if extra_flag is not None and extra_score is not None:
            flag = flag | extra_flag[i]
            s = np.maximum(s, extra_score[i])
        anomaly[seg.rows] = flag
        score[seg.rows] = s
        if params.inputs == "position":
            lat, lon = seg.frame.to_geodetic(out[:, 2], out[:, 3])
            lat_clean[seg.rows] = np.where(flag, lat, lat_clean[seg.rows])
            lon_clean[seg.rows] = np.where(flag, lon, lon_clean[seg.rows])
    return result_frame(
        fixes.index, reason, anomaly=anomaly, score=score, lat_clean=lat_clean, lon_clean=lon_clean
    )


class KalmanDetector(StreamingBaseline):
    """The ``kf`` baseline: batch ``detect`` and streaming ``update`` (module docstring).

    ``inputs`` is ``position`` (protocol ``grad``) or ``sensor`` (protocol
    ``sensor-grid``). :meth:`fit` sets ``params_`` from clean training
    fixes and labelled validation fixes; :meth:`from_params` builds a fitted
    detector directly.
    """

    def __init__(self, inputs: str = "position", max_gap_s: float = 5.0) -> None:
        self.inputs = inputs
        self.max_gap_s = max_gap_s
        self._reset_stream()

    @classmethod
    def from_params(cls, params: KalmanParams) -> KalmanDetector:
        det = cls(params.inputs, params.max_gap_s)
        det.params_ = params
        return det

    def fit(
        self,
        train_fixes: Sequence[pd.DataFrame],
        val_fixes: Sequence[pd.DataFrame],
        val_labels: Sequence[np.ndarray],
    ) -> KalmanDetector:
        """``q``, ``r`` from the clean ``train_fixes``; threshold from labelled ``val_fixes``.

        ``val_labels[i]`` holds one 0/1 label per row of ``val_fixes[i]``.
        """
        input_names(self.inputs)
        train = [s for f in train_fixes for s in segments(f, self.inputs, self.max_gap_s)[0]]
        q, r = fit_noise(train)
        val_segs, val_truth = [], []
        for fixes, labels in zip(val_fixes, val_labels, strict=True):
            segs = segments(fixes, self.inputs, self.max_gap_s)[0]
            val_segs += segs
            val_truth += [np.asarray(labels)[s.rows] for s in segs]
        joint = self.inputs == "position"
        threshold = tune_threshold(val_segs, val_truth, q, r, joint)
        self.params_ = KalmanParams(
            self.inputs, tuple(q.tolist()), tuple(r.tolist()), threshold, self.max_gap_s
        )
        return self

    def _fitted(self) -> KalmanParams:
        params: KalmanParams | None = getattr(self, "params_", None)
        if params is None:
            raise ConfigError("this KalmanDetector is not fitted; call fit() or use from_params()")
        return params

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """One result row per input row; each segment runs through a fresh filter in time order."""
        params = self._fitted()
        segs, reason, outs = detect_with_filter(fixes, params)
        return filter_result(fixes, params, segs, reason, outs)

    # -- streaming (one track) ---------------------------------------------

    def _reset_stream(self) -> None:
        self._frame: LocalFrame | None = None
        self._last_t: float | None = None
        self._state: FloatArray | None = None

    def _update_valid(self, fix: Reading) -> PointResult:
        """Judge one usable reading of this detector's track, as :meth:`detect` would."""
        return self.step_valid(fix, forced=False)

    def step_valid(self, fix: Reading, *, forced: bool) -> PointResult:
        """:meth:`_update_valid` with ``forced``: flag the reading and never use it (``cnn-kf``)."""
        t, lat, lon = fix.t, fix.lat, fix.lon
        params = self._fitted()
        if self._frame is None:
            self._frame = LocalFrame(float(lat), float(lon))
        if params.inputs == "position":
            east, north = self._frame.to_local(lat, lon)
            z = np.array([float(east), float(north)])
        else:
            z = np.array(fix.sensor_values())
        gap = self._last_t is None or t - self._last_t > params.max_gap_s
        if gap or self._state is None:
            self._state = np.zeros((z.size, N_CHANNEL_STATE))
        dt = 0.0 if gap or self._last_t is None else float(t) - self._last_t
        self._last_t = float(t)
        out = np.empty(2 + z.size)
        kf_step(
            self._state,
            z,
            dt,
            np.array(params.q),
            np.array(params.r),
            params.threshold,
            params.joint,
            forced,
            out,
        )
        lat_c, lon_c = float(lat), float(lon)
        if out[0] == 1.0 and params.inputs == "position":
            la, lo = self._frame.to_geodetic(out[2], out[3])
            lat_c, lon_c = float(la), float(lo)
        return PointResult(
            int(out[0]), float(out[1] / (out[1] + params.threshold)), None, None, lat_c, lon_c, 0
        )

    def get_state(self) -> dict[str, Any]:
        """The stream's memory as strict-JSON-able data (the fitted settings are not state)."""
        return {
            "frame": None if self._frame is None else [self._frame.lat0, self._frame.lon0],
            "last_t": self._last_t,
            "state": None if self._state is None else [encode_floats(r) for r in self._state],
        }

    def set_state(self, state: Mapping[str, Any]) -> KalmanDetector:
        """Restore :meth:`get_state` output of a filter with the same input kind; returns self."""
        channels = len(input_names(self._fitted().inputs))
        try:
            frame, last_t = load_frame(state["frame"]), load_time(state["last_t"])
            rows = state["state"]
            filt = None
            if rows is not None:
                filt = np.array([decode_floats(r) for r in rows], np.float64)
                if filt.shape != (channels, N_CHANNEL_STATE):
                    raise ValueError(
                        f"filter state of shape {filt.shape}, expected ({channels}, {N_CHANNEL_STATE})"
                    )
        except (KeyError, TypeError, ValueError) as exc:
            raise state_error("Kalman detector", exc) from exc
        self._frame, self._last_t, self._state = frame, last_t, filt
        return self
