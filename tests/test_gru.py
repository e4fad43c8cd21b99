"""Torch-free GRU inference: NumPy reference == numba kernels == PyTorch."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _gru_support import GRUFleet, GRUStream, random_weights
from gradgps import ConfigError, ModelError
from gradgps._grad.gru import GRUModel, reference_stream, reference_windows

F, K = 7, 4
SRC = Path(__file__).resolve().parents[1] / "src"


@pytest.fixture(scope="module")
def weights() -> dict[str, np.ndarray]:
    return random_weights(F, K, seed=1)


@pytest.fixture(scope="module")
def scaler() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(2)
    return rng.normal(size=F).astype(np.float32), rng.uniform(0.5, 3.0, F).astype(np.float32)


@pytest.fixture(scope="module")
def features() -> np.ndarray:
    rng = np.random.default_rng(3)
    x = (rng.normal(size=(120, F)) * 3).astype(np.float32)
    x[5, 2] = np.nan
    x[17, 0] = np.inf
    x[40, 1] = 1e30  # saturates every gate: exp overflow must not produce NaN
    return x


def _model(
    weights: dict[str, np.ndarray], scaler: tuple[np.ndarray, np.ndarray], **kw: object
) -> GRUModel:
    return GRUModel(weights, scaler[0], scaler[1], **kw)  # type: ignore[arg-type]


def test_numba_stream_equals_reference(weights, scaler, features):
    model = _model(weights, scaler)
    prediction, state = model.predict_stream(features)
    ref, ref_state = reference_stream(weights, *scaler, features)
    assert np.all(np.isfinite(prediction.anomaly))
    assert np.all(np.isfinite(state))
    assert prediction.confirm is None
    assert ref.confirm is None
    np.testing.assert_allclose(prediction.anomaly, ref.anomaly, atol=1e-6)
    np.testing.assert_allclose(prediction.bias, ref.bias, atol=1e-6)
    np.testing.assert_allclose(state, ref_state, atol=1e-6)
    np.testing.assert_allclose(prediction.bias.sum(axis=1), 1.0, atol=1e-5)


@pytest.mark.parametrize("window", [1, 3, 10, 200])
def test_numba_windows_equal_reference(weights, scaler, features, window):
    prediction = _model(weights, scaler, mode="window", window=window).predict(features)
    ref = reference_windows(weights, *scaler, features, window)
    np.testing.assert_allclose(prediction.anomaly, ref.anomaly, atol=1e-6)
    np.testing.assert_allclose(prediction.bias, ref.bias, atol=1e-6)


def test_any_layer_sizes(features):
    """Nothing assumes 32/16: a second layer wider than the first uses the same kernels."""
    weights = random_weights(F, 3, seed=5, hidden1=5, hidden2=11)
    mean, std = np.zeros(F, np.float32), np.ones(F, np.float32)
    model = GRUModel(weights, mean, std)
    assert model.state_size == 16
    np.testing.assert_allclose(
        model.predict_stream(features)[0].anomaly,
        reference_stream(weights, mean, std, features)[0].anomaly,
        atol=1e-6,
    )
    np.testing.assert_allclose(
        GRUStream(model).update(features[0])[1:],
        reference_stream(weights, mean, std, features[:1])[0].bias[0],
        atol=1e-6,
    )


def test_window_longer_than_segment_is_streaming(weights, scaler, features):
    """Every point sees the whole prefix when W >= n: window mode == stream mode from zero."""
    model = _model(weights, scaler)
    stream = model.predict_stream(features)[0]
    windows = model.predict_windows(features, window=len(features))
    np.testing.assert_allclose(windows.anomaly, stream.anomaly, atol=1e-6)


def _torch_net(weights, scaler):
    torch = pytest.importorskip("torch")
    from gradgps._train.torch_gru import network_from_arrays

    return torch, network_from_arrays(weights, *scaler).eval()


def test_equals_torch_in_both_modes(weights, scaler, features):
    torch, net = _torch_net(weights, scaler)
    with torch.no_grad():
        la, lb, _ = net(torch.from_numpy(features)[None])
        stream_anomaly = torch.softmax(la, -1)[0, :, 1].numpy()
        stream_bias = torch.softmax(lb, -1)[0].numpy()
        window = 6
        win = [
            net(torch.from_numpy(features[max(0, i - window + 1) : i + 1])[None])
            for i in range(len(features))
        ]
        win_anomaly = np.array([torch.softmax(a[0, -1], -1)[1].item() for a, _, _ in win])
    model = _model(weights, scaler)
    np.testing.assert_allclose(model.predict_stream(features)[0].anomaly, stream_anomaly, atol=1e-5)
    np.testing.assert_allclose(model.predict_stream(features)[0].bias, stream_bias, atol=1e-5)
    np.testing.assert_allclose(
        model.predict_windows(features, window).anomaly, win_anomaly, atol=1e-5
    )


def test_confirm_head_equals_reference_and_torch(scaler, features):
    """The confirm head (P(anomaly) of the point before) is one more softmax head on the
    same state: numba == NumPy reference == PyTorch in both modes, and the other heads
    are exactly those of the network without it."""
    weights = random_weights(F, K, seed=1, confirm_head=True)
    plain = {k: v for k, v in weights.items() if not k.startswith("confirm_head")}
    model, without = _model(weights, scaler), _model(plain, scaler)
    assert model.has_confirm_head
    assert not without.has_confirm_head
    prediction, state = model.predict_stream(features)
    ref, _ = reference_stream(weights, *scaler, features)
    np.testing.assert_allclose(prediction.confirm, ref.confirm, atol=1e-6)
    np.testing.assert_array_equal(prediction.anomaly, without.predict_stream(features)[0].anomaly)
    np.testing.assert_array_equal(state, without.predict_stream(features)[1])
    windows = model.predict_windows(features, 5)
    np.testing.assert_allclose(
        windows.confirm, reference_windows(weights, *scaler, features, 5).confirm, atol=1e-6
    )
    np.testing.assert_array_equal(windows.bias, without.predict_windows(features, 5).bias)

    torch, net = _torch_net(weights, scaler)
    assert net.confirm_head is not None
    with torch.no_grad():
        out = net.run(torch.from_numpy(features)[None])
    assert out.confirm is not None
    np.testing.assert_allclose(
        prediction.confirm, torch.softmax(out.confirm, -1)[0, :, 1].numpy(), atol=1e-5
    )
    np.testing.assert_allclose(
        prediction.anomaly, torch.softmax(out.anomaly, -1)[0, :, 1].numpy(), atol=1e-5
    )


def test_half_a_confirm_head_is_refused(weights, scaler):
    extra = random_weights(F, K, seed=1, confirm_head=True)
    with pytest.raises(ModelError, match="part of the confirm head"):
        _model({**weights, "confirm_head.bias": extra["confirm_head.bias"]}, scaler)


@settings(max_examples=25, deadline=None)
@given(split=st.integers(0, 60), seed=st.integers(0, 2**31 - 1))
def test_stream_state_carries_across_calls(split, seed):
    weights = random_weights(3, 2, seed=seed % 7)
    model = GRUModel(weights, np.zeros(3), np.ones(3))
    x = np.random.default_rng(seed).normal(size=(60, 3)).astype(np.float32)
    whole, _ = model.predict_stream(x)
    first, state = model.predict_stream(x[:split])
    second, _ = model.predict_stream(x[split:], state)
    np.testing.assert_array_equal(np.concatenate([first.anomaly, second.anomaly]), whole.anomaly)


@pytest.mark.parametrize(("mode", "window"), [("stream", 10), ("window", 5)])
def test_one_track_stream_matches_batch_and_restores_state(weights, scaler, features, mode, window):
    model = _model(weights, scaler, mode=mode, window=window)
    batch = model.predict(features)
    stream = GRUStream(model)
    online = np.array([stream.update(x).copy() for x in features[:50]])
    saved = json.loads(json.dumps(stream.get_state()))
    restored = GRUStream(model)
    restored.set_state(saved)
    online = np.vstack([online, [restored.update(x).copy() for x in features[50:]]])
    np.testing.assert_allclose(online[:, 0], batch.anomaly, atol=1e-6)
    np.testing.assert_allclose(online[:, 1:], batch.bias, atol=1e-6)
    stream.reset()
    np.testing.assert_allclose(stream.update(features[0])[0], batch.anomaly[0], atol=1e-6)


def test_fleet_steps_tracks_independently(weights, scaler):
    model = _model(weights, scaler)
    rng = np.random.default_rng(4)
    tracks = [rng.normal(size=(n, F)).astype(np.float32) for n in (30, 12, 25)]
    expected = [model.predict_stream(x)[0].anomaly for x in tracks]
    fleet = GRUFleet(model, 3)
    got: list[list[float]] = [[], [], []]
    cursor = [0, 0, 0]
    for _ in range(40):  # each step, a random subset of vehicles reports
        rows = np.array(
            [k for k in range(3) if cursor[k] < len(tracks[k]) and rng.random() < 0.7], np.int64
        )
        if rows.size == 0:
            continue
        prediction = fleet.step(rows, np.array([tracks[k][cursor[k]] for k in rows]))
        for k, p in zip(rows, prediction.anomaly, strict=True):
            got[k].append(float(p))
            cursor[k] += 1
    for k in range(3):
        np.testing.assert_allclose(got[k], expected[k][: cursor[k]], atol=1e-6)
    fleet.reset(np.array([0]))
    assert not fleet.states[0].any()
    assert fleet.states[1].any()


def test_bad_shapes_fail_clearly(weights, scaler):
    broken = dict(weights)
    broken["gru2.weight_hh"] = broken["gru2.weight_hh"][:, :3]
    with pytest.raises(ModelError, match=r"gru2\.weight_hh"):
        _model(broken, scaler)
    with pytest.raises(ModelError, match=r"lack gru1\.bias_ih"):
        _model({k: v for k, v in weights.items() if k != "gru1.bias_ih"}, scaler)
    with pytest.raises(ModelError, match="scaler"):
        GRUModel(weights, np.zeros(F), np.zeros(F))
    model = _model(weights, scaler)
    with pytest.raises(ConfigError, match=r"shape \(n, 7\)"):
        model.predict(np.zeros((4, F + 1)))
    with pytest.raises(ConfigError, match="stream-mode"):
        GRUFleet(_model(weights, scaler, mode="window"), 2)
    with pytest.raises(ConfigError, match=r"shape \(7,\)"):
        GRUStream(model).update(np.zeros(F - 1, np.float32))
    with pytest.raises(ConfigError, match="rows must be in"):
        GRUFleet(model, 2).step(np.array([2]), np.zeros((1, F)))


def test_inference_never_imports_torch(tmp_path):
    """Importing gradgps, loading a model directory and running every kernel must not pull in torch."""
    script = textwrap.dedent("""
        import sys
        import numpy as np
        import gradgps
        from gradgps._grad.model_io import gru_model, load_model, save_model
        sys.path.insert(0, sys.argv[2])
        from _gru_support import GRUFleet, GRUStream, model_config, random_weights
        save_model(sys.argv[1], random_weights(4, 3), model_config(4, 3, mode="stream"))
        model = gru_model(*load_model(sys.argv[1]))
        x = np.random.default_rng(0).normal(size=(20, 4)).astype(np.float32)
        model.predict_stream(x); model.predict_windows(x, 5); GRUStream(model).update(x[0])
        GRUFleet(model, 2).step(np.array([0, 1]), x[:2])
        assert "torch" not in sys.modules, sorted(m for m in sys.modules if m.startswith("torch"))
        print("ok")
    """)
    env = {**os.environ, "PYTHONPATH": str(SRC), "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "m"), str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"
