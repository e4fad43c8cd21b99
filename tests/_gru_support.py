"""Helpers shared by the GRU tests: random weights, a valid model config, toy labelled data,
and the online GRU objects the product does not use (``GRUStream``, ``GRUFleet``).

The Detector steps the GRU inside its compiled per-fix pipeline
(:mod:`gradgps._grad.pipeline`); ``GRUStream`` (one track, either mode) and
``GRUFleet`` (many tracks stepped together) are kept here for the tests that
check them against the batch predictions and for ``benchmarks/gru_speed.py``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numba
import numpy as np

from gradgps._exceptions import ConfigError
from gradgps._grad.gru import (
    GRUModel,
    GRUPrediction,
    _heads,
    _recurrent_step,
    _scratch_size,
    weight_shapes,
)
from gradgps._grad.model_io import save_model
from gradgps._grad.pipeline import PipelineParams, pipeline_feature_names


def random_weights(
    n_features: int,
    n_bias: int,
    seed: int = 0,
    hidden1: int = 32,
    hidden2: int = 16,
    scale: float = 0.4,
    *,
    confirm_head: bool = False,
) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    shapes = weight_shapes(n_features, hidden1, hidden2, n_bias, confirm_head=confirm_head)
    return {
        name: (rng.normal(size=shape) * scale).astype(np.float32) for name, shape in shapes.items()
    }


def random_detector_model(
    directory: Path,
    threshold: float = 0.5,
    seed: int = 0,
    params: PipelineParams | None = None,
    *,
    confirm_head: bool = False,
) -> Path:
    """A stream model with random weights for the Detector (``params``: its pipeline
    settings, the defaults with ``threshold`` when ``None``), saved to ``directory``;
    ``confirm_head``: with one (threshold 0.5)."""
    params = params or PipelineParams(threshold=threshold)
    names = pipeline_feature_names(params)
    rng = np.random.default_rng(seed)
    config = {
        "architecture": {
            "n_features": len(names),
            "hidden1": 32,
            "hidden2": 16,
            "n_bias_classes": 3,
        },
        "mode": "stream",
        "window": 10,
        "features": {"names": names, "params": {"pipeline": params.to_dict()}},
        "scaler": {
            "mean": rng.normal(0, 0.5, len(names)).tolist(),
            "std": rng.uniform(0.5, 2.0, len(names)).tolist(),
        },
        "thresholds": {"anomaly": threshold},
        "rema": {},
        "class_names": {"anomaly": ["normal", "anomaly"], "bias": ["none", "noise", "jump"]},
    }
    if confirm_head:
        config["architecture"]["confirm_head"] = True  # type: ignore[index]
        config["thresholds"]["confirm"] = 0.5  # type: ignore[index]
    weights = random_weights(len(names), 3, seed=seed, scale=0.6, confirm_head=confirm_head)
    save_model(directory, weights, config)
    return directory


def model_config(
    n_features: int, n_bias: int, *, mode: str = "stream", window: int = 10, seed: int = 0
) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    return {
        "architecture": {
            "n_features": n_features,
            "hidden1": 32,
            "hidden2": 16,
            "n_bias_classes": n_bias,
        },
        "mode": mode,
        "window": window,
        "features": {
            "names": [f"feature_{i}" for i in range(n_features)],
            "params": {"windows": [5, 20]},
        },
        "scaler": {
            "mean": rng.normal(size=n_features).tolist(),
            "std": rng.uniform(0.5, 2.0, size=n_features).tolist(),
        },
        "thresholds": {"anomaly": 0.5},
        "rema": {"alpha": 0.3},
        "class_names": {
            "anomaly": ["normal", "anomaly"],
            "bias": ["none", *(f"b{i}" for i in range(1, n_bias))],
        },
    }


def toy_sequences(
    count: int,
    seed: int,
    n_features: int = 5,
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Noise features; anomalies are +4 on feature 0 (bias class 1) or -4 on feature 1 (class 2)."""
    rng = np.random.default_rng(seed)
    sequences = []
    for _ in range(count):
        length = int(rng.integers(15, 90))
        features = rng.normal(size=(length, n_features)).astype(np.float32)
        anomaly = np.zeros(length, np.int64)
        bias = np.zeros(length, np.int64)
        for column, shift, kind in ((0, 4.0, 1), (1, -4.0, 2)):
            rows = rng.choice(length, max(1, length // 10), replace=False)
            features[rows, column] += shift
            anomaly[rows] = 1
            bias[rows] = kind
        sequences.append((features, anomaly, bias))
    return sequences


@numba.njit(cache=True)
def stream_step_kernel(params: Any, dims: Any, x: Any, state: Any, scratch: Any, out: Any) -> None:
    """(c) One streaming step for one track: advance ``state`` with ``x``, write ``out`` (1+K)."""
    _recurrent_step(params, dims, x, state, scratch)
    _heads(params, dims, state, scratch, out)


@numba.njit(cache=True)
def window_step_kernel(
    params: Any, dims: Any, ring: Any, count: int, state: Any, scratch: Any, out: Any
) -> None:
    """Window mode for one track online: ``ring`` (W, F) holds the last points, the newest at
    ``(count - 1) % W``; runs the window from zero state (``state`` is scratch here)."""
    window = ring.shape[0]
    state[:] = 0.0
    first = max(0, count - window)
    for t in range(first, count):
        _recurrent_step(params, dims, ring[t % window], state, scratch)
    _heads(params, dims, state, scratch, out)


@numba.njit(cache=True)
def fleet_step_kernel(
    params: Any, dims: Any, rows: Any, features: Any, states: Any, out: Any
) -> None:
    """(d) One streaming step for many tracks: ``states[rows[i]]`` advanced with ``features[i]``."""
    scratch = np.empty(_scratch_size(dims), np.float32)
    for i in range(rows.shape[0]):
        state = states[rows[i]]
        _recurrent_step(params, dims, features[i], state, scratch)
        _heads(params, dims, state, scratch, out[i])


class GRUStream:
    """Online predictions for one track, one point at a time (river style).

    Stream mode keeps the GRU state (hidden1 + hidden2 floats) and costs one
    step per point; window mode keeps the last W feature rows and reruns the
    window from zero state, W steps per point. Call :meth:`reset` at every
    segment start. :meth:`update` returns a view of an internal buffer,
    overwritten by the next call: copy it to keep it.
    """

    def __init__(self, model: GRUModel) -> None:
        self.model = model
        self._state = np.zeros(model.state_size, np.float32)
        self._scratch = np.empty(
            model.n_features + 6 * int(max(model.dims[1], model.dims[2])), np.float32
        )
        self._out = np.empty(model.n_outputs, np.float32)
        self._ring = np.zeros((model.window, model.n_features), np.float32)
        self._count = 0

    def reset(self) -> None:
        """Forget the past (a new segment starts)."""
        self._state[:] = 0.0
        self._count = 0

    def update(self, features: np.ndarray) -> np.ndarray:
        """Feed one point's features (F,); returns ``[P(anomaly), P(bias class 0..K-1)]``."""
        model = self.model
        x = features if isinstance(features, np.ndarray) else np.asarray(features, np.float32)
        if x.shape != self._ring.shape[1:]:  # the kernel would read out of bounds
            raise ConfigError(f"features must have shape ({model.n_features},), got {x.shape}")
        if model.mode == "stream":
            stream_step_kernel(model.params, model.dims, x, self._state, self._scratch, self._out)
        else:
            self._ring[self._count % model.window] = x
            self._count += 1
            window_step_kernel(
                model.params,
                model.dims,
                self._ring,
                self._count,
                self._state,
                self._scratch,
                self._out,
            )
        return self._out

    def get_state(self) -> dict[str, Any]:
        """Plain JSON-able state: the GRU state (stream) or the last points (window)."""
        if self.model.mode == "stream":
            return {"mode": "stream", "h": self._state.tolist()}
        window = self.model.window
        last = [
            self._ring[t % window].tolist()
            for t in range(max(0, self._count - window), self._count)
        ]
        return {"mode": "window", "count": self._count, "last": last}

    def set_state(self, state: Mapping[str, Any]) -> None:
        """Restore what :meth:`get_state` returned (for the same model)."""
        if state.get("mode") != self.model.mode:
            raise ConfigError(
                f"state is for mode {state.get('mode')!r}, this model streams in {self.model.mode!r}"
            )
        if self.model.mode == "stream":
            self._state[:] = self.model._state(np.asarray(state["h"], np.float32))
            return
        last = np.asarray(state["last"], np.float32).reshape(-1, self.model.n_features)
        count = int(state["count"])
        if len(last) != min(count, self.model.window):
            raise ConfigError(f"window state holds {len(last)} points but count={count}")
        self._count = count
        for t, row in zip(range(max(0, count - self.model.window), count), last, strict=True):
            self._ring[t % self.model.window] = row


class GRUFleet:
    """Streaming state of many tracks, stepped together: ``states`` is (n_tracks, hidden1 + hidden2).

    Each call advances only the tracks in ``rows`` (vehicles report at
    different times); :meth:`reset` zeroes tracks whose segment restarts.
    """

    def __init__(self, model: GRUModel, n_tracks: int) -> None:
        if model.mode != "stream":
            raise ConfigError(
                "fleet stepping needs a stream-mode model; window-mode models "
                "rerun W points per step, use one GRUStream per track"
            )
        self.model = model
        self.states = np.zeros((n_tracks, model.state_size), np.float32)

    def reset(self, rows: np.ndarray) -> None:
        self.states[np.asarray(rows, np.int64)] = 0.0

    def step(self, rows: np.ndarray, features: np.ndarray) -> GRUPrediction:
        """Advance track ``rows[i]`` with ``features[i]``, in order (a repeated row takes its points in turn)."""
        rows = np.ascontiguousarray(rows, dtype=np.int64)
        x = self.model._features(features)
        if rows.shape != (len(x),):
            raise ConfigError(f"need one row index per feature row: {rows.shape} vs {len(x)} rows")
        if rows.size and (rows.min() < 0 or rows.max() >= len(self.states)):
            raise ConfigError(f"track rows must be in 0..{len(self.states) - 1}")
        out = np.empty((len(x), self.model.n_outputs), np.float32)
        fleet_step_kernel(self.model.params, self.model.dims, rows, x, self.states, out)
        return self.model._split(out)
