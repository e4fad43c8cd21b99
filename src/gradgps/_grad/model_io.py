"""Model directories: how a trained GRAD network is stored, checked and loaded.

A model directory holds two files:

* ``weights.npz``: the network weights (float32 arrays named as in
  :data:`gradgps._grad.gru.WEIGHT_NAMES`, plus
  :data:`gradgps._grad.gru.CONFIRM_NAMES` for a model with a confirm head),
  read with ``allow_pickle=False``;
* ``config.json``: ``format_version``, ``architecture`` (``n_features``,
  ``hidden1``, ``hidden2``, ``n_bias_classes``, and ``confirm_head``: true
  for a model with one), ``mode`` and ``window``,
  ``features`` (``names`` + opaque ``params`` of the extractor), ``scaler``
  (``mean``, ``std``), ``thresholds`` (``anomaly``, and ``confirm`` with a
  confirm head), ``rema`` (opaque REMA
  parameters), ``class_names`` (``anomaly``, ``bias``), ``weights_file`` and
  ``weights_sha256``, plus any extra keys the caller adds (e.g. ``training``).

Why not pickle or ``torch.save``: loading a pickle runs code from the file,
and deployment must not need torch. Why a checksum: a truncated copy or an
edited weights file must fail loudly, naming the file, instead of silently
producing different detections.

Nothing here imports torch; :func:`export_torch` only calls methods on the
module it is given.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .._exceptions import ModelError
from .gru import CONFIRM_NAMES, MODES, WEIGHT_NAMES, GRUModel, weight_shapes

__all__ = [
    "CONFIG_FILE",
    "FORMAT_VERSION",
    "WEIGHTS_FILE",
    "export_torch",
    "gru_model",
    "load_model",
    "save_model",
    "save_thresholds",
    "torch_state",
]

FORMAT_VERSION = 1
WEIGHTS_FILE = "weights.npz"
CONFIG_FILE = "config.json"

_TORCH_NAMES = {  # exported name -> attribute path on the torch module
    "gru1.weight_ih": "gru1.weight_ih_l0",
    "gru1.weight_hh": "gru1.weight_hh_l0",
    "gru1.bias_ih": "gru1.bias_ih_l0",
    "gru1.bias_hh": "gru1.bias_hh_l0",
    "gru2.weight_ih": "gru2.weight_ih_l0",
    "gru2.weight_hh": "gru2.weight_hh_l0",
    "gru2.bias_ih": "gru2.bias_ih_l0",
    "gru2.bias_hh": "gru2.bias_hh_l0",
    "anomaly_head.weight": "anomaly_head.weight",
    "anomaly_head.bias": "anomaly_head.bias",
    "bias_head.weight": "bias_head.weight",
    "bias_head.bias": "bias_head.bias",
    "confirm_head.weight": "confirm_head.weight",
    "confirm_head.bias": "confirm_head.bias",
}
_FLOAT32_MAX = float(np.finfo(np.float32).max)
_RETRAIN = "export the model again (gradgps train) or restore the directory from its source"


def export_torch(model: Any) -> dict[str, np.ndarray]:
    """Weights of a :class:`gradgps._train.torch_gru.GRADNet` as float32 NumPy arrays, PyTorch layouts.

    The scaler is not included: it goes to ``config.json`` (see
    :meth:`gradgps._train.torch_gru.TrainedModel.model_config`). The confirm
    head's arrays come only from a network that has one.
    """
    state = model.state_dict()
    return {
        name: state[path].detach().cpu().numpy().astype(np.float32, copy=True)
        for name, path in _TORCH_NAMES.items()
        if path in state
    }


def torch_state(weights: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``weights`` (as :func:`export_torch` names them) under the torch module's parameter
    names: what ``GRADNet.load_state_dict`` takes, with the scaler buffers added."""
    return {_TORCH_NAMES[name]: np.asarray(array, np.float32) for name, array in weights.items()}


def _has_confirm(config: Mapping[str, Any]) -> bool:
    arch = config.get("architecture")
    return isinstance(arch, Mapping) and arch.get("confirm_head") is True


