"""Training the GRU (tiny data, seconds): determinism, stopping rules, export == torch."""

from __future__ import annotations

import io

import numpy as np
import pytest

from _gru_support import toy_sequences

torch = pytest.importorskip("torch")

from rich.console import Console  # noqa: E402

from gradgps import ConfigError  # noqa: E402
from gradgps._grad.model_io import gru_model, load_model, save_model  # noqa: E402
from gradgps._train.torch_gru import (  # noqa: E402
    _IGNORE,
    TrainConfig,
    _class_weights,
    _fit_scaler,
    _pack,
    _predict_packed,
    _stream_lanes,
    _window_batch,
    _window_samples,
    train_model,
)

TRAIN = toy_sequences(16, seed=0)
VAL = toy_sequences(4, seed=1)


def _config(**kw: object) -> TrainConfig:
    base = {"max_epochs": 3, "batch_size": 16, "chunk_length": 24, "window": 8, "progress": False}
    return TrainConfig(**{**base, **kw})  # type: ignore[arg-type]


@pytest.mark.parametrize("mode", ["window", "stream"])
def test_same_seed_same_weights(mode: str):
    first = train_model(TRAIN, VAL, _config(mode=mode, seed=3)).weights()
    second = train_model(TRAIN, VAL, _config(mode=mode, seed=3)).weights()
    other = train_model(TRAIN, VAL, _config(mode=mode, seed=4)).weights()
    assert all(np.array_equal(first[k], second[k]) for k in first)
    assert not all(np.array_equal(first[k], other[k]) for k in first)


def test_learns_a_separable_toy_problem():
    model = train_model(TRAIN, VAL, _config(max_epochs=8, learning_rate=1e-2))
    assert model.history[-1].val_f1 > 0.8
    assert model.history[-1].val_bias_accuracy > 0.8
    assert model.history[-1].val_loss < model.history[0].val_loss
    assert 0.05 <= model.anomaly_threshold <= 0.95


@pytest.mark.parametrize(("mode", "window"), [("window", 8), ("stream", 8)])
def test_exported_model_equals_torch(tmp_path, mode: str, window: int):
    trained = train_model(TRAIN, VAL, _config(mode=mode, window=window, max_epochs=2))
    names = [f"f{i}" for i in range(5)]
    save_model(tmp_path, trained.weights(), trained.model_config(names, {"w": 1}, {"alpha": 0.2}))
    model = gru_model(*load_model(tmp_path))
    features = VAL[0][0]
    net = trained.network
    with torch.no_grad():
        if mode == "stream":
            logits = net(torch.from_numpy(features)[None])[0][0]
        else:
            logits = torch.stack(
                [
                    net(torch.from_numpy(features[max(0, i - window + 1) : i + 1])[None])[0][0, -1]
                    for i in range(len(features))
                ]
            )
    np.testing.assert_allclose(
        model.predict(features).anomaly, torch.softmax(logits, -1)[:, 1].numpy(), atol=1e-5
    )


def test_stops_on_patience_when_nothing_improves():
    # A learning rate far below float32 resolution leaves the weights unchanged.
    model = train_model(TRAIN, VAL, _config(max_epochs=20, patience=2, learning_rate=1e-20))
    assert model.stop_reason == "patience"
    assert len(model.history) == 3
    assert model.best_epoch == 1


def test_stops_when_time_budget_is_spent():
    model = train_model(TRAIN, VAL, _config(max_epochs=50, time_budget_s=1e-6))
    assert model.stop_reason == "time_budget"
    assert len(model.history) == 1


def test_progress_reports_every_epoch():
    out = io.StringIO()
    train_model(
        TRAIN[:4],
        VAL[:2],
        _config(max_epochs=2, progress=True),
        console=Console(file=out, width=120, force_terminal=False),
    )
    text = out.getvalue()
    assert "epoch   1" in text
    assert "epoch   2" in text
    assert "val F1" in text


