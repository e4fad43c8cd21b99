"""Baseline ``cnn``: a 1-D convolutional classifier over a window of readings (torch-free inference).

What it follows: the CNN of van Wyk et al. (2020), which classifies a short
window of recent sensor readings as normal or anomalous. Here: the window of
the last ``W`` input rows ending at the reading being judged (causal, zero
rows before a segment's start) -> Conv1d(F, 32, 5, same) -> ReLU ->
Conv1d(32, 32, 5, same) -> ReLU -> flatten -> Linear(64) -> ReLU ->
Linear(2) -> softmax; the reading is anomalous when P(anomaly) reaches the
threshold tuned on validation.

Where it simplifies: van Wyk et al. turn several sensors' windows into an
image and use 2-D convolutions; a 1-D convolution over time with the
channels as input planes is the same idea for our two (position) or three
(sensor) channels. Input rows are built by :mod:`gradgps._baselines.window`.

Inference is plain NumPy in float32 (tested equal to the PyTorch module
within 1e-5): a convolution is a sliding-window view and one ``einsum``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = ["CNN_WEIGHTS", "cnn_forward", "conv1d_same", "softmax_anomaly"]

CNN_WEIGHTS = (
    "conv1.weight",
    "conv1.bias",
    "conv2.weight",
    "conv2.bias",
    "dense.weight",
    "dense.bias",
    "out.weight",
    "out.bias",
)


def conv1d_same(x: np.ndarray, weight: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """PyTorch ``Conv1d`` with odd kernel ``k`` and zero padding ``k // 2``: (N, Cin, W) -> (N, Cout, W)."""
    k = weight.shape[2]
    padded = np.pad(x, ((0, 0), (0, 0), (k // 2, k // 2)))
    windows = sliding_window_view(padded, k, axis=2)  # (N, Cin, W, k)
    out = np.einsum("ncwk,ock->now", windows, weight, optimize=True) + bias[None, :, None]
    return np.asarray(out, dtype=np.float32)


def softmax_anomaly(logits: np.ndarray) -> np.ndarray:
    """P(class 1) of two-class logits (N, 2), computed without overflow."""
    return np.asarray(1.0 / (1.0 + np.exp(logits[:, 0] - logits[:, 1])), dtype=np.float32)


def cnn_forward(weights: Mapping[str, np.ndarray], windows: np.ndarray) -> np.ndarray:
    """P(anomaly) for scaled windows (N, W, F) float32."""
    x = np.transpose(windows, (0, 2, 1))
    x = np.maximum(conv1d_same(x, weights["conv1.weight"], weights["conv1.bias"]), 0.0)
    x = np.maximum(conv1d_same(x, weights["conv2.weight"], weights["conv2.bias"]), 0.0)
    flat = x.reshape(len(x), -1)
    hidden = np.maximum(flat @ weights["dense.weight"].T + weights["dense.bias"], 0.0)
    return softmax_anomaly(hidden @ weights["out.weight"].T + weights["out.bias"])
