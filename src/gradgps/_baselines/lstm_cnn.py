"""Baseline ``lstm-cnn``: convolutions, an LSTM and content-based attention (torch-free inference).

What it follows: MSALSTM-CNN of Javed et al. (2021) ("ML-C" in the paper's
comparison table): convolutional layers extract local patterns from the
window of recent readings, an LSTM carries them through time, an attention
stage weighs the LSTM's outputs by their content, and dense layers classify.
Here: window (N, W, F) -> three Conv1d(·, 32, 3, same) + ReLU -> LSTM(32)
over the W steps -> attention ``a_t = softmax_t(v · tanh(A h_t + b))``,
context ``Σ a_t h_t`` -> Linear(32) -> ReLU -> Linear(2) -> P(anomaly).

Where it simplifies: Javed et al. stack several attention stages and feed
the result to a weight-adjusted ensemble (WAVED); we keep one attention
stage and no ensemble, so this stands for their "ML-C" column, not WAVED.

Inference is NumPy in float32, PyTorch's LSTM equations (gate order
i, f, g, o; both biases), tested equal to the PyTorch module within 1e-5.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .cnn import conv1d_same, softmax_anomaly

__all__ = ["LSTM_CNN_WEIGHTS", "lstm_cnn_forward"]

LSTM_CNN_WEIGHTS = (
    "conv1.weight",
    "conv1.bias",
    "conv2.weight",
    "conv2.bias",
    "conv3.weight",
    "conv3.bias",
    "lstm.weight_ih_l0",
    "lstm.weight_hh_l0",
    "lstm.bias_ih_l0",
    "lstm.bias_hh_l0",
    "attention.weight",
    "attention.bias",
    "attention_v.weight",
    "dense.weight",
    "dense.bias",
    "out.weight",
    "out.bias",
)


def _sigmoid(v: np.ndarray) -> np.ndarray:
    return np.asarray(0.5 * (1.0 + np.tanh(0.5 * v)), dtype=np.float32)


def _lstm(weights: Mapping[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """All hidden states (N, W, H) of a one-layer LSTM from zero state over x (N, W, I)."""
    w_ih, w_hh = weights["lstm.weight_ih_l0"], weights["lstm.weight_hh_l0"]
    bias = weights["lstm.bias_ih_l0"] + weights["lstm.bias_hh_l0"]
    size = w_hh.shape[1]
    n, steps, _ = x.shape
    h = np.zeros((n, size), np.float32)
    c = np.zeros((n, size), np.float32)
    inputs = x @ w_ih.T + bias  # (N, W, 4H), the input half of every gate at once
    out = np.empty((n, steps, size), np.float32)
    for s in range(steps):
        gates = inputs[:, s] + h @ w_hh.T
        i = _sigmoid(gates[:, :size])
        f = _sigmoid(gates[:, size : 2 * size])
        g = np.tanh(gates[:, 2 * size : 3 * size])
        o = _sigmoid(gates[:, 3 * size :])
        c = f * c + i * g
        h = o * np.tanh(c)
        out[:, s] = h
    return out


def lstm_cnn_forward(weights: Mapping[str, np.ndarray], windows: np.ndarray) -> np.ndarray:
    """P(anomaly) for scaled windows (N, W, F) float32."""
    x = np.transpose(windows, (0, 2, 1))
    for layer in ("conv1", "conv2", "conv3"):
        x = np.maximum(conv1d_same(x, weights[f"{layer}.weight"], weights[f"{layer}.bias"]), 0.0)
    states = _lstm(weights, np.ascontiguousarray(np.transpose(x, (0, 2, 1))))
    energy = np.tanh(states @ weights["attention.weight"].T + weights["attention.bias"])
    energy = (energy @ weights["attention_v.weight"].T)[:, :, 0]  # (N, W)
    energy = np.exp(energy - energy.max(axis=1, keepdims=True))
    attention = energy / energy.sum(axis=1, keepdims=True)
    context = np.einsum("nw,nwh->nh", attention, states).astype(np.float32)
    hidden = np.maximum(context @ weights["dense.weight"].T + weights["dense.bias"], 0.0)
    return softmax_anomaly(hidden @ weights["out.weight"].T + weights["out.bias"])
