"""Export the GRAD network to ONNX, for deployment outside Python.

What the graph is: the *network* only (scaler, GRU(32), GRU(16), anomaly and
bias-type heads), exactly as :mod:`gradgps._grad.gru` runs it. What it is not: the
feature pipeline (projection to metres, REMA, MS-SW windows, offset tracker,
signed log1p) nor the time classifier and recovery, which are compiled
NumPy/numba code with per-track state. A deployment computes the feature
vectors (with gradgps, or a port of :mod:`gradgps._grad.pipeline`) and feeds
them here; the names and order of the features are stored in the model's
metadata (``feature_names``).

Why build the graph by hand with ``onnx.helper`` instead of ``torch.onnx``:
deployment and export must not need torch, and the weights we ship are plain
NumPy arrays. The two conventions that must be converted:

* PyTorch stacks the GRU gates ``r, z, n``; ONNX's ``GRU`` op stacks them
  ``z, r, h``, so the row blocks of every weight and bias are reordered;
* PyTorch applies the reset gate *after* the hidden linear map
  (``r * (W_hn h + b_hn)``), which is ONNX's ``linear_before_reset=1``.

Graph (T time steps, B independent tracks, F features)::

    features (T, B, F) -> (x - mean) * (1/std) -> non-finite to 0
      -> GRU (h1_in (1, B, H1)) -> GRU (h2_in (1, B, H2))
      -> softmax(W_a h2 + b_a)[..., 1] = anomaly_probability (T, B)
      -> softmax(W_b h2 + b_b)         = bias_probabilities (T, B, K)
      [-> softmax(W_c h2 + b_c)[..., 1] = confirm_probability (T, B): a model with a
          confirm head; P(anomaly) of the step before, judged with this one seen]
    and the final states h1_out, h2_out, to feed the next call (streaming).

A segment starts from zero states, as in training; feeding one step at a time
with the returned states gives the same numbers as feeding the whole segment.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._exceptions import ConfigError
from .._grad.gru import GRUModel

__all__ = ["OPSET", "build_onnx", "export_onnx"]

#: ONNX opset of the exported graph (Squeeze with axes as an input needs 13).
OPSET = 17

# PyTorch's gate blocks (r, z, n) in ONNX's order (z, r, h).
_TORCH_TO_ONNX_GATES = (1, 0, 2)


def _onnx_gates(array: np.ndarray, hidden: int) -> np.ndarray:
    """Reorder the three stacked gate blocks (first axis) of a GRU weight or bias."""
    blocks = [array[k * hidden : (k + 1) * hidden] for k in _TORCH_TO_ONNX_GATES]
    return np.ascontiguousarray(np.concatenate(blocks, axis=0), dtype=np.float32)


def _gru_initializers(
    weights: Mapping[str, np.ndarray], layer: str, hidden: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ONNX ``W`` (1, 3H, in), ``R`` (1, 3H, H), ``B`` (1, 6H) of one PyTorch-named layer."""
    w = _onnx_gates(weights[f"{layer}.weight_ih"], hidden)[None]
    r = _onnx_gates(weights[f"{layer}.weight_hh"], hidden)[None]
    b = np.concatenate(
        [
            _onnx_gates(weights[f"{layer}.bias_ih"], hidden),
            _onnx_gates(weights[f"{layer}.bias_hh"], hidden),
        ]
    )[None]
    return w, r, b


