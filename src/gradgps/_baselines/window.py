"""The window classifiers ``cnn`` and ``lstm-cnn`` as detectors: input rows, windows, batch and stream.

Both networks judge a reading from the window of the last ``W`` input rows
ending at it. An input row holds, per channel, the *signal* and its change
since the previous reading:

* ``position``: the signal is the velocity east and north (m/s, the step
  divided by the time step), not the position itself, so nothing depends on
  where the drive is (a position in metres from the track's first fix would
  be meaningless to a network trained elsewhere);
* ``sensor``: the signal is the raw reading (speed, acceleration, yaw rate).

Rows are scaled with the training mean and std; anything undefined (the
first reading's change, a missing reading, ``dt = 0``) scales to 0, the
training mean, and so do the rows before a segment's start. Streaming keeps
the last ``W`` scaled rows and the last two readings, and gives the batch's
numbers (float32 rounding aside: tested within 1e-5).

A model is a directory with ``weights.npz`` and ``config.json``
(architecture, window, input kind, scaler, threshold, training notes),
written by :mod:`gradgps._train.baselines`.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ModelError
from .._result import PointResult, decode_floats, encode_floats
from .._tracks.geo import LocalFrame
from .base import (
    Reading,
    Segment,
    StreamingBaseline,
    flags_frame,
    input_names,
    load_frame,
    load_time,
    segments,
    state_error,
)
from .cnn import CNN_WEIGHTS, cnn_forward
from .lstm_cnn import LSTM_CNN_WEIGHTS, lstm_cnn_forward

__all__ = [
    "ARCHITECTURES",
    "WindowClassifier",
    "WindowModel",
    "input_rows",
    "load_window_model",
    "save_window_model",
    "windows",
]

ARCHITECTURES: dict[
    str, tuple[tuple[str, ...], Callable[[Mapping[str, np.ndarray], np.ndarray], np.ndarray]]
] = {
    "cnn": (CNN_WEIGHTS, cnn_forward),
    "lstm-cnn": (LSTM_CNN_WEIGHTS, lstm_cnn_forward),
}


def _signal(values: np.ndarray, t: np.ndarray, inputs: str) -> np.ndarray:
    if inputs == "sensor":
        return values
    sig = np.full(values.shape, np.nan)
    dt = np.diff(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        sig[1:] = np.where((dt > 0)[:, None], np.diff(values, axis=0) / dt[:, None], np.nan)
    return sig


def input_rows(segment: Segment, inputs: str) -> np.ndarray:
    """Unscaled input rows (n, 2C): per channel the signal, then its change (module docstring)."""
    sig = _signal(segment.values, segment.t, inputs)
    change = np.full(sig.shape, np.nan)
    change[1:] = np.diff(sig, axis=0)
    return np.hstack([sig, change])


def scale_rows(rows: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """``(rows - mean) / std`` in float32, non-finite results 0."""
    scaled = (np.asarray(rows, np.float32) - mean.astype(np.float32)) / std.astype(np.float32)
    scaled[~np.isfinite(scaled)] = 0.0
    return scaled


def windows(scaled: np.ndarray, window: int) -> np.ndarray:
    """(n, W, F) windows ending at each row, zero rows before the first."""
    padded = np.vstack([np.zeros((window - 1, scaled.shape[1]), np.float32), scaled])
    idx = np.arange(len(scaled))[:, None] + np.arange(window)
    out: np.ndarray = padded[idx]
    return out


@dataclass(frozen=True)
class WindowModel:
    """A trained window classifier: weights (float32) plus what decides its input."""

    architecture: str
    inputs: str
    window: int
    mean: np.ndarray
    std: np.ndarray
    threshold: float
    weights: Mapping[str, np.ndarray]
    config: Mapping[str, Any]
    max_gap_s: float = 5.0

    def predict(self, scaled_windows: np.ndarray, batch: int = 4096) -> np.ndarray:
        """P(anomaly) for scaled windows (N, W, F), in batches to bound memory."""
        forward = ARCHITECTURES[self.architecture][1]
        parts = [
            forward(self.weights, scaled_windows[lo : lo + batch])
            for lo in range(0, len(scaled_windows), batch)
        ]
        return np.concatenate(parts) if parts else np.zeros(0, np.float32)

    def segment_probability(self, segment: Segment) -> np.ndarray:
        rows = scale_rows(input_rows(segment, self.inputs), self.mean, self.std)
        return self.predict(windows(rows, self.window))


def save_window_model(directory: str | os.PathLike[str], model: WindowModel) -> None:
    """Write ``weights.npz`` and ``config.json`` (the config carries scaler and threshold)."""
    path = Path(directory)
    path.mkdir(parents=True, exist_ok=True)
    np.savez(
        path / "weights.npz",
        allow_pickle=False,
        **{k: np.asarray(v, np.float32) for k, v in model.weights.items()},
    )
    config = {
        **model.config,
        "architecture": model.architecture,
        "inputs": model.inputs,
        "window": model.window,
        "threshold": model.threshold,
        "max_gap_s": model.max_gap_s,
        "scaler": {"mean": model.mean.tolist(), "std": model.std.tolist()},
    }
    tmp = path / "config.json.tmp"
    tmp.write_text(json.dumps(config, indent=1) + "\n")
    tmp.replace(path / "config.json")


def load_window_model(directory: str | os.PathLike[str]) -> WindowModel:
    """Read a model directory written by :func:`save_window_model`."""
    path = Path(directory)
    try:
        config = json.loads((path / "config.json").read_text())
        with np.load(path / "weights.npz", allow_pickle=False) as data:
            weights = {k: np.asarray(data[k], np.float32) for k in data.files}
        names = ARCHITECTURES[config["architecture"]][0]
        missing = [n for n in names if n not in weights]
        if missing:
            raise ModelError(f"{path}: weights lack {missing}; retrain the model")
        input_names(config["inputs"])
        return WindowModel(
            config["architecture"],
            config["inputs"],
            int(config["window"]),
            np.asarray(config["scaler"]["mean"], np.float32),
            np.asarray(config["scaler"]["std"], np.float32),
            float(config["threshold"]),
            weights,
            config,
            float(config["max_gap_s"]),
        )
    except (OSError, KeyError, ValueError, json.JSONDecodeError) as exc:
        raise ModelError(f"{path}: not a window-classifier model ({exc}); retrain it") from exc


class WindowClassifier(StreamingBaseline):
    """The ``cnn`` or ``lstm-cnn`` baseline for a loaded :class:`WindowModel`: batch and stream.

    It repairs nothing: ``lat_clean``/``lon_clean`` are the input position
    (the source papers detect and identify, they do not recover).
    """

    def __init__(self, model: WindowModel) -> None:
        self.model = model
        self._reset_stream()

    def segment_flags(
        self, fixes: pd.DataFrame
    ) -> tuple[list[Segment], np.ndarray, list[np.ndarray]]:
        """Segments, invalid reasons and P(anomaly) per segment (``cnn-kf`` reuses this)."""
        segs, reason = segments(fixes, self.model.inputs, self.model.max_gap_s)
        return segs, reason, [self.model.segment_probability(s) for s in segs]

    def _detect_core(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """One result row per input row; each segment is windowed on its own, in time order."""
        segs, reason, probs = self.segment_flags(fixes)
        n = len(fixes)
        score = np.full(n, np.nan)
        for seg, p in zip(segs, probs, strict=True):
            score[seg.rows] = p
        return flags_frame(fixes, reason, score, self.model.threshold)

    # -- streaming (one track) ---------------------------------------------

    def _reset_stream(self) -> None:
        self._frame: LocalFrame | None = None
        self._last_t: float | None = None
        self._recent: list[tuple[float, list[float]]] = []  # (t, values) of the last two readings
        self._rows = np.zeros((self.model.window, len(self.model.mean)), np.float32)

    def _update_valid(self, fix: Reading) -> PointResult:
        """Judge one usable reading of this detector's track (time order), as :meth:`detect` would."""
        m, t, lat, lon = self.model, fix.t, fix.lat, fix.lon
        if self._frame is None:
            self._frame = LocalFrame(float(lat), float(lon))
        if self._last_t is not None and t - self._last_t > m.max_gap_s:
            frame = self._frame
            self._reset_stream()
            self._frame = frame
        self._last_t = float(t)
        if m.inputs == "position":
            east, north = self._frame.to_local(lat, lon)
            values = [float(east), float(north)]
        else:
            values = fix.sensor_values()
        self._recent = ([*self._recent, (float(t), values)])[-3:]
        recent = Segment(
            "",
            np.zeros(0, np.int64),
            np.array([r[0] for r in self._recent]),
            np.array([r[1] for r in self._recent]),
            self._frame,
        )
        row = scale_rows(input_rows(recent, m.inputs)[-1:], m.mean, m.std)
        self._rows = np.vstack([self._rows[1:], row])
        p = float(m.predict(self._rows[None])[0])
        return PointResult(int(p >= m.threshold), p, None, None, float(lat), float(lon), 0)

    def get_state(self) -> dict[str, Any]:
        """The stream's memory as strict-JSON-able data."""
        return {
            "frame": None if self._frame is None else [self._frame.lat0, self._frame.lon0],
            "last_t": self._last_t,
            "recent": [[t, encode_floats(v)] for t, v in self._recent],
            "rows": [encode_floats(r) for r in self._rows],
        }

    def set_state(self, state: Mapping[str, Any]) -> WindowClassifier:
        """Restore :meth:`get_state` output of a classifier with the same model; returns self."""
        m = self.model
        channels = len(input_names(m.inputs))
        try:
            frame, last_t = load_frame(state["frame"]), load_time(state["last_t"])
            recent: list[tuple[float, list[float]]] = []
            for t, v in state["recent"]:
                values = decode_floats(v)
                time = load_time(t)
                if values is None or time is None or len(values) != channels:
                    raise ValueError(f"a recent reading is [t, {channels} values], got {[t, v]!r}")
                recent.append((time, values))
            if len(recent) > 3:
                raise ValueError(f"{len(recent)} recent readings, at most 3 are kept")
            rows = np.array([decode_floats(r) for r in state["rows"]], np.float32)
            if rows.shape != self._rows.shape or not np.isfinite(rows).all():
                raise ValueError(f"window rows of shape {rows.shape}, expected {self._rows.shape}")
        except (KeyError, TypeError, ValueError) as exc:
            raise state_error("window classifier", exc) from exc
        self._frame, self._last_t, self._recent, self._rows = frame, last_t, recent, rows
        return self
