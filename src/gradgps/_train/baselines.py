"""Training the comparison baselines on a data set, the way GRAD is trained, and caching them.

Same data as GRAD (:mod:`gradgps._train.grad`): the data set's *train*
split injected with every seed of :class:`GradTrainingSet` (protocol
``grad``) or with the ``mixed`` sensor-grid row and the same seeds (protocol
``sensor-grid``); the *validation* split injected with the validation seed
for early stopping and thresholds. Same budget and stopping as GRAD: Adam at
3e-3, balanced class weights, up to 400 epochs of at most 100,000 windows,
early stopping on validation anomaly F1 with patience 25, a 3-minute wall
budget, one torch thread, seeded; then the anomaly threshold with the best
validation F1 (:func:`gradgps._train.torch_gru.train_model` does the same for the
GRU; its helpers are reused here, the loop differs because these networks
judge windows, not sequences). The channel-wise GRAD of protocol
``sensor-grid`` (:mod:`gradgps._baselines.channel_grad`) is trained with
:func:`gradgps._train.torch_gru.train_model` itself (:func:`dataset_channel_grad`).

Torch is imported inside the functions that train, so fitting the Kalman
filter and loading cached models never needs it.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .._baselines.base import Segment, segments
from .._baselines.channel_grad import SENSOR_BIAS_CLASSES, ChannelGradModel, channel_features
from .._baselines.kalman import KalmanDetector, KalmanParams, tune_threshold
from .._baselines.window import (
    WindowModel,
    input_rows,
    load_window_model,
    save_window_model,
    scale_rows,
    windows,
)
from .._data.inject import inject_grad, inject_sensor_grid, with_accel_mps2
from .._exceptions import ConfigError, ModelError
from .._grad.features import FeatureParams
from .._grad.gru import GRUModel
from .._grad.rema import RemaParams
from .._result import f1_score
from .._tracks.track import ColumnMap, to_fixes
from .cache import cached_path

if TYPE_CHECKING:
    from torch import nn

__all__ = [
    "BaselineRecipe",
    "dataset_channel_grad",
    "dataset_cnn_kf",
    "dataset_kalman",
    "dataset_window_model",
    "labelled_fixes",
    "train_window_model",
]

PROTOCOL_INPUTS = {"grad": "position", "sensor-grid": "sensor"}
SENSOR_EXTRA = ["accel_x_mps2", "gyro_z_dps"]
WINDOW = 20


@dataclass(frozen=True)
class BaselineRecipe:
    """Everything that decides a trained baseline; its hash keys the cache.

    The defaults are GRAD's (:class:`gradgps._train.grad.GradTrainingSet`
    and ``train_grad``'s settings); ``--quick`` benchmarks shrink them.
    """

    seeds: tuple[int, ...] = tuple(range(101, 111))
    val_seed: int = 7
    time_budget_s: float = 180.0
    max_epochs: int = 400
    patience: int = 25
    learning_rate: float = 3e-3
    batch_size: int = 256
    max_samples_per_epoch: int = 100_000
    window: int = WINDOW
    seed: int = 0


def _inputs(protocol: str) -> str:
    if protocol not in PROTOCOL_INPUTS:
        raise ConfigError(
            f"unknown protocol {protocol!r}; choose one of {', '.join(PROTOCOL_INPUTS)}"
        )
    return PROTOCOL_INPUTS[protocol]


def labelled_fixes(
    table: pd.DataFrame, protocol: str, seed: int | None, scale: float = 1.0
) -> tuple[pd.DataFrame, np.ndarray, pd.DataFrame]:
    """``(fixes, label_anomaly per row, labelled table)``; ``seed=None`` gives the clean fixes."""
    cmap: ColumnMap = to_fixes(table).attrs["columns"]
    channels = SENSOR_EXTRA if protocol == "sensor-grid" else []
    if seed is None:
        clean = with_accel_mps2(table) if protocol == "sensor-grid" else table
        fixes = to_fixes(clean, cmap, channels=channels)
        return fixes, np.zeros(len(fixes), np.int64), clean
    if protocol == "grad":
        labelled = inject_grad(table, seed=seed, scale=scale, columns=cmap)
    else:
        labelled = inject_sensor_grid(table, row="mixed", seed=seed, scale=scale, columns=cmap)
    fixes = to_fixes(labelled, cmap, channels=channels)
    return fixes, labelled["label_anomaly"].to_numpy(np.int64), labelled


def _labelled_segments(
    table: pd.DataFrame, protocol: str, seeds: Sequence[int]
) -> tuple[list[Segment], list[np.ndarray]]:
    segs: list[Segment] = []
    labels: list[np.ndarray] = []
    for seed in seeds:
        fixes, truth, _ = labelled_fixes(table, protocol, seed)
        for seg in segments(fixes, _inputs(protocol))[0]:
            segs.append(seg)
            labels.append(truth[seg.rows])
    return segs, labels


# ----------------------------------------------------------------------------
# Kalman filter
# ----------------------------------------------------------------------------


def fit_kalman(
    train: pd.DataFrame, val: pd.DataFrame, protocol: str, recipe: BaselineRecipe
) -> KalmanParams:
    """``q``, ``r`` on the clean train split; threshold on the injected validation split."""
    clean, _, _ = labelled_fixes(train, protocol, None)
    val_fixes, val_truth, _ = labelled_fixes(val, protocol, recipe.val_seed)
    det = KalmanDetector(_inputs(protocol)).fit([clean], [val_fixes], [val_truth])
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

    from .torch_gru import _best_threshold, _class_weights, _fit_scaler, _optimise

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
            best_f1, best_epoch, best_state = -math.inf, 0, None
            history: list[dict[str, float]] = []
            stop_reason = "max_epochs"

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
                if val_f1 > best_f1:
                    best_f1, best_epoch = val_f1, epoch
                    best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
                if out_of_time:
                    stop_reason = "time_budget"
                    break
                if epoch - best_epoch >= recipe.patience:
                    stop_reason = "patience"
                    break
            if best_state is not None:
                net.load_state_dict(best_state)
            threshold = _best_threshold(val_truth, val_probability())
    finally:
        torch.set_num_threads(threads)
        torch.use_deterministic_algorithms(deterministic)
    weights = {k: v.detach().numpy().astype(np.float32) for k, v in net.state_dict().items()}
    config = {
        "training": {
            "recipe": asdict(recipe),
            "best_epoch": best_epoch,
            "stop_reason": stop_reason,
            "history": history,
            **(notes or {}),
        }
    }
    return WindowModel(architecture, inputs, recipe.window, mean, std, threshold, weights, config)


# ----------------------------------------------------------------------------
# Cache: trained once per (what decides it), like gradgps._train.grad.dataset_model
# ----------------------------------------------------------------------------


def _cache_dir(
    kind: str, dataset: str, protocol: str, recipe: BaselineRecipe, data_dir: str | Path | None
) -> Path:
    settings = {"kind": kind, "dataset": dataset, "protocol": protocol, "recipe": asdict(recipe)}
    return cached_path("baselines", f"{kind}-{dataset}-{protocol}", settings, dataset, data_dir)


def _splits(dataset: str, data_dir: str | Path | None) -> tuple[pd.DataFrame, pd.DataFrame]:
    from .._data.datasets import load_dataset

    return (
        load_dataset(dataset, "train", data_dir=data_dir),
        load_dataset(dataset, "validation", data_dir=data_dir),
    )


def dataset_kalman(
    dataset: str,
    protocol: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
) -> KalmanParams:
    """The ``kf`` filter fitted on ``dataset`` for ``protocol`` (cached as JSON)."""
    rec = recipe or BaselineRecipe()
    target = _cache_dir("kf", dataset, protocol, rec, data_dir) / "kalman.json"
    if not target.is_file():
        params = fit_kalman(*_splits(dataset, data_dir), protocol, rec)
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
    target = _cache_dir(architecture, dataset, protocol, rec, data_dir)
    if not (target / "config.json").is_file():
        train, val = _splits(dataset, data_dir)
        model = train_window_model(
            architecture,
            _labelled_segments(train, protocol, rec.seeds),
            _labelled_segments(val, protocol, (rec.val_seed,)),
            _inputs(protocol),
            rec,
            {"dataset": dataset, "protocol": protocol},
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
    target = _cache_dir("cnn-kf", dataset, protocol, rec, data_dir) / "kalman.json"
    if not target.is_file():
        _, val = _splits(dataset, data_dir)
        segs, labels = _labelled_segments(val, protocol, (rec.val_seed,))
        forced = [cnn.segment_probability(s) >= cnn.threshold for s in segs]
        threshold = tune_threshold(segs, labels, np.array(kf.q), np.array(kf.r), kf.joint, forced)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps({**kf.to_dict(), "threshold": threshold}) + "\n")
    return cnn, KalmanParams.from_dict(json.loads(target.read_text()))


def _sequences(
    table: pd.DataFrame, seeds: Sequence[int], features: FeatureParams, rema: RemaParams
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    index = {name: i for i, name in enumerate(SENSOR_BIAS_CLASSES)}
    out = []
    for seed in seeds:
        fixes, truth, labelled = labelled_fixes(table, "sensor-grid", seed)
        kinds = np.array([index[str(v)] for v in labelled["label_type"].to_numpy(object)])
        for seg in segments(fixes, "sensor")[0]:
            out.append(
                (
                    channel_features(seg, features, rema).astype(np.float32),
                    truth[seg.rows],
                    kinds[seg.rows],
                )
            )
    return out


def dataset_channel_grad(
    dataset: str, data_dir: str | Path | None = None, recipe: Any = None
) -> ChannelGradModel:
    """Channel-wise GRAD trained on ``dataset`` under ``sensor-grid`` (cached; see module doc).

    ``recipe`` is a :class:`gradgps._train.baselines.BaselineRecipe` (seeds, budget, stopping).
    """

    rec = recipe or BaselineRecipe()
    features, rema = FeatureParams(speed_heading=False), RemaParams()
    settings = {
        "recipe": asdict(rec),
        "dataset": dataset,
        "features": asdict(features),
        "rema": asdict(rema),
    }
    target = cached_path("baselines", f"channel-grad-{dataset}", settings, dataset, data_dir)
    if not (target / "config.json").is_file():
        from .torch_gru import TrainConfig, train_model  # torch only when training

        train, val = _splits(dataset, data_dir)
        config = TrainConfig(
            bias_classes=SENSOR_BIAS_CLASSES,
            mode="stream",
            time_budget_s=rec.time_budget_s,
            seed=rec.seed,
            progress=False,
            early_stopping="f1",
            patience=rec.patience,
            learning_rate=rec.learning_rate,
            max_epochs=rec.max_epochs,
        )
        trained = train_model(
            _sequences(train, rec.seeds, features, rema),
            _sequences(val, (rec.val_seed,), features, rema),
            config,
        )
        target.mkdir(parents=True, exist_ok=True)
        np.savez(target / "weights.npz", allow_pickle=False, **trained.weights())
        cfg = {
            "threshold": trained.anomaly_threshold,
            "scaler": {
                "mean": trained.network.scaler_mean.tolist(),
                "std": trained.network.scaler_std.tolist(),
            },
            "best_epoch": trained.best_epoch,
            "stop_reason": trained.stop_reason,
        }
        (target / "config.json").write_text(json.dumps(cfg) + "\n")
    try:
        cfg = json.loads((target / "config.json").read_text())
        with np.load(target / "weights.npz", allow_pickle=False) as data:
            weights = {k: data[k] for k in data.files}
        gru = GRUModel(
            weights,
            np.asarray(cfg["scaler"]["mean"]),
            np.asarray(cfg["scaler"]["std"]),
            mode="stream",
        )
    except (OSError, KeyError, ValueError) as exc:
        raise ModelError(
            f"{target}: unusable channel-GRAD model ({exc}); delete it to retrain"
        ) from exc
    if not 0.0 < float(cfg["threshold"]) < 1.0:
        raise ConfigError(f"{target}: threshold {cfg['threshold']} outside (0, 1)")
    return ChannelGradModel(gru, float(cfg["threshold"]), features, rema)