def build_onnx(
    model: GRUModel,
    *,
    feature_names: Sequence[str] | None = None,
    bias_classes: Sequence[str] | None = None,
    metadata: Mapping[str, str] | None = None,
) -> Any:
    """The network of ``model`` as an ``onnx.ModelProto`` (see the module docstring).

    ``feature_names`` and ``bias_classes`` are stored in the model's metadata
    so that a consumer knows what to feed and what the outputs mean; extra
    ``metadata`` (threshold, source checksum...) is stored as given.
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    n_features, hidden1, hidden2, n_bias = (int(v) for v in model.dims[:4])
    if feature_names is not None and len(feature_names) != n_features:
        raise ConfigError(
            f"{len(feature_names)} feature names for a network of {n_features} inputs"
        )
    if bias_classes is not None and len(bias_classes) != n_bias:
        raise ConfigError(f"{len(bias_classes)} bias class names for a head of {n_bias} outputs")
    w = model.weights
    inits = {
        "scaler_mean": model.mean.astype(np.float32),
        # Multiply by 1/std computed as the kernels do (float64 then float32): same rounding.
        "scaler_inv_std": (1.0 / model.std.astype(np.float64)).astype(np.float32),
        "zero": np.zeros((), np.float32),
        "axis1": np.array([1], np.int64),
        "axis2": np.array([2], np.int64),
        "anomaly_head_wt": np.ascontiguousarray(w["anomaly_head.weight"].T),
        "anomaly_head_b": w["anomaly_head.bias"],
        "bias_head_wt": np.ascontiguousarray(w["bias_head.weight"].T),
        "bias_head_b": w["bias_head.bias"],
        "anomaly_index": np.array([1], np.int64),
    }
    if model.has_confirm_head:
        inits["confirm_head_wt"] = np.ascontiguousarray(w["confirm_head.weight"].T)
        inits["confirm_head_b"] = w["confirm_head.bias"]
    for layer, hidden in (("gru1", hidden1), ("gru2", hidden2)):
        inits[f"{layer}_W"], inits[f"{layer}_R"], inits[f"{layer}_B"] = _gru_initializers(
            w, layer, hidden
        )
    node = helper.make_node

    def gru_layer(k: int, x: str, hidden: int, out: str) -> list[Any]:
        """GRU layer ``k`` over ``x``, its output squeezed to ``out``: (T, 1, B, H) -> (T, B, H)."""
        gru = node(
            "GRU",
            [x, f"gru{k}_W", f"gru{k}_R", f"gru{k}_B", "", f"h{k}_in"],
            [f"y{k}", f"h{k}_out"],
            hidden_size=hidden,
            linear_before_reset=1,
        )
        return [gru, node("Squeeze", [f"y{k}", "axis1"], [out])]

    def probability(head: str, out: str) -> list[Any]:
        """P(class 1) of a two-class softmax ``head`` on the top layer, squeezed to ``out``."""
        return [
            node("MatMul", ["top", f"{head}_wt"], [f"{head}_mm"]),
            node("Add", [f"{head}_mm", f"{head}_b"], [f"{head}_logits"]),
            node("Softmax", [f"{head}_logits"], [f"{head}_softmax"], axis=-1),
            node("Gather", [f"{head}_softmax", "anomaly_index"], [f"{head}_column"], axis=2),
            node("Squeeze", [f"{head}_column", "axis2"], [out]),
        ]

    nodes = [
        node("Sub", ["features", "scaler_mean"], ["centred"]),
        node("Mul", ["centred", "scaler_inv_std"], ["scaled_raw"]),
        # NaN or +-inf (a missing feature) becomes 0, the training mean, as in _gru.scale_features.
        node("IsNaN", ["scaled_raw"], ["is_nan"]),
        node("IsInf", ["scaled_raw"], ["is_inf"]),
        node("Or", ["is_nan", "is_inf"], ["not_finite"]),
        node("Where", ["not_finite", "zero", "scaled_raw"], ["scaled"]),
        *gru_layer(1, "scaled", hidden1, "x2"),
        *gru_layer(2, "x2", hidden2, "top"),
        *probability("anomaly_head", "anomaly_probability"),
        node("MatMul", ["top", "bias_head_wt"], ["bias_mm"]),
        node("Add", ["bias_mm", "bias_head_b"], ["bias_logits"]),
        node("Softmax", ["bias_logits"], ["bias_probabilities"], axis=-1),
    ]
    if model.has_confirm_head:
        nodes += probability("confirm_head", "confirm_probability")
    f32 = TensorProto.FLOAT
    inputs = [
        helper.make_tensor_value_info("features", f32, ["time", "batch", n_features]),
        helper.make_tensor_value_info("h1_in", f32, [1, "batch", hidden1]),
        helper.make_tensor_value_info("h2_in", f32, [1, "batch", hidden2]),
    ]
    outputs = [
        helper.make_tensor_value_info("anomaly_probability", f32, ["time", "batch"]),
        helper.make_tensor_value_info("bias_probabilities", f32, ["time", "batch", n_bias]),
        helper.make_tensor_value_info("h1_out", f32, [1, "batch", hidden1]),
        helper.make_tensor_value_info("h2_out", f32, [1, "batch", hidden2]),
    ]
    if model.has_confirm_head:
        outputs.append(helper.make_tensor_value_info("confirm_probability", f32, ["time", "batch"]))
    graph = helper.make_graph(
        nodes,
        "grad_gru",
        inputs,
        outputs,
        initializer=[numpy_helper.from_array(np.asarray(v), name=k) for k, v in inits.items()],
    )
    proto = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="gradgps"
    )
    # onnxruntime releases lag the onnx package; the oldest IR version that carries the opset.
    proto.ir_version = 8
    info = {
        "inputs": "features (time, batch, F) float32 = the GRAD feature vectors, unscaled; "
        "h1_in/h2_in zeros at a segment start",
        **(metadata or {}),
    }
    if feature_names is not None:
        info["feature_names"] = ",".join(feature_names)
    if bias_classes is not None:
        info["bias_classes"] = ",".join(bias_classes)
    helper.set_model_props(proto, {str(k): str(v) for k, v in info.items()})
    onnx.checker.check_model(proto)
    return proto


def export_onnx(model_dir: str | os.PathLike[str] | None, output: str | os.PathLike[str]) -> Path:
    """Write the network of a model directory (``None``: the shipped model) to ``output``."""
    import onnx

    from .._grad.detector import load_grad_model
    from .._grad.model_io import gru_model, load_model
    from .._grad.pipeline import pipeline_feature_names

    loaded = load_grad_model(model_dir)
    weights, config = load_model(loaded.path)
    proto = build_onnx(
        gru_model(weights, config),
        feature_names=pipeline_feature_names(loaded.params),
        bias_classes=loaded.bias_classes,
        metadata={
            "anomaly_threshold": repr(loaded.params.threshold),
            "weights_sha256": loaded.checksum,
            "mode": str(config["mode"]),
            "window": str(config["window"]),
            **(
                {"confirm_threshold": repr(float(config["thresholds"]["confirm"]))}
                if "confirm" in config["thresholds"]
                else {}
            ),
            # Segments sampled this slowly or slower take these thresholds instead.
            **(
                {"thresholds_by_rate": json.dumps(config["thresholds"]["by_rate"])}
                if config["thresholds"].get("by_rate")
                else {}
            ),
        },
    )
    path = Path(output)
    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save_model(proto, str(path))
    return path
