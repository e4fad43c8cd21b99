"""Training the comparison baselines on a data set, the way GRAD is trained, and caching them.

Same data as GRAD (:mod:`gradgps._train.grad`): the data set's *train*
split injected with every seed of :class:`GradTrainingSet` (protocol
``grad``) or with the recipe's sensor-grid row (``mixed``, or one row for
per-row experiments) and the recipe's seeds (protocol ``sensor-grid``);
the *validation* split injected with the validation seed
for early stopping and thresholds. Same budget and stopping as GRAD: Adam at
3e-3, balanced class weights, up to 400 epochs of at most 100,000 windows,
early stopping on validation anomaly F1 with patience 25, a 3-minute wall
budget, one torch thread, seeded; then the anomaly threshold with the best
validation F1 (:func:`gradgps._train.torch_gru.train_model` does the same for the
GRU; its helpers are reused here, the loop differs because these networks
judge windows, not sequences). ``waved`` (:func:`dataset_waved`) combines
the trained ``cnn`` and ``lstm-cnn``. The recipe and the labelled data live
in :mod:`gradgps._train.baseline_recipe`; the channel GRAD of protocol
``sensor-grid`` is trained by :mod:`gradgps._train.channel_grad`.

Torch is imported inside the functions that train, so fitting the Kalman
filter and loading cached models never needs it.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .._baselines.base import Segment, segments
from .._baselines.kalman import KalmanDetector, KalmanParams, fit_noise, tune_threshold
from .._baselines.waved import WavedModel
from .._baselines.window import (
    WindowModel,
    input_rows,
    load_window_model,
    save_window_model,
    scale_rows,
    windows,
)
from .._exceptions import ConfigError
from .._result import f1_score
from .baseline_recipe import (
    BaselineRecipe,
    inputs_for,
    labelled_fixes,
    labelled_segments,
    splits,
)
from .cache import baseline_dir

if TYPE_CHECKING:
    from torch import nn

__all__ = [
    "BaselineRecipe",
    "dataset_cnn_kf",
    "dataset_kalman",
    "dataset_waved",
    "dataset_window_model",
    "inputs_for",
    "labelled_fixes",
    "labelled_segments",
    "splits",
    "train_window_model",
]

# ----------------------------------------------------------------------------
# Kalman filter
# ----------------------------------------------------------------------------


def fit_kalman(
    train: pd.DataFrame, val: pd.DataFrame, protocol: str, recipe: BaselineRecipe
) -> KalmanParams:
    """``q``, ``r`` on the clean train split; threshold on the injected validation split."""
    clean, _, _ = labelled_fixes(train, protocol, None, recipe=recipe)
    val_fixes, val_truth, _ = labelled_fixes(val, protocol, recipe.val_seed, recipe=recipe)
    det = KalmanDetector(inputs_for(protocol, recipe)).fit([clean], [val_fixes], [val_truth])
    return det.params_


# ----------------------------------------------------------------------------
# Window classifiers (torch)
# ----------------------------------------------------------------------------


def _cnn_net(n_features: int, window: int) -> nn.Module:
    from torch import nn

    class CNNNet(nn.Module):
        """PyTorch twin of :func:`gradgps._baselines.cnn.cnn_forward` (same parameter names)."""

        def __init__(self) -> None:
            super().__init__()
            self.conv1 = nn.Conv1d(n_features, 32, 5, padding=2)
            self.conv2 = nn.Conv1d(32, 32, 5, padding=2)
            self.dense = nn.Linear(32 * window, 64)
            self.out = nn.Linear(64, 2)

        def forward(self, x: Any) -> Any:  # x (N, W, F)
            h = self.conv2(self.conv1(x.transpose(1, 2)).relu()).relu()
            return self.out(self.dense(h.flatten(1)).relu())

    return CNNNet()


def _lstm_cnn_net(n_features: int, window: int) -> nn.Module:
    import torch
    from torch import nn

    class LSTMCNNNet(nn.Module):
        """PyTorch twin of :func:`gradgps._baselines.lstm_cnn.lstm_cnn_forward` (same parameter names)."""

        def __init__(self) -> None:
            super().__init__()
            self.conv1 = nn.Conv1d(n_features, 32, 3, padding=1)
            self.conv2 = nn.Conv1d(32, 32, 3, padding=1)
            self.conv3 = nn.Conv1d(32, 32, 3, padding=1)
            self.lstm = nn.LSTM(32, 32, batch_first=True)
            self.attention = nn.Linear(32, 32)
            self.attention_v = nn.Linear(32, 1, bias=False)
            self.dense = nn.Linear(32, 32)
            self.out = nn.Linear(32, 2)

        def forward(self, x: Any) -> Any:
            h = self.conv3(self.conv2(self.conv1(x.transpose(1, 2)).relu()).relu()).relu()
            states, _ = self.lstm(h.transpose(1, 2))
            energy = self.attention_v(torch.tanh(self.attention(states)))[:, :, 0]
            context = (torch.softmax(energy, dim=1)[:, :, None] * states).sum(dim=1)
            return self.out(self.dense(context).relu())

    return LSTMCNNNet()


NETS = {"cnn": _cnn_net, "lstm-cnn": _lstm_cnn_net}


def _packed_windows(rows: Sequence[np.ndarray], window: int) -> tuple[np.ndarray, np.ndarray]:
    """Scaled rows of all segments end to end, each after ``window - 1`` zero rows; target indices."""
    width = rows[0].shape[1]
    parts, targets, offset = [], [], 0
    for r in rows:
        parts += [np.zeros((window - 1, width), np.float32), r]
        targets.append(offset + window - 1 + np.arange(len(r)))
        offset += window - 1 + len(r)
    return np.vstack(parts), np.concatenate(targets)


def train_window_model(
    architecture: str,
    train: tuple[list[Segment], list[np.ndarray]],
    val: tuple[list[Segment], list[np.ndarray]],
    inputs: str,
    recipe: BaselineRecipe,
    notes: dict[str, Any] | None = None,
) -> WindowModel:
    """Train ``cnn`` or ``lstm-cnn`` on labelled segments; best validation-F1 epoch, tuned threshold."""
    import torch
    from torch import nn

    from .thresholds import best_f1_threshold
    from .torch_gru import _BestEpoch, _class_weights, _fit_scaler, _optimise

    if architecture not in NETS:
        raise ConfigError(
            f"unknown window architecture {architecture!r}; choose one of {list(NETS)}"
        )
    raw = [input_rows(s, inputs) for s in train[0]]
    mean, std = _fit_scaler(np.vstack(raw))
    data, targets = _packed_windows([scale_rows(r, mean, std) for r in raw], recipe.window)
    labels = np.concatenate(train[1]).astype(np.int64)
    val_windows = np.vstack(
        [windows(scale_rows(input_rows(s, inputs), mean, std), recipe.window) for s in val[0]]
    )
    val_truth = np.concatenate(val[1]).astype(bool)
    offsets = np.arange(-recipe.window + 1, 1)

    threads, deterministic = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    try:
        with torch.random.fork_rng():
            torch.manual_seed(recipe.seed)
            rng = np.random.default_rng(recipe.seed)
            net = NETS[architecture](data.shape[1], recipe.window)
            loss_fn = nn.CrossEntropyLoss(weight=_class_weights(labels, 2, 50.0))
            optimizer = torch.optim.Adam(net.parameters(), lr=recipe.learning_rate)
            began = time.perf_counter()
            best = _BestEpoch(net, recipe.patience)
            history: list[dict[str, float]] = []

            def val_probability() -> np.ndarray:
                net.eval()
                with torch.no_grad():
                    parts = [
                        torch.softmax(net(torch.from_numpy(val_windows[lo : lo + 4096])), -1)[:, 1]
                        for lo in range(0, len(val_windows), 4096)
                    ]
                return torch.cat(parts).numpy()

            for epoch in range(1, recipe.max_epochs + 1):
                net.train()
                losses = []
                pick = rng.permutation(len(targets))[: recipe.max_samples_per_epoch]
                out_of_time = False
                for lo in range(0, len(pick), recipe.batch_size):
                    chosen = pick[lo : lo + recipe.batch_size]
                    x = torch.from_numpy(data[targets[chosen, None] + offsets])
                    y = torch.from_numpy(labels[chosen])
                    losses.append(_optimise(optimizer, loss_fn(net(x), y)))
                    if time.perf_counter() - began > recipe.time_budget_s:
                        out_of_time = True
                        break
                val_f1 = f1_score(val_truth, val_probability() >= 0.5)
                history.append(
                    {
                        "epoch": epoch,
                        "train_loss": float(np.mean(losses)),
                        "val_f1": val_f1,
                        "seconds": time.perf_counter() - began,
                    }
                )
                if best.stop(epoch, -val_f1, out_of_time):
                    break
            best.restore()
            threshold = best_f1_threshold(val_truth, val_probability())
    finally:
        torch.set_num_threads(threads)
        torch.use_deterministic_algorithms(deterministic)
    weights = {k: v.detach().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    config = {
        "training": {
            "recipe": asdict(recipe),
            "best_epoch": best.epoch,
            "stop_reason": best.stop_reason,
            "history": history,
            **(notes or {}),
        }
    }
    return WindowModel(architecture, inputs, recipe.window, mean, std, threshold, weights, config)


# ----------------------------------------------------------------------------
# Cache: trained once per (what decides it), like gradgps._train.grad.dataset_model
# ----------------------------------------------------------------------------


def dataset_kalman(
    dataset: str,
    protocol: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
) -> KalmanParams:
    """The ``kf`` filter fitted on ``dataset`` for ``protocol`` (cached as JSON)."""
    rec = recipe or BaselineRecipe()
    target = baseline_dir("kf", dataset, protocol, rec, data_dir) / "kalman.json"
    if not target.is_file():
        inputs = inputs_for(protocol, rec)
        train, val = splits(dataset, data_dir)
        # q and r come from the clean drives: one fit serves every row.
        noise_rec = replace(rec, row="mixed", constant="stuck")
        noise_file = baseline_dir("kf-noise", dataset, protocol, noise_rec, data_dir) / "noise.json"
        if not noise_file.is_file():
            clean, _, _ = labelled_fixes(train, protocol, None, recipe=rec)
            q, r = fit_noise(segments(clean, inputs)[0])
            noise_file.parent.mkdir(parents=True, exist_ok=True)
            noise_file.write_text(json.dumps({"q": q.tolist(), "r": r.tolist()}) + "\n")
        noise = json.loads(noise_file.read_text())
        q, r = np.asarray(noise["q"], np.float64), np.asarray(noise["r"], np.float64)
        segs, labels = labelled_segments(val, protocol, (rec.val_seed,), rec)
        threshold = tune_threshold(segs, labels, q, r, inputs == "position")
        params = KalmanParams(inputs, tuple(q.tolist()), tuple(r.tolist()), threshold)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(params.to_dict()) + "\n")
    return KalmanParams.from_dict(json.loads(target.read_text()))


def dataset_window_model(
    architecture: str,
    dataset: str,
    protocol: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
) -> WindowModel:
    """``cnn`` or ``lstm-cnn`` trained on ``dataset`` for ``protocol`` (cached model directory)."""
    rec = recipe or BaselineRecipe()
    target = baseline_dir(architecture, dataset, protocol, rec, data_dir)
    if not (target / "config.json").is_file():
        train, val = splits(dataset, data_dir)
        model = train_window_model(
            architecture,
            labelled_segments(train, protocol, rec.seeds, rec),
            labelled_segments(val, protocol, (rec.val_seed,), rec),
            inputs_for(protocol, rec),
            rec,
            {"dataset": dataset, "protocol": protocol, "row": rec.row},
        )
        save_window_model(target, model)
    return load_window_model(target)


def dataset_cnn_kf(
    dataset: str,
    protocol: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
) -> tuple[WindowModel, KalmanParams]:
    """The ``cnn`` model and a ``kf`` filter whose threshold is re-tuned with the CNN in front."""
    rec = recipe or BaselineRecipe()
    cnn = dataset_window_model("cnn", dataset, protocol, data_dir, rec)
    kf = dataset_kalman(dataset, protocol, data_dir, rec)
    target = baseline_dir("cnn-kf", dataset, protocol, rec, data_dir) / "kalman.json"
    if not target.is_file():
        _, val = splits(dataset, data_dir)
        segs, labels = labelled_segments(val, protocol, (rec.val_seed,), rec)
        forced = [cnn.segment_probability(s) >= cnn.threshold for s in segs]
        threshold = tune_threshold(segs, labels, np.array(kf.q), np.array(kf.r), kf.joint, forced)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps({**kf.to_dict(), "threshold": threshold}) + "\n")
    return cnn, KalmanParams.from_dict(json.loads(target.read_text()))


def dataset_waved(
    dataset: str,
    protocol: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
) -> WavedModel:
    """``waved``: the ``cnn`` and ``lstm-cnn`` models, weight and threshold tuned on validation."""
    from .._baselines.waved import WAVED_WEIGHTS, ensemble_probability
    from .thresholds import best_f1_threshold

    rec = recipe or BaselineRecipe()
    cnn = dataset_window_model("cnn", dataset, protocol, data_dir, rec)
    lstm = dataset_window_model("lstm-cnn", dataset, protocol, data_dir, rec)
    target = baseline_dir("waved", dataset, protocol, rec, data_dir) / "waved.json"
    if not target.is_file():
        _, val = splits(dataset, data_dir)
        segs, labels = labelled_segments(val, protocol, (rec.val_seed,), rec)
        truth = np.concatenate(labels).astype(bool)
        p_cnn = np.concatenate([cnn.segment_probability(s) for s in segs])
        p_lstm = np.concatenate([lstm.segment_probability(s) for s in segs])
        best = (-1.0, 0.5, 0.5)
        for w in WAVED_WEIGHTS:
            p = ensemble_probability(p_cnn, p_lstm, w)
            threshold = best_f1_threshold(truth, p)
            f1 = f1_score(truth, p >= threshold)
            if f1 > best[0]:
                best = (f1, float(w), threshold)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(
            json.dumps({"weight": best[1], "threshold": best[2], "val_f1": best[0]}) + "\n"
        )
    cfg = json.loads(target.read_text())
    return WavedModel(cnn, lstm, float(cfg["weight"]), float(cfg["threshold"]))