def _weight_names(config: Mapping[str, Any]) -> tuple[str, ...]:
    """The arrays a model of ``config`` stores, in file order."""
    return WEIGHT_NAMES + (CONFIRM_NAMES if _has_confirm(config) else ())


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _check_config(config: Mapping[str, Any], source: str) -> None:
    """Structure and consistency of a config (without the file bookkeeping keys)."""

    def fail(what: str) -> ModelError:
        return ModelError(f"{source}: {what}; {_RETRAIN}")

    for key in (
        "architecture",
        "mode",
        "window",
        "features",
        "scaler",
        "thresholds",
        "rema",
        "class_names",
    ):
        if key not in config:
            raise fail(f"missing key {key!r}")
    arch = config["architecture"]
    sizes = {}
    for key in ("n_features", "hidden1", "hidden2", "n_bias_classes"):
        value = arch.get(key) if isinstance(arch, Mapping) else None
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise fail(f"architecture.{key} must be a positive integer, got {value!r}")
        sizes[key] = value
    if config["mode"] not in MODES:
        raise fail(f"mode must be one of {', '.join(MODES)}, got {config['mode']!r}")
    if not isinstance(config["window"], int) or config["window"] < 1:
        raise fail(f"window must be a positive integer, got {config['window']!r}")
    n = sizes["n_features"]
    names = config["features"].get("names") if isinstance(config["features"], Mapping) else None
    if not isinstance(names, list) or len(names) != n or not all(isinstance(x, str) for x in names):
        raise fail(f"features.names must list {n} feature names")
    if not isinstance(config["features"].get("params"), Mapping) or not isinstance(
        config["rema"], Mapping
    ):
        raise fail("features.params and rema must be objects")
    scaler = config["scaler"]
    for key in ("mean", "std"):
        values = scaler.get(key) if isinstance(scaler, Mapping) else None
        if (
            not isinstance(values, list)
            or len(values) != n
            or not all(isinstance(v, int | float) and abs(v) <= _FLOAT32_MAX for v in values)
        ):
            raise fail(f"scaler.{key} must hold {n} finite float32 numbers")
    if not all(np.float32(v) > 0 for v in scaler["std"]):  # as the network stores it
        raise fail("scaler.std must be > 0 (and not below float32's smallest number)")
    threshold = (
        config["thresholds"].get("anomaly") if isinstance(config["thresholds"], Mapping) else None
    )
    if not isinstance(threshold, int | float) or not 0.0 <= threshold <= 1.0:
        raise fail(f"thresholds.anomaly must be a probability in [0, 1], got {threshold!r}")
    if arch.get("confirm_head", False) not in (True, False):
        raise fail(f"architecture.confirm_head must be true or false, got {arch['confirm_head']!r}")
    if _has_confirm(config):
        confirm = config["thresholds"].get("confirm")
        if not isinstance(confirm, int | float) or not 0.0 <= confirm <= 1.0:
            raise fail(
                f"thresholds.confirm must be a probability in [0, 1] for a model with a "
                f"confirm head, got {confirm!r}"
            )
    classes = config["class_names"]
    bias = classes.get("bias") if isinstance(classes, Mapping) else None
    if not isinstance(bias, list) or len(bias) != sizes["n_bias_classes"]:
        raise fail(f"class_names.bias must list {sizes['n_bias_classes']} class names")
    if not isinstance(classes.get("anomaly"), list) or len(classes["anomaly"]) != 2:
        raise fail("class_names.anomaly must list 2 class names")


