"""Model directories: round trip, and every way a directory can be broken fails with ModelError."""

from __future__ import annotations

import hashlib
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from _gru_support import model_config, random_weights
from gradgps import ModelError
from gradgps._grad.model_io import (
    CONFIG_FILE,
    FORMAT_VERSION,
    WEIGHTS_FILE,
    gru_model,
    load_model,
    save_model,
)

SRC = Path(__file__).resolve().parents[1] / "src" / "gradgps"
F, K = 6, 5


@pytest.fixture
def model_dir(tmp_path: Path) -> Path:
    directory = tmp_path / "model"
    save_model(directory, random_weights(F, K), model_config(F, K, mode="window", window=50))
    return directory


def _edit_config(directory: Path, **changes: object) -> None:
    path = directory / CONFIG_FILE
    config = json.loads(path.read_text())
    config.update(changes)
    path.write_text(json.dumps(config))


def test_round_trip_keeps_every_value(model_dir: Path):
    weights, config = load_model(model_dir)
    expected_weights = random_weights(F, K)
    assert set(weights) == set(expected_weights)
    for name, array in expected_weights.items():
        np.testing.assert_array_equal(weights[name], array)
        assert weights[name].dtype == np.float32
    expected = model_config(F, K, mode="window", window=50)
    assert {k: config[k] for k in expected} == expected
    assert config["format_version"] == FORMAT_VERSION
    assert (
        config["weights_sha256"]
        == hashlib.sha256((model_dir / WEIGHTS_FILE).read_bytes()).hexdigest()
    )
    model = gru_model(weights, config)
    assert (model.mode, model.window, model.n_features, model.n_bias_classes) == (
        "window",
        50,
        F,
        K,
    )
    np.testing.assert_array_equal(model.mean, np.asarray(expected["scaler"]["mean"], np.float32))


def test_flipped_byte_in_weights_names_the_file(model_dir: Path):
    path = model_dir / WEIGHTS_FILE
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(ModelError, match=re.escape(str(path)) + ".*checksum"):
        load_model(model_dir)


def test_truncated_weights_fail(model_dir: Path):
    path = model_dir / WEIGHTS_FILE
    path.write_bytes(path.read_bytes()[:100])
    with pytest.raises(ModelError, match=re.escape(str(path)) + ".*truncated"):
        load_model(model_dir)


def test_other_format_version_fails(model_dir: Path):
    _edit_config(model_dir, format_version=FORMAT_VERSION + 1)
    with pytest.raises(
        ModelError, match=re.escape(str(model_dir / CONFIG_FILE)) + ".*format_version.*re-export"
    ):
        load_model(model_dir)


@pytest.mark.parametrize("name", [WEIGHTS_FILE, CONFIG_FILE])
def test_missing_file_fails(model_dir: Path, name: str):
    (model_dir / name).unlink()
    with pytest.raises(ModelError, match=re.escape(str(model_dir / name)) + ": file not found"):
        load_model(model_dir)


def test_missing_directory_and_broken_json_fail(tmp_path: Path, model_dir: Path):
    with pytest.raises(ModelError, match="model directory not found"):
        load_model(tmp_path / "nowhere")
    (model_dir / CONFIG_FILE).write_text('{"format_version": 1,')
    with pytest.raises(ModelError, match="not valid JSON"):
        load_model(model_dir)


def test_config_inconsistent_with_weights_fails(model_dir: Path):
    """A consistent-looking config for 7 features does not load 6-feature weights."""
    wider = model_config(F + 1, K)
    _edit_config(
        model_dir,
        architecture=wider["architecture"],
        features=wider["features"],
        scaler=wider["scaler"],
    )
    with pytest.raises(ModelError, match=r"gru1\.weight_ih.*shape \(96, 6\).*\(96, 7\)"):
        load_model(model_dir)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("mode", "batch", "mode must be one of"),
        ("thresholds", {"anomaly": 1.5}, "thresholds.anomaly"),
        ("scaler", {"mean": [0.0] * F, "std": [0.0] * F}, r"scaler.std must be > 0"),
        ("class_names", {"anomaly": ["normal", "anomaly"], "bias": ["none"]}, "class_names.bias"),
    ],
)
def test_invalid_config_values_fail(model_dir: Path, key: str, value: object, message: str):
    _edit_config(model_dir, **{key: value})
    with pytest.raises(ModelError, match=message):
        load_model(model_dir)


def test_save_refuses_inconsistent_model(tmp_path: Path):
    with pytest.raises(ModelError, match=r"features\.names must list 6"):
        save_model(
            tmp_path / "m",
            random_weights(F, K),
            {**model_config(F, K), "features": {"names": [], "params": {}}},
        )
    with pytest.raises(ModelError, match=r"bias_head\.weight.*shape"):
        save_model(tmp_path / "m", random_weights(F, K + 1), model_config(F, K))
    with pytest.raises(ModelError, match="cannot be written as JSON"):
        save_model(
            tmp_path / "m", random_weights(F, K), {**model_config(F, K), "rema": {"alpha": np.nan}}
        )
    assert not (tmp_path / "m").exists()