def test_every_point_is_a_window_target_exactly_once():
    sequences = toy_sequences(6, seed=5)
    sequences.append(
        (sequences[0][0][:3], sequences[0][1][:3], sequences[0][2][:3])
    )  # shorter than W
    window = 10
    packed = _pack(sequences, window, 1)
    starts, first = _window_samples(packed, window)
    _, anomaly, _ = _window_batch(packed, starts, first, window)
    targets = starts[:, None] + np.arange(window)
    hit = targets[anomaly.numpy() != _IGNORE]
    expected = np.concatenate(
        [s + np.arange(n) for s, n in zip(packed.starts, packed.lengths, strict=True)]
    )
    np.testing.assert_array_equal(np.sort(hit), expected)


def test_stream_lanes_cover_every_chunk_once_in_order():
    packed = _pack(toy_sequences(9, seed=7), 1, 8)
    offsets, resets = _stream_lanes(packed, 4, 8, 32, np.random.default_rng(0))
    used = offsets[offsets >= 0]
    expected = np.concatenate(
        [s + 8 * np.arange(-(-n // 8)) for s, n in zip(packed.starts, packed.lengths, strict=True)]
    )
    np.testing.assert_array_equal(np.sort(used), expected)
    for lane, flags in zip(offsets, resets, strict=True):
        for step in range(1, len(lane)):
            if (
                lane[step] >= 0 and not flags[step]
            ):  # continuing a piece: the next chunk of the same sequence
                assert lane[step] == lane[step - 1] + 8
        assert flags[0]
    # Every lane starts with a reset, so cutting the flattened lanes at resets gives the pieces.
    longest_piece = max(
        len(run) for run in np.split(np.arange(resets.size), np.flatnonzero(resets.ravel()))
    )
    assert longest_piece <= 32 // 8


def test_class_weights_balance_rare_anomalies():
    labels = np.array([0] * 90 + [1] * 10 + [_IGNORE] * 5)
    np.testing.assert_allclose(_class_weights(labels, 2, 50.0).numpy(), [1.0, 9.0])
    np.testing.assert_allclose(_class_weights(labels, 2, 4.0).numpy(), [1.0, 4.0])
    np.testing.assert_allclose(
        _class_weights(np.array([0, 0, 2]), 3, 50.0).numpy(), [1.0, 1.0, 2.0]
    )


def test_bad_inputs_fail_clearly():
    with pytest.raises(ConfigError, match="mode must be one of"):
        train_model(TRAIN, VAL, _config(mode="batch"))
    features, anomaly, bias = TRAIN[0]
    with pytest.raises(ConfigError, match=r"sequences\[0\]: bias labels must be in 0..2"):
        train_model([(features, anomaly, bias + 5)], VAL, _config())
    with pytest.raises(ConfigError, match=r"sequences\[0\]: need one anomaly and one bias label"):
        train_model([(features, anomaly[:-1], bias)], VAL, _config())
    with pytest.raises(ConfigError, match="different number of features"):
        train_model(TRAIN, [(features[:, :3], anomaly, bias)], _config())
    with pytest.raises(ConfigError, match="val_sequences: no sequences"):
        train_model(TRAIN, [], _config())


def test_floor_f1_early_stopping_scores_epochs_at_the_floor_threshold():
    from gradgps._result import f1_score
    from gradgps._train.thresholds import recall_floor_threshold

    with pytest.raises(ConfigError, match="needs a normal_recall_floor"):
        train_model(TRAIN, VAL, _config(early_stopping="floor-f1"))
    with pytest.raises(ConfigError, match="early_stopping must be"):
        train_model(TRAIN, VAL, _config(early_stopping="auc"))
    config = _config(early_stopping="floor-f1", normal_recall_floor=0.99, max_epochs=1)
    model = train_model(TRAIN, VAL, config)
    # One epoch: its validation F1 is the F1 at the threshold the floor picks, which is
    # also the model's threshold.
    pred = _predict_packed(model.network.eval(), _pack(VAL, 8, 1), config)
    la, truth = pred.anomaly, pred.a_true
    p = torch.softmax(la, -1)[:, 1].numpy()
    cut = recall_floor_threshold(truth == 1, p, 0.99)
    assert model.anomaly_threshold == pytest.approx(cut)
    assert model.history[-1].val_f1 == pytest.approx(f1_score(truth == 1, p >= cut))
    assert model.history[-1].val_f1 != pytest.approx(f1_score(truth == 1, p >= 0.5))


def test_scaler_ignores_non_finite_values_and_constant_features():
    features = np.array([[1.0, np.nan, 5.0], [3.0, np.nan, 5.0], [np.inf, np.nan, 5.0]], np.float32)
    mean, std = _fit_scaler(features)
    np.testing.assert_allclose(mean, [2.0, 0.0, 5.0])
    np.testing.assert_allclose(std, [1.0, 1.0, 1.0])
    assert mean.dtype == std.dtype == np.float32


def test_trains_with_nan_features_and_segments_of_one_point():
    sequences = toy_sequences(6, seed=8)
    sequences[0][0][:, 3] = np.nan
    sequences.append((sequences[1][0][:1], sequences[1][1][:1], sequences[1][2][:1]))
    for mode in ("window", "stream"):
        model = train_model(sequences, VAL, _config(mode=mode, max_epochs=1))
        assert np.isfinite(model.history[0].val_loss)
        assert all(np.isfinite(w).all() for w in model.weights().values())


@pytest.mark.parametrize("mode", ["window", "stream"])
def test_ignored_points_are_left_out_of_validation_scores(mode: str):
    """A point labelled _IGNORE (a stale start's held fix) teaches nothing and is not scored:
    the threshold and validation F1 see only labelled points, in stream mode as in window
    mode (the stream branch once returned them, counted as normal)."""
    from gradgps._train.torch_gru import GRADNet, _predict_packed

    config = _config(mode=mode)
    sequences = [(f, a.copy(), b.copy()) for f, a, b in VAL]
    for _, anomaly, bias in sequences:
        anomaly[:5] = _IGNORE
        bias[:5] = _IGNORE
    packed = _pack(sequences, config.window, 1)
    net = GRADNet(VAL[0][0].shape[1], 3, config.hidden1, config.hidden2)
    labels = _predict_packed(net, packed, config).a_true
    assert not (labels == _IGNORE).any()
    assert labels.size == sum(len(f) - 5 for f, _, _ in sequences)


def test_packed_previous_labels_stay_inside_their_sequence():
    """The confirm head's target at a step is the anomaly label of the step before in the
    same sequence: never the last step of the sequence packed before it, never padding."""
    packed = _pack(VAL, 8, 24)
    for start, length, (_, anomaly, _) in zip(packed.starts, packed.lengths, VAL, strict=True):
        assert packed.previous[start] == _IGNORE
        np.testing.assert_array_equal(packed.previous[start + 1 : start + length], anomaly[:-1])
        assert (packed.previous[start + length : start + length + 1] == _IGNORE).all()


def test_a_confirm_head_learns_the_previous_steps_labels(tmp_path):
    """Toy faults show in the features of their own step only, so only a head that
    remembers one step back can name the previous step's: the confirm head learns it, gets
    its own threshold, and the exported model runs it as torch does."""
    config = _config(mode="stream", confirm_head=True, max_epochs=10, learning_rate=1e-2)
    trained = train_model(TRAIN, VAL, config)
    assert trained.confirm_threshold is not None
    net = trained.network.eval()
    packed = _pack(VAL, 1, 1)
    pred = _predict_packed(net, packed, config)
    assert pred.confirm is not None
    late = torch.softmax(pred.confirm, -1)[:, 1].numpy() >= trained.confirm_threshold
    truth = pred.previous == 1
    assert (late & truth).sum() / truth.sum() > 0.8  # recall of the previous step's faults
    assert (late & truth).sum() / late.sum() > 0.8  # precision
    names = [f"f{i}" for i in range(5)]
    cfg = trained.model_config(names, {}, {})
    assert cfg["architecture"]["confirm_head"] is True
    assert cfg["thresholds"]["confirm"] == trained.confirm_threshold
    save_model(tmp_path, trained.weights(), cfg)
    model = gru_model(*load_model(tmp_path))
    features = VAL[0][0]
    with torch.no_grad():
        out = net.run(torch.from_numpy(features)[None])
    np.testing.assert_allclose(
        model.predict(features).confirm, torch.softmax(out.confirm, -1)[0, :, 1].numpy(), atol=1e-5
    )


def test_a_confirm_head_needs_stream_mode():
    with pytest.raises(ConfigError, match="confirm_head needs mode 'stream'"):
        train_model(TRAIN, VAL, _config(mode="window", confirm_head=True))