def _check_weights(
    weights: Mapping[str, np.ndarray], config: Mapping[str, Any], source: str
) -> None:
    arch = config["architecture"]
    expected = weight_shapes(
        arch["n_features"],
        arch["hidden1"],
        arch["hidden2"],
        arch["n_bias_classes"],
        confirm_head=_has_confirm(config),
    )
    unexpected = sorted(set(weights) - set(expected))
    if unexpected:
        raise ModelError(f"{source}: unexpected arrays {', '.join(unexpected)}; {_RETRAIN}")
    for name, shape in expected.items():
        if name not in weights:
            raise ModelError(f"{source}: array {name!r} is missing; {_RETRAIN}")
        array = weights[name]
        if array.dtype.kind != "f":
            raise ModelError(
                f"{source}: array {name!r} has dtype {array.dtype}, expected floats; {_RETRAIN}"
            )
        if array.shape != shape:
            raise ModelError(
                f"{source}: array {name!r} has shape {array.shape}, "
                f"config.json says {shape}; {_RETRAIN}"
            )
        if not np.all(np.abs(array) <= _FLOAT32_MAX):  # NaN compares False
            raise ModelError(
                f"{source}: array {name!r} holds NaN, infinite or beyond-float32 values; {_RETRAIN}"
            )


def save_model(
    directory: str | os.PathLike[str], weights: Mapping[str, np.ndarray], config: Mapping[str, Any]
) -> None:
    """Write ``weights.npz`` and ``config.json`` into ``directory`` (created if needed).

    ``config`` is checked against the weights first, so an inconsistent model
    is never written; ``format_version``, ``weights_file`` and
    ``weights_sha256`` are set here. Each file is written to a temporary name
    and renamed, so an interrupted save never leaves a half-written file
    under the real name.
    """
    folder = Path(directory)
    content = {
        k: v
        for k, v in config.items()
        if k not in ("format_version", "weights_file", "weights_sha256")
    }
    _check_config(content, f"config for {folder}")
    arrays = {name: np.ascontiguousarray(weights[name], dtype=np.float32) for name in weights}
    _check_weights(arrays, content, f"weights for {folder}")
    buffer = io.BytesIO()
    np.savez(buffer, allow_pickle=False, **{name: arrays[name] for name in _weight_names(content)})
    data = buffer.getvalue()
    content["format_version"] = FORMAT_VERSION
    content["weights_file"] = WEIGHTS_FILE
    content["weights_sha256"] = _sha256(data)
    try:  # before writing anything: a config that cannot be stored must not leave new weights behind
        text = json.dumps(content, indent=2, allow_nan=False) + "\n"
    except (TypeError, ValueError) as error:
        raise ModelError(
            f"config for {folder} cannot be written as JSON ({error}); "
            "feature and REMA parameters must be plain numbers, strings, lists and dicts"
        ) from None
    folder.mkdir(parents=True, exist_ok=True)
    _write_atomic(folder / WEIGHTS_FILE, data)
    _write_atomic(folder / CONFIG_FILE, text.encode())


def save_thresholds(directory: str | os.PathLike[str], thresholds: dict[str, Any]) -> None:
    """Replace the ``thresholds`` block of a saved model's ``config.json`` (atomically);
    its weights and their checksum are untouched."""
    path = Path(directory) / CONFIG_FILE
    config = json.loads(path.read_text())
    config["thresholds"] = thresholds
    try:
        text = json.dumps(config, indent=2, allow_nan=False) + "\n"
    except (TypeError, ValueError) as error:
        raise ModelError(
            f"thresholds for {directory} cannot be written as JSON ({error})"
        ) from None
    _write_atomic(path, text.encode())


def _write_atomic(path: Path, data: bytes) -> None:
    temporary = path.with_name(path.name + ".tmp")
    temporary.write_bytes(data)
    os.replace(temporary, path)