def test_pickled_object_array_is_refused_not_loaded(model_dir: Path):
    """Even with a matching checksum, an archive holding an object array is never unpickled."""
    buffer = io.BytesIO()
    arrays = {name: np.asarray(value) for name, value in load_model(model_dir)[0].items()}
    arrays["gru1.bias_ih"] = np.array([object()] * 3 * 32, dtype=object)
    np.savez(buffer, **arrays)
    (model_dir / WEIGHTS_FILE).write_bytes(buffer.getvalue())
    _edit_config(model_dir, weights_sha256=hashlib.sha256(buffer.getvalue()).hexdigest())
    with pytest.raises(ModelError, match="not a readable weights archive"):
        load_model(model_dir)


def test_export_torch_names_and_shapes():
    pytest.importorskip("torch")
    from gradgps._grad.gru import weight_shapes
    from gradgps._grad.model_io import export_torch
    from gradgps._train.torch_gru import GRADNet

    exported = export_torch(GRADNet(F, K))
    assert {k: v.shape for k, v in exported.items()} == weight_shapes(F, 32, 16, K)
    assert all(v.dtype == np.float32 for v in exported.values())
    confirm = export_torch(GRADNet(F, K, confirm_head=True))
    assert {k: v.shape for k, v in confirm.items()} == weight_shapes(
        F, 32, 16, K, confirm_head=True
    )


@pytest.mark.parametrize("confirm_head", [False, True])
def test_network_from_arrays_inverts_export_torch(confirm_head: bool):
    pytest.importorskip("torch")
    from gradgps._grad.model_io import export_torch
    from gradgps._train.torch_gru import network_from_arrays

    weights = random_weights(F, K, hidden1=5, hidden2=3, confirm_head=confirm_head)
    mean, std = np.linspace(-1, 1, F), np.linspace(0.5, 2, F)
    net = network_from_arrays(weights, mean, std)
    assert (net.confirm_head is not None) == confirm_head
    exported = export_torch(net)
    assert set(exported) == set(weights)
    for name, array in weights.items():
        np.testing.assert_array_equal(exported[name], array)
    np.testing.assert_array_equal(net.scaler_mean.numpy(), mean.astype(np.float32))
    np.testing.assert_array_equal(net.scaler_std.numpy(), std.astype(np.float32))


def _confirm_config(**thresholds: object) -> dict[str, object]:
    config = model_config(F, K)
    config["architecture"] = {**config["architecture"], "confirm_head": True}  # type: ignore[dict-item]
    config["thresholds"] = {**config["thresholds"], **thresholds}  # type: ignore[dict-item]
    return config


def test_a_confirm_head_round_trips_and_is_checked(tmp_path: Path):
    """A model with a confirm head stores its arrays and threshold and loads them back; a
    config that claims the head without a threshold, or weights with the head under a
    config without it, are refused, naming what is wrong."""
    weights = random_weights(F, K, confirm_head=True)
    save_model(tmp_path / "m", weights, _confirm_config(confirm=0.7))
    loaded, config = load_model(tmp_path / "m")
    assert set(loaded) == set(weights)
    for name, array in weights.items():
        np.testing.assert_array_equal(loaded[name], array)
    assert config["thresholds"]["confirm"] == 0.7
    assert gru_model(loaded, config).has_confirm_head
    with pytest.raises(ModelError, match=r"thresholds\.confirm must be a probability"):
        save_model(tmp_path / "n", weights, _confirm_config())
    with pytest.raises(ModelError, match="unexpected arrays confirm_head"):
        save_model(tmp_path / "n", weights, model_config(F, K))
    with pytest.raises(ModelError, match=r"confirm_head\.weight' is missing"):
        save_model(tmp_path / "n", random_weights(F, K), _confirm_config(confirm=0.7))
    bad = _confirm_config(confirm=0.7)
    bad["architecture"] = {**bad["architecture"], "confirm_head": "yes"}  # type: ignore[dict-item]
    with pytest.raises(ModelError, match=r"architecture\.confirm_head must be true or false"):
        save_model(tmp_path / "n", weights, bad)
    assert not (tmp_path / "n").exists()


_UNSAFE = re.compile(
    r"^\s*(import pickle|from pickle)|\bpickle\.(loads?|Unpickler)|allow_pickle\s*=\s*True"
    r"|torch\.load\b|joblib|cloudpickle|\bdill\b",
    re.MULTILINE,
)


def test_no_unpickling_anywhere_in_the_package():
    """No module may load pickles; every np.load passes allow_pickle=False."""
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        offenders += [f"{path.name}: {m.group(0).strip()}" for m in _UNSAFE.finditer(text)]
        for call in re.finditer(r"np\.load\(((?:[^()]|\([^()]*\))*)\)", text):
            if "allow_pickle=False" not in call.group(1):
                offenders.append(f"{path.name}: {call.group(0)}")
    assert offenders == []
