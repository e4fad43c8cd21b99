"""ONNX export: onnxruntime on the exported graph gives our GRU's numbers (1e-5)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from _gru_support import random_weights
from gradgps._cli import main
from gradgps._grad.detector import load_grad_model
from gradgps._grad.gru import GRUModel
from gradgps._train.onnx_export import build_onnx

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")


def _session(proto):
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    return ort.InferenceSession(
        proto.SerializeToString(), options, providers=["CPUExecutionProvider"]
    )


def _run(session, features, h1, h2):
    return session.run(None, {"features": features.astype(np.float32), "h1_in": h1, "h2_in": h2})


@pytest.fixture(scope="module")
def random_model() -> GRUModel:
    rng = np.random.default_rng(3)
    n_features, n_bias = 9, 3
    return GRUModel(
        random_weights(n_features, n_bias, seed=4),
        rng.normal(size=n_features),
        rng.uniform(0.5, 2.0, size=n_features),
    )


def test_onnx_matches_stream_inference_with_states(random_model):
    rng = np.random.default_rng(5)
    features = rng.normal(size=(200, random_model.n_features)) * 3
    features[17, 2] = np.nan  # a missing feature is read as the training mean by both
    features[40, 0] = np.inf
    ours, final = random_model.predict_stream(features)
    session = _session(build_onnx(random_model))
    zeros1 = np.zeros((1, 1, 32), np.float32)
    zeros2 = np.zeros((1, 1, 16), np.float32)
    anomaly, bias, h1, h2 = _run(session, features[:, None, :], zeros1, zeros2)
    np.testing.assert_allclose(anomaly[:, 0], ours.anomaly, atol=1e-5)
    np.testing.assert_allclose(bias[:, 0, :], ours.bias, atol=1e-5)
    np.testing.assert_allclose(np.concatenate([h1[0, 0], h2[0, 0]]), final, atol=1e-5)
    # Streaming through the graph: two calls, the states handed over, same numbers.
    a1, _, s1, s2 = _run(session, features[:120, None, :], zeros1, zeros2)
    a2, _, _, _ = _run(session, features[120:, None, :], s1, s2)
    np.testing.assert_allclose(np.concatenate([a1[:, 0], a2[:, 0]]), ours.anomaly, atol=1e-5)


def test_onnx_confirm_probability_matches_the_confirm_head():
    """A model with a confirm head gets a fifth output, confirm_probability, equal to our
    GRU's; the other outputs are those of the network without it."""
    rng = np.random.default_rng(7)
    weights = random_weights(9, 3, seed=4, confirm_head=True)
    mean, std = rng.normal(size=9), rng.uniform(0.5, 2.0, size=9)
    model = GRUModel(weights, mean, std)
    features = rng.normal(size=(80, 9)) * 3
    ours, _ = model.predict_stream(features)
    session = _session(build_onnx(model))
    assert [o.name for o in session.get_outputs()][-1] == "confirm_probability"
    zeros1, zeros2 = np.zeros((1, 1, 32), np.float32), np.zeros((1, 1, 16), np.float32)
    anomaly, _, _, _, confirm = _run(session, features[:, None, :], zeros1, zeros2)
    np.testing.assert_allclose(confirm[:, 0], ours.confirm, atol=1e-5)
    np.testing.assert_allclose(anomaly[:, 0], ours.anomaly, atol=1e-5)


def test_onnx_batch_axis_runs_tracks_independently(random_model):
    rng = np.random.default_rng(6)
    a, b = rng.normal(size=(2, 50, random_model.n_features))
    session = _session(build_onnx(random_model))
    anomaly, _, _, _ = _run(
        session,
        np.stack([a, b], axis=1),
        np.zeros((1, 2, 32), np.float32),
        np.zeros((1, 2, 16), np.float32),
    )
    np.testing.assert_allclose(anomaly[:, 0], random_model.predict_stream(a)[0].anomaly, atol=1e-5)
    np.testing.assert_allclose(anomaly[:, 1], random_model.predict_stream(b)[0].anomaly, atol=1e-5)


def test_cli_exports_the_shipped_model_and_it_runs_on_real_features(tmp_path):
    from gradgps._data.simulator import simulate_drive
    from gradgps._grad.model_io import gru_model, load_model
    from gradgps._grad.pipeline import grad_features
    from gradgps._tracks.geo import LocalFrame

    out = tmp_path / "grad.onnx"
    result = CliRunner().invoke(main, ["export", "--onnx", str(out)])
    assert result.exit_code == 0, result.output
    proto = onnx.load(str(out))
    meta = {p.key: p.value for p in proto.metadata_props}
    loaded = load_grad_model(None)
    assert meta["bias_classes"].split(",") == list(loaded.bias_classes)
    assert float(meta["anomaly_threshold"]) == loaded.params.threshold
    bands = json.loads(meta["thresholds_by_rate"])  # the shipped model's slow band
    assert [b["anomaly"] for b in bands] == [b.anomaly for b in loaded.params.rate_thresholds]

    drive = simulate_drive(minutes=3.0, seed=2)
    frame = LocalFrame(float(drive["lat"].iloc[0]), float(drive["lon"].iloc[0]))
    columns = {c: drive[c].to_numpy(np.float64) for c in ("t", "lat", "lon", "speed", "heading")}
    features = grad_features(
        loaded.params,
        frame,
        columns["t"],
        columns["lat"],
        columns["lon"],
        columns["speed"],
        columns["heading"],
    ).features
    weights, config = load_model(loaded.path)
    ours = gru_model(weights, config).predict_stream(features)[0]
    arch = config["architecture"]  # the shipped network's own sizes (four members: 128, 64)
    anomaly, bias, _, _, *confirm = _run(
        _session(proto),
        features[:, None, :],
        np.zeros((1, 1, arch["hidden1"]), np.float32),
        np.zeros((1, 1, arch["hidden2"]), np.float32),
    )
    np.testing.assert_allclose(anomaly[:, 0], ours.anomaly, atol=1e-5)
    np.testing.assert_allclose(bias[:, 0, :], ours.bias, atol=1e-5)
    assert len(confirm) == (ours.confirm is not None)  # the confirm head, where it has one
    if ours.confirm is not None:
        np.testing.assert_allclose(confirm[0][:, 0], ours.confirm, atol=1e-5)
