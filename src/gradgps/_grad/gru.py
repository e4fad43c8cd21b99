"""Torch-free inference for the GRAD network (paper sections 3.3 and 4.5).

The network is the paper's "optimized and lightweight" stacked GRU: a feature
scaler, a GRU layer of 32 units, a GRU layer of 16 units, then per point two
dense softmax heads: the paper's anomaly head (normal/anomaly) and a bias-type
head (``none`` plus the fault types of the labelling protocol). A model may
have a third, the *confirm* head (:data:`CONFIRM_NAMES`): P(anomaly) of the
point *before*, judged with this point seen
(:class:`gradgps._train.torch_gru.GRADNet`). Training
happens in PyTorch (:mod:`gradgps._train.torch_gru`); deployment must not need it, so
this module re-implements the forward pass with NumPy (readable reference) and
numba (fast kernels), and never imports torch.

The equations are PyTorch's ``nn.GRU`` ones, gate order ``r, z, n`` in the
stacked weight matrices, *both* input and hidden biases::

    r  = sigmoid(W_ir x + b_ir + W_hr h + b_hr)
    z  = sigmoid(W_iz x + b_iz + W_hz h + b_hz)
    n  = tanh(W_in x + b_in + r * (W_hn h + b_hn))
    h' = (1 - z) * n + z * h

(the paper writes the same cell with one bias per gate; PyTorch's form has the
reset gate applied to ``W_hn h + b_hn``, and that is what a trained model
needs). ``sigmoid(v)`` is computed as ``0.5 * (1 + tanh(v / 2))``: the same
function, but it cannot overflow for large negative ``v``.

Two ways to feed the network:

* **window** (the paper's "feed sliding window", W = 10 or 50): the
  prediction for point ``i`` comes from a fresh zero state run over the
  points ``max(0, i-W+1) .. i``. Cost per point is W GRU steps, O(W); the
  first W-1 points of a segment see a shorter window.
* **stream**: one state carried from point to point, one GRU step per point,
  O(1). The state must be reset (zeros) at the start of every segment, the
  same way training starts each sequence from zeros.

Non-finite scaled features (NaN or +-inf) are replaced by 0, i.e. by the
training mean: one NaN would otherwise poison a streaming state for good.

Weights are a ``dict[str, np.ndarray]`` with PyTorch-like names (see
:data:`WEIGHT_NAMES`); the scaler's mean and std come separately (they live
in the model directory's ``config.json``). The numba kernels take everything
packed in one flat float32 vector (:func:`pack_parameters`) so that calling a
kernel from Python costs few argument checks: a single streaming step is
dominated by the dispatch, not the arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from .._exceptions import ConfigError, ModelError

__all__ = [
    "CONFIRM_NAMES",
    "MODES",
    "WEIGHT_NAMES",
    "GRUModel",
    "GRUPrediction",
    "pack_parameters",
    "reference_stream",
    "reference_windows",
    "scale_features",
    "weight_shapes",
]

MODES = ("window", "stream")

WEIGHT_NAMES = (
    "gru1.weight_ih",
    "gru1.weight_hh",
    "gru1.bias_ih",
    "gru1.bias_hh",
    "gru2.weight_ih",
    "gru2.weight_hh",
    "gru2.bias_ih",
    "gru2.bias_hh",
    "anomaly_head.weight",
    "anomaly_head.bias",
    "bias_head.weight",
    "bias_head.bias",
)

#: The optional confirm head's arrays (a model has both or neither).
CONFIRM_NAMES = ("confirm_head.weight", "confirm_head.bias")


def weight_shapes(
    n_features: int,
    hidden1: int,
    hidden2: int,
    n_bias_classes: int,
    *,
    confirm_head: bool = False,
) -> dict[str, tuple[int, ...]]:
    """The shape of every weight array, as PyTorch stores it (``(out, in)`` matrices)."""
    confirm: dict[str, tuple[int, ...]] = (
        {"confirm_head.weight": (2, hidden2), "confirm_head.bias": (2,)} if confirm_head else {}
    )
    return {
        "gru1.weight_ih": (3 * hidden1, n_features),
        "gru1.weight_hh": (3 * hidden1, hidden1),
        "gru1.bias_ih": (3 * hidden1,),
        "gru1.bias_hh": (3 * hidden1,),
        "gru2.weight_ih": (3 * hidden2, hidden1),
        "gru2.weight_hh": (3 * hidden2, hidden2),
        "gru2.bias_ih": (3 * hidden2,),
        "gru2.bias_hh": (3 * hidden2,),
        "anomaly_head.weight": (2, hidden2),
        "anomaly_head.bias": (2,),
        "bias_head.weight": (n_bias_classes, hidden2),
        "bias_head.bias": (n_bias_classes,),
        **confirm,
    }


# ----------------------------------------------------------------------------
# NumPy reference: readable, one line per equation. The numba kernels below
# must agree with it (tests/test_gru.py).
# ----------------------------------------------------------------------------


def _sigmoid(v: np.ndarray) -> np.ndarray:
    return np.asarray(0.5 * (1.0 + np.tanh(0.5 * v)), dtype=v.dtype)


def _softmax(logits: np.ndarray) -> np.ndarray:
    e = np.exp(logits - logits.max(axis=-1, keepdims=True))
    return np.asarray(e / e.sum(axis=-1, keepdims=True), dtype=logits.dtype)


def scale_features(features: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """``(x - mean) / std`` as float32, with non-finite results replaced by 0."""
    scaled = (np.asarray(features, dtype=np.float32) - mean.astype(np.float32)) / std.astype(
        np.float32
    )
    scaled[~np.isfinite(scaled)] = 0.0
    return scaled


def _reference_cell(
    x: np.ndarray,
    h: np.ndarray,
    w_ih: np.ndarray,
    w_hh: np.ndarray,
    b_ih: np.ndarray,
    b_hh: np.ndarray,
) -> np.ndarray:
    """One GRU step, PyTorch's equations (module docstring)."""
    size = h.shape[0]
    gi = w_ih @ x + b_ih
    gh = w_hh @ h + b_hh
    r = _sigmoid(gi[:size] + gh[:size])
    z = _sigmoid(gi[size : 2 * size] + gh[size : 2 * size])
    n = np.tanh(gi[2 * size :] + r * gh[2 * size :])
    return np.asarray((1.0 - z) * n + z * h, dtype=h.dtype)