def load_model(directory: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Read and verify a model directory: ``(weights as float32 arrays, config)``.

    Raises :class:`ModelError` naming the offending file when the directory
    or a file is missing, the config is not valid JSON or of another
    ``format_version``, the weights checksum does not match (truncated or
    modified file), or arrays are missing or of the wrong shape. Never
    unpickles anything.
    """
    folder = Path(directory)
    config_path = folder / CONFIG_FILE
    if not folder.is_dir():
        raise ModelError(
            f"{folder}: model directory not found; pass the directory that holds "
            f"{CONFIG_FILE} and {WEIGHTS_FILE}"
        )
    if not config_path.is_file():
        raise ModelError(
            f"{config_path}: file not found; a model directory needs {CONFIG_FILE} "
            f"and {WEIGHTS_FILE}; {_RETRAIN}"
        )
    try:
        text = config_path.read_text(encoding="utf-8")
    except OSError as error:
        raise ModelError(f"{config_path}: cannot be read ({error.strerror or error})") from None
    except UnicodeDecodeError as error:
        raise ModelError(f"{config_path}: not valid JSON ({error}); {_RETRAIN}") from None
    try:
        config = json.loads(text)
    except (ValueError, RecursionError) as error:
        # ValueError: bad syntax, or an integer of more than 4,300 digits;
        # RecursionError: arrays or objects nested thousands deep.
        what = "nested too deep" if isinstance(error, RecursionError) else str(error)[:200]
        raise ModelError(f"{config_path}: not valid JSON ({what}); {_RETRAIN}") from None
    if not isinstance(config, dict):
        raise ModelError(f"{config_path}: expected a JSON object; {_RETRAIN}")
    version = config.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelError(
            f"{config_path}: format_version {version!r}, this gradgps reads version "
            f"{FORMAT_VERSION}; re-export the model with this gradgps version"
        )
    _check_config(config, str(config_path))
    weights_name = config.get("weights_file")
    if weights_name != WEIGHTS_FILE:
        raise ModelError(
            f"{config_path}: weights_file must be {WEIGHTS_FILE!r}, got {weights_name!r}; {_RETRAIN}"
        )
    weights_path = folder / WEIGHTS_FILE
    if not weights_path.is_file():
        raise ModelError(f"{weights_path}: file not found; {_RETRAIN}")
    try:
        data = weights_path.read_bytes()
    except OSError as error:
        raise ModelError(f"{weights_path}: cannot be read ({error.strerror or error})") from None
    if _sha256(data) != config.get("weights_sha256"):
        raise ModelError(
            f"{weights_path}: sha256 checksum does not match config.json (the file is "
            f"truncated or was modified); {_RETRAIN}"
        )
    _check_archive(data, weights_path)
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as archive:
            weights = {name: np.asarray(archive[name]) for name in archive.files}
    except (ValueError, OSError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise ModelError(
            f"{weights_path}: not a readable weights archive ({error}); {_RETRAIN}"
        ) from None
    _check_weights(weights, config, str(weights_path))
    return {name: weights[name].astype(np.float32) for name in _weight_names(config)}, config


#: Largest array a weights archive may hold, uncompressed (the shipped model's are kilobytes).
_MAX_ARRAY_BYTES = 64 * 2**20


def _check_archive(data: bytes, path: Path) -> None:
    """Refuse an archive with other arrays than the weights, or a huge one, before any array
    is decompressed (an 8 GiB array of zeros compresses to a few megabytes)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = archive.infolist()
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as error:
        raise ModelError(f"{path}: not a readable weights archive ({error}); {_RETRAIN}") from None
    names = {m.filename.removesuffix(".npy") for m in members}
    extra = sorted(names - set(WEIGHT_NAMES + CONFIRM_NAMES))
    if extra:
        raise ModelError(f"{path}: unexpected arrays {extra[:5]}; {_RETRAIN}")
    big = [m.filename for m in members if m.file_size > _MAX_ARRAY_BYTES]
    if big:
        raise ModelError(
            f"{path}: array {big[0]!r} is larger than {_MAX_ARRAY_BYTES // 2**20} MiB; {_RETRAIN}"
        )


def gru_model(weights: Mapping[str, np.ndarray], config: Mapping[str, Any]) -> GRUModel:
    """The torch-free inference network for a loaded ``(weights, config)`` pair."""
    scaler = config["scaler"]
    return GRUModel(
        weights,
        np.asarray(scaler["mean"], np.float32),
        np.asarray(scaler["std"], np.float32),
        mode=config["mode"],
        window=config["window"],
    )
