"""Helpers shared by the GRU tests: random weights, a valid model config, toy labelled data."""

from __future__ import annotations

from typing import Any

import numpy as np

from gradgps._grad.gru import weight_shapes


def random_weights(
    n_features: int,
    n_bias: int,
    seed: int = 0,
    hidden1: int = 32,
    hidden2: int = 16,
    scale: float = 0.4,
) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        name: (rng.normal(size=shape) * scale).astype(np.float32)
        for name, shape in weight_shapes(n_features, hidden1, hidden2, n_bias).items()
    }


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