def _reference_run(
    weights: Mapping[str, np.ndarray], scaled: np.ndarray, h1: np.ndarray, h2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Run both GRU layers over ``scaled`` rows; returns the final (h1, h2)."""
    w = {k: np.asarray(v, dtype=np.float32) for k, v in weights.items()}
    for x in scaled:
        h1 = _reference_cell(
            x, h1, w["gru1.weight_ih"], w["gru1.weight_hh"], w["gru1.bias_ih"], w["gru1.bias_hh"]
        )
        h2 = _reference_cell(
            h1, h2, w["gru2.weight_ih"], w["gru2.weight_hh"], w["gru2.bias_ih"], w["gru2.bias_hh"]
        )
    return h1, h2


def _reference_head(weights: Mapping[str, np.ndarray], head: str, h2: np.ndarray) -> np.ndarray:
    return _softmax(
        np.asarray(weights[f"{head}.weight"], np.float32) @ h2
        + np.asarray(weights[f"{head}.bias"], np.float32)
    )


def _reference_outputs(n: int, weights: Mapping[str, np.ndarray]) -> GRUPrediction:
    """Empty per-point outputs for ``n`` points of a network with ``weights``' heads."""
    return GRUPrediction(
        anomaly=np.empty(n, np.float32),
        bias=np.empty((n, weights["bias_head.bias"].shape[0]), np.float32),
        confirm=np.empty(n, np.float32) if CONFIRM_NAMES[0] in weights else None,
    )


def _reference_point(
    weights: Mapping[str, np.ndarray], h2: np.ndarray, out: GRUPrediction, i: int
) -> None:
    out.anomaly[i] = _reference_head(weights, "anomaly_head", h2)[1]
    out.bias[i] = _reference_head(weights, "bias_head", h2)
    if out.confirm is not None:
        out.confirm[i] = _reference_head(weights, "confirm_head", h2)[1]


def reference_stream(
    weights: Mapping[str, np.ndarray],
    mean: np.ndarray,
    std: np.ndarray,
    features: np.ndarray,
    state: np.ndarray | None = None,
) -> tuple[GRUPrediction, np.ndarray]:
    """Streaming mode, NumPy reference: ``(per-point outputs, final state)``.

    ``state`` is ``h1`` and ``h2`` concatenated (zeros when None).
    """
    hidden1 = weights["gru1.weight_hh"].shape[1]
    hidden2 = weights["gru2.weight_hh"].shape[1]
    h = np.zeros(hidden1 + hidden2, np.float32) if state is None else np.asarray(state, np.float32)
    h1, h2 = h[:hidden1].copy(), h[hidden1:].copy()
    scaled = scale_features(features, mean, std)
    out = _reference_outputs(len(scaled), weights)
    for i in range(len(scaled)):
        h1, h2 = _reference_run(weights, scaled[i : i + 1], h1, h2)
        _reference_point(weights, h2, out, i)
    return out, np.concatenate([h1, h2])


def reference_windows(
    weights: Mapping[str, np.ndarray],
    mean: np.ndarray,
    std: np.ndarray,
    features: np.ndarray,
    window: int,
) -> GRUPrediction:
    """Window mode, NumPy reference: each point from a zero state over its last ``window`` points."""
    hidden1 = weights["gru1.weight_hh"].shape[1]
    hidden2 = weights["gru2.weight_hh"].shape[1]
    scaled = scale_features(features, mean, std)
    out = _reference_outputs(len(scaled), weights)
    for i in range(len(scaled)):
        _, h2 = _reference_run(
            weights,
            scaled[max(0, i - window + 1) : i + 1],
            np.zeros(hidden1, np.float32),
            np.zeros(hidden2, np.float32),
        )
        _reference_point(weights, h2, out, i)
    return out


# ----------------------------------------------------------------------------
# Packed parameters for the numba kernels.
#
# One float32 vector holds, in this order: scaler mean (F), 1/std (F), then per
# GRU layer W_ih^T (in x 3H), W_hh^T (H x 3H), b_ih (3H), b_hh (3H), then per
# head (anomaly, bias, and the confirm head when there is one) W^T (H2 x C)
# and b (C). Matrices are stored transposed so the kernels' inner loop runs
# over contiguous outputs ("axpy" order): it vectorises without reassociating
# sums, so results do not depend on compiler flags.
# ``dims`` = [F, H1, H2, K, 1 with a confirm head else 0, M networks side by side].
# ----------------------------------------------------------------------------


def pack_parameters(
    weights: Mapping[str, np.ndarray],
    mean: np.ndarray,
    std: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``(params float32 (P,), dims int64 [F, H1, H2, K, C, M])`` for the numba kernels
    (``C`` = 1 when ``weights`` hold the confirm head, else 0; ``M``: the networks side
    by side, :func:`diagonal_blocks`)."""
    n_features = int(weights["gru1.weight_ih"].shape[1])
    hidden1 = int(weights["gru1.weight_hh"].shape[1])
    hidden2 = int(weights["gru2.weight_hh"].shape[1])
    n_bias = int(weights["bias_head.bias"].shape[0])
    parts = [np.asarray(mean, np.float32), (1.0 / np.asarray(std, np.float64)).astype(np.float32)]
    for layer in ("gru1", "gru2"):
        parts += [
            weights[f"{layer}.weight_ih"].T,
            weights[f"{layer}.weight_hh"].T,
            weights[f"{layer}.bias_ih"],
            weights[f"{layer}.bias_hh"],
        ]
    confirm = CONFIRM_NAMES[0] in weights
    for head in ("anomaly_head", "bias_head") + (("confirm_head",) if confirm else ()):
        parts += [weights[f"{head}.weight"].T, weights[f"{head}.bias"]]
    params = np.concatenate([np.asarray(p, np.float32).ravel() for p in parts])
    members = diagonal_blocks(weights)
    return params, np.array([n_features, hidden1, hidden2, n_bias, int(confirm), members], np.int64)


def diagonal_blocks(weights: Mapping[str, np.ndarray]) -> int:
    """The number of networks side by side in these weights: the most blocks M for which
    every weight matrix that reads a hidden state (``gru1.weight_hh``, ``gru2.weight_ih``,
    ``gru2.weight_hh``) is, gate by gate, block-diagonal, its off-diagonal blocks all
    exact zeros (:func:`gradgps._train.torch_gru.merge_networks` builds them so); 1 for
    one network.

    Why: the kernels then skip the zero blocks (:func:`_accumulate_blocks`), which with
    four members are 3/4 of those matrices' products; skipping adds of exact zeros
    leaves every sum as it was.
    """
    hidden1 = int(weights["gru1.weight_hh"].shape[1])
    hidden2 = int(weights["gru2.weight_hh"].shape[1])
    matrices = [
        (np.asarray(weights["gru1.weight_hh"]), hidden1, hidden1),
        (np.asarray(weights["gru2.weight_ih"]), hidden2, hidden1),
        (np.asarray(weights["gru2.weight_hh"]), hidden2, hidden2),
    ]
    for members in range(min(hidden1, hidden2), 1, -1):
        if hidden1 % members or hidden2 % members:
            continue
        if all(_block_diagonal(w, rows, cols, members) for w, rows, cols in matrices):
            return members
    return 1


def _block_diagonal(w: np.ndarray, rows: int, cols: int, members: int) -> bool:
    """Whether ``w`` (3 gates x ``rows``, ``cols``) has, in every gate, nothing but exact
    zeros outside its ``members`` diagonal blocks."""
    r, c = rows // members, cols // members
    mask = np.kron(np.eye(members, dtype=bool), np.ones((r, c), dtype=bool))
    return all(not np.any(w[g * rows : (g + 1) * rows][~mask]) for g in range(3))


@numba.njit(cache=True)
def _sigmoid_scalar(v: float) -> float:
    # exp is ~3x cheaper than tanh here (no vector math library); exp(-v)
    # overflowing to inf gives the right limit 0 (numba raises no FP warnings).
    return 1.0 / (1.0 + math.exp(-v))


@numba.njit(cache=True)
def _tanh_scalar(v: float) -> float:
    return 2.0 / (1.0 + math.exp(-2.0 * v)) - 1.0


@numba.njit(cache=True)
def _accumulate(params: Any, o_w: int, n_in: int, g: int, x: Any, acc: Any) -> None:
    """``acc[i] += sum_j W[j, i] * x[j]``, ``W^T`` (n_in x g) at ``params[o_w:]``: j = 0, 1,
    2, ... in order, each product and sum in float32.

    Four inputs per pass over ``acc``, their additions written out left to right (so
    the sums are the one-input-at-a-time sums, bit for bit): a quarter of the passes,
    loads and stores of ``acc``, which at 96 gates cost as much as the arithmetic.
    Row views (not params[base + i]) let LLVM prove the indices are in range and
    vectorise the loops: about 5x faster.
    """
    j = 0
    while j + 4 <= n_in:
        r0 = params[o_w + j * g : o_w + (j + 1) * g]
        r1 = params[o_w + (j + 1) * g : o_w + (j + 2) * g]
        r2 = params[o_w + (j + 2) * g : o_w + (j + 3) * g]
        r3 = params[o_w + (j + 3) * g : o_w + (j + 4) * g]
        x0, x1, x2, x3 = x[j], x[j + 1], x[j + 2], x[j + 3]
        for i in range(g):
            acc[i] = (((acc[i] + r0[i] * x0) + r1[i] * x1) + r2[i] * x2) + r3[i] * x3
        j += 4
    while j < n_in:
        xj = x[j]
        row = params[o_w + j * g : o_w + (j + 1) * g]
        for i in range(g):
            acc[i] += row[i] * xj
        j += 1


@numba.njit(cache=True)
def _accumulate_blocks(
    params: Any, o_w: int, n_in: int, size: int, members: int, x: Any, acc: Any
) -> None:
    """:func:`_accumulate` for a block-diagonal ``W`` (``members`` networks side by side,
    :func:`diagonal_blocks`): input ``j`` of member ``m`` reaches only member ``m``'s
    rows of each of the three gates, so only those products are made. Every sum gets
    the same nonzero terms in the same order as in :func:`_accumulate` (the skipped
    ones are exact zeros times a finite hidden state), so the result is the same, bit
    for bit (tests/test_gru.py)."""
    g = 3 * size
    n_own = n_in // members  # inputs per member
    width = size // members  # each member's rows per gate
    for m in range(members):
        j = m * n_own
        end = j + n_own
        while j + 4 <= end:
            x0, x1, x2, x3 = x[j], x[j + 1], x[j + 2], x[j + 3]
            for q in range(3):
                o = o_w + q * size + m * width
                r0 = params[o + j * g : o + j * g + width]
                r1 = params[o + (j + 1) * g : o + (j + 1) * g + width]
                r2 = params[o + (j + 2) * g : o + (j + 2) * g + width]
                r3 = params[o + (j + 3) * g : o + (j + 3) * g + width]
                a = acc[q * size + m * width : q * size + (m + 1) * width]
                for i in range(width):
                    a[i] = (((a[i] + r0[i] * x0) + r1[i] * x1) + r2[i] * x2) + r3[i] * x3
            j += 4
        while j < end:
            xj = x[j]
            for q in range(3):
                o = o_w + q * size + m * width
                row = params[o + j * g : o + j * g + width]
                a = acc[q * size + m * width : q * size + (m + 1) * width]
                for i in range(width):
                    a[i] += row[i] * xj
            j += 1


@numba.njit(cache=True)
def _cell(
    params: Any,
    o_wih: int,
    n_in: int,
    size: int,
    members: int,
    x: Any,
    h: Any,
    gi: Any,
    gh: Any,
    input_blocks: bool,
) -> None:
    """One GRU step in place on ``h``; weights at ``params[o_wih:]`` in packed order.
    ``members`` > 1: the recurrent weights are block-diagonal (and the input weights too
    where ``input_blocks``, the second layer reading the first's members one by one)."""
    g = 3 * size
    o_whh = o_wih + n_in * g
    o_bih = o_whh + size * g
    o_bhh = o_bih + g
    gi[:g] = params[o_bih : o_bih + g]
    gh[:g] = params[o_bhh : o_bhh + g]
    if members > 1 and input_blocks:
        _accumulate_blocks(params, o_wih, n_in, size, members, x, gi)
    else:
        _accumulate(params, o_wih, n_in, g, x, gi)
    if members > 1:
        _accumulate_blocks(params, o_whh, size, size, members, h, gh)
    else:
        _accumulate(params, o_whh, size, g, h, gh)
    for i in range(size):
        r = _sigmoid_scalar(gi[i] + gh[i])
        z = _sigmoid_scalar(gi[size + i] + gh[size + i])
        n = _tanh_scalar(gi[2 * size + i] + r * gh[2 * size + i])
        h[i] = (1.0 - z) * n + z * h[i]


@numba.njit(cache=True)
def _layer_size(n_in: int, size: int) -> int:
    return 3 * size * (n_in + size + 2)


@numba.njit(cache=True)
def _recurrent_step(params: Any, dims: Any, x: Any, state: Any, scratch: Any) -> None:
    """Scale ``x`` and advance both layers; ``state`` = [h1, h2] updated in place."""
    n_features, hidden1, hidden2 = dims[0], dims[1], dims[2]
    scaled = scratch[:n_features]
    for j in range(n_features):
        v = (x[j] - params[j]) * params[n_features + j]
        scaled[j] = v if math.isfinite(v) else 0.0
    widest = max(hidden1, hidden2)  # gate buffers shared by both layers
    gi = scratch[n_features : n_features + 3 * widest]
    gh = scratch[n_features + 3 * widest : n_features + 6 * widest]
    members = dims[5]
    o1 = 2 * n_features
    h1 = state[:hidden1]
    _cell(params, o1, n_features, hidden1, members, scaled, h1, gi, gh, False)
    o2 = o1 + _layer_size(n_features, hidden1)
    h2 = state[hidden1 : hidden1 + hidden2]
    _cell(params, o2, hidden1, hidden2, members, h1, h2, gi, gh, True)


@numba.njit(cache=True)
def _softmax_head(params: Any, offset: int, h: Any, n_out: int, out: Any) -> None:
    """``out = softmax(W h + b)`` with W^T (len(h) x n_out) then b at ``params[offset:]``."""
    o_b = offset + h.shape[0] * n_out
    out[:n_out] = params[o_b : o_b + n_out]
    for j in range(h.shape[0]):
        hj = h[j]
        row = params[offset + j * n_out : offset + (j + 1) * n_out]
        for i in range(n_out):
            out[i] += row[i] * hj
    top = out[0]
    for i in range(1, n_out):
        top = max(top, out[i])
    total = 0.0
    for i in range(n_out):
        out[i] = math.exp(out[i] - top)
        total += out[i]
    for i in range(n_out):
        out[i] /= total


@numba.njit(cache=True)
def _heads(params: Any, dims: Any, state: Any, scratch: Any, out: Any) -> None:
    """``out[0]`` = P(anomaly), ``out[1:1+K]`` = bias-class probabilities, and with a
    confirm head ``out[1+K]`` = its P(anomaly) of the point before."""
    n_features, hidden1, hidden2, n_bias = dims[0], dims[1], dims[2], dims[3]
    o_heads = 2 * n_features + _layer_size(n_features, hidden1) + _layer_size(hidden1, hidden2)
    h2 = state[hidden1 : hidden1 + hidden2]
    two = scratch[:2]
    _softmax_head(params, o_heads, h2, 2, two)
    out[0] = two[1]
    o_bias = o_heads + 2 * hidden2 + 2
    _softmax_head(params, o_bias, h2, n_bias, out[1 : 1 + n_bias])
    if dims[4] != 0:
        _softmax_head(params, o_bias + n_bias * hidden2 + n_bias, h2, 2, two)
        out[1 + n_bias] = two[1]


@numba.njit(cache=True)
def _scratch_size(dims: Any) -> int:
    return int(dims[0] + 6 * max(dims[1], dims[2]))


@numba.njit(cache=True)
def stream_sequence_kernel(params: Any, dims: Any, features: Any, state: Any, out: Any) -> None:
    """(a) Streaming mode over a whole sequence: ``out[i]`` for each row, ``state`` carried."""
    scratch = np.empty(_scratch_size(dims), np.float32)
    for i in range(features.shape[0]):
        _recurrent_step(params, dims, features[i], state, scratch)
        _heads(params, dims, state, scratch, out[i])


@numba.njit(cache=True)
def window_sequence_kernel(params: Any, dims: Any, features: Any, window: int, out: Any) -> None:
    """(b) Window mode: point ``i`` from zero state over rows ``max(0, i-W+1)..i``: O(W) per point."""
    scratch = np.empty(_scratch_size(dims), np.float32)
    state = np.empty(dims[1] + dims[2], np.float32)
    for i in range(features.shape[0]):
        state[:] = 0.0
        for t in range(max(0, i - window + 1), i + 1):
            _recurrent_step(params, dims, features[t], state, scratch)
        _heads(params, dims, state, scratch, out[i])


# ----------------------------------------------------------------------------
# Python-facing objects.
# ----------------------------------------------------------------------------


@dataclass(frozen=True)
class GRUPrediction:
    """Per-point network outputs: ``anomaly`` (n,) = P(anomaly), ``bias`` (n, K) class
    probabilities, ``confirm`` (n,) = the confirm head's P(anomaly) of the point before
    (None without the head)."""

    anomaly: np.ndarray
    bias: np.ndarray
    confirm: np.ndarray | None = None


def _split_out(out: np.ndarray, n_bias: int, confirm: bool) -> GRUPrediction:
    return GRUPrediction(
        anomaly=out[:, 0].copy(),
        bias=out[:, 1 : 1 + n_bias].copy(),
        confirm=out[:, 1 + n_bias].copy() if confirm else None,
    )


class GRUModel:
    """The GRAD network for inference: scaler, GRU(32), GRU(16), anomaly and bias-type heads
    (and the confirm head when ``weights`` hold :data:`CONFIRM_NAMES`).

    Built from the arrays of a model directory (``weights`` named as in
    :data:`WEIGHT_NAMES`, scaler ``mean``/``std`` of length F). ``mode`` is
    how :meth:`predict` feeds points (``"window"`` or ``"stream"``, see the
    module docstring); both feeding functions are always available.
    Shapes are checked here because a wrong shape inside a numba kernel
    would read out of bounds instead of failing.
    """

    def __init__(
        self,
        weights: Mapping[str, np.ndarray],
        mean: np.ndarray,
        std: np.ndarray,
        *,
        mode: str = "stream",
        window: int = 10,
    ) -> None:
        if mode not in MODES:
            raise ModelError(f"unknown model mode {mode!r}; expected one of {', '.join(MODES)}")
        if window < 1:
            raise ModelError(f"window must be >= 1, got {window}")
        missing = [name for name in WEIGHT_NAMES if name not in weights]
        if missing:
            raise ModelError(
                f"weights lack {', '.join(missing)}; the model was exported incompletely, export it again"
            )
        confirm = [name in weights for name in CONFIRM_NAMES]
        if any(confirm) and not all(confirm):
            raise ModelError(
                f"weights hold only part of the confirm head ({', '.join(CONFIRM_NAMES)}); "
                "export the model again"
            )
        n_features = int(np.shape(weights["gru1.weight_ih"])[1])
        expected = weight_shapes(
            n_features,
            int(np.shape(weights["gru1.weight_hh"])[1]),
            int(np.shape(weights["anomaly_head.weight"])[1]),
            int(np.shape(weights["bias_head.bias"])[0]),
            confirm_head=all(confirm),
        )
        for name, shape in expected.items():
            if tuple(np.shape(weights[name])) != shape:
                raise ModelError(
                    f"weight {name!r} has shape {np.shape(weights[name])}, expected {shape}"
                )
        mean = np.asarray(mean, np.float32)
        std = np.asarray(std, np.float32)
        if mean.shape != (n_features,) or std.shape != (n_features,):
            raise ModelError(
                f"scaler mean/std must have {n_features} values (one per feature), "
                f"got {mean.shape} and {std.shape}"
            )
        if not (np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and np.all(std > 0)):
            raise ModelError("scaler mean must be finite and std finite and > 0")
        self.weights = {name: np.asarray(weights[name], np.float32) for name in expected}
        self.mean = mean
        self.std = std
        self.mode = mode
        self.window = int(window)
        self.params, self.dims = pack_parameters(self.weights, mean, std)

    @property
    def n_features(self) -> int:
        return int(self.dims[0])

    @property
    def n_bias_classes(self) -> int:
        return int(self.dims[3])

    @property
    def has_confirm_head(self) -> bool:
        """Whether the network also judges each point's predecessor (:class:`GRUPrediction`)."""
        return bool(self.dims[4])

    @property
    def n_outputs(self) -> int:
        """Values per point in the kernels' output rows: P(anomaly), K bias classes, confirm."""
        return int(1 + self.dims[3] + self.dims[4])

    @property
    def state_size(self) -> int:
        """Length of one track's streaming state (hidden1 + hidden2)."""
        return int(self.dims[1] + self.dims[2])

    def _features(self, features: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(features, dtype=np.float32)
        if x.ndim != 2 or x.shape[1] != self.n_features:
            raise ConfigError(f"features must have shape (n, {self.n_features}), got {x.shape}")
        return x

    def predict(self, features: np.ndarray) -> GRUPrediction:
        """Outputs for every row of one segment's features (n, F), fed the model's way."""
        if self.mode == "window":
            return self.predict_windows(features)
        return self.predict_stream(features)[0]

    def predict_stream(
        self,
        features: np.ndarray,
        state: np.ndarray | None = None,
    ) -> tuple[GRUPrediction, np.ndarray]:
        """Streaming mode over a segment; returns the outputs and the final state (a new array)."""
        x = self._features(features)
        h = np.zeros(self.state_size, np.float32) if state is None else self._state(state)
        out = np.empty((len(x), self.n_outputs), np.float32)
        stream_sequence_kernel(self.params, self.dims, x, h, out)
        return self._split(out), h

    def _split(self, out: np.ndarray) -> GRUPrediction:
        return _split_out(out, self.n_bias_classes, self.has_confirm_head)

    def predict_windows(self, features: np.ndarray, window: int | None = None) -> GRUPrediction:
        """Window mode over a segment: W GRU steps per point (O(n W)); W defaults to the model's."""
        x = self._features(features)
        out = np.empty((len(x), self.n_outputs), np.float32)
        window_sequence_kernel(
            self.params, self.dims, x, self.window if window is None else int(window), out
        )
        return self._split(out)

    def _state(self, state: np.ndarray) -> np.ndarray:
        h = np.array(state, dtype=np.float32)
        if h.shape != (self.state_size,):
            raise ConfigError(f"state must have shape ({self.state_size},), got {h.shape}")
        return h
