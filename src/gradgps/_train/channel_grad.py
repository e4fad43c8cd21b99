"""Training the channel GRAD of protocol ``sensor-grid`` (:mod:`gradgps._baselines.channel_grad`).

Same data, seeds and budget as the comparison baselines
(:class:`gradgps._train.baselines.BaselineRecipe`: the train split injected
with the recipe's seeds and row, the validation split with the validation
seed; the same wall-clock budget, patience and learning rate), in three steps:

1. **REMA per channel**: a grid over ``alpha``, ``slide_size`` and
   ``sensitivity`` (:data:`REMA_GRID`); for each channel the setting whose
   REMA flags have the best F1 against that channel's labels on the
   validation split (a channel that is never faulty keeps the defaults);
2. the GRU (32, 16) in the paper's feed-sliding-window mode (W = 10
   steps: trained on independent windows like the window baselines, which
   fits more updates into the shared budget than stream mode), early stopping
   on validation F1 (:func:`gradgps._train.torch_gru.train_model`);
3. the anomaly threshold: the best validation F1 among thresholds that keep
   validation normal recall at or above :data:`NORMAL_RECALL_FLOOR` (a
   detector that flags normal readings wholesale is no use on a vehicle).

Cached under ``$GRADGPS_CACHE/baselines/channel-grad-*``, keyed by
everything that decides the model.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._baselines.base import segments
from .._baselines.channel_grad import (
    CROSS_SOURCES,
    SENSOR_BIAS_CLASSES,
    ChannelGradModel,
    channel_features,
    channel_signals,
    rema_names,
)
from .._exceptions import ConfigError, ModelError
from .._grad.features import FeatureParams
from .._grad.gru import GRUModel
from .._grad.rema import RemaParams, rema_batch
from .._result import f1_score
from .baseline_recipe import BaselineRecipe, inputs_for, labelled_fixes, splits
from .cache import baseline_dir
from .thresholds import NORMAL_RECALL_FLOOR, best_f1_threshold, recall_floor_threshold

if TYPE_CHECKING:  # torch only when training
    from .torch_gru import TrainConfig

__all__ = [
    "GRU_WINDOW",
    "NORMAL_RECALL_FLOOR",
    "REMA_GRID",
    "dataset_channel_grad",
    "recall_floor_threshold",
    "tune_channel_rema",
]

#: (alpha, slide_size, sensitivity) settings searched per channel.
REMA_GRID = tuple(itertools.product((0.3, 0.5, 0.8), (5, 10, 20), (2.0, 3.0, 4.0, 6.0)))
#: The paper's feed sliding window: each verdict from the GRU run over the last 10 steps.
GRU_WINDOW = 10
#: Validation normal recall the anomaly threshold must keep.
#: The fixes' channel name -> the injection's label column.
_LABEL = {
    "speed": "label_speed_mps",
    "accel_x_mps2": "label_accel_x_mps2",
    "gyro_z_dps": "label_gyro_z_dps",
}


def tune_channel_rema(
    values: Sequence[np.ndarray], labels: Sequence[np.ndarray]
) -> tuple[RemaParams, float]:
    """The :data:`REMA_GRID` setting with the best flag F1 on one channel's segments; and that F1.

    ``values[i]`` are one segment's readings (missing ones carried forward),
    ``labels[i]`` its 0/1 labels for this channel. No faulty reading: the
    defaults, F1 0.
    """
    truth = np.concatenate(labels).astype(bool) if labels else np.zeros(0, bool)
    if not truth.any():
        return RemaParams(), 0.0
    best, best_f1 = RemaParams(), -1.0
    for alpha, slide, sensitivity in REMA_GRID:
        params = RemaParams(alpha=alpha, slide_size=slide, sensitivity=sensitivity).checked()
        flags = np.concatenate([rema_batch(v, params).flag for v in values]).astype(bool)
        f1 = f1_score(truth, flags)
        if f1 > best_f1:
            best, best_f1 = params, f1
    return best, best_f1


def _sequences(
    table: Any,
    seeds: Sequence[int],
    features: FeatureParams,
    rema: Sequence[RemaParams],
    recipe: BaselineRecipe,
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    index = {name: i for i, name in enumerate(SENSOR_BIAS_CLASSES)}
    inputs = inputs_for("sensor-grid", recipe)
    out = []
    for seed in seeds:
        fixes, truth, labelled = labelled_fixes(table, "sensor-grid", seed, recipe=recipe)
        kinds = np.array([index[str(v)] for v in labelled["label_type"].to_numpy(object)])
        for seg in segments(fixes, inputs)[0]:
            feats = channel_features(seg, features, rema, inputs).astype(np.float32)
            out.append((feats, truth[seg.rows], kinds[seg.rows]))
    return out


def _tuned_rema(val: Any, recipe: BaselineRecipe) -> tuple[tuple[RemaParams, ...], list[float]]:
    """REMA per signal (:func:`rema_names`), tuned against the labels of the channels it sees."""
    inputs = inputs_for("sensor-grid", recipe)
    fixes, _, labelled = labelled_fixes(val, "sensor-grid", recipe.val_seed, recipe=recipe)
    segs = segments(fixes, inputs)[0]
    signals = [channel_signals(s, inputs) for s in segs]
    chosen, scores = [], []
    for name in rema_names(inputs):
        sources = [c for c in CROSS_SOURCES.get(name, (name,)) if c in _LABEL]
        if not sources:  # a clean reference channel (speed from the fixes)
            chosen.append(RemaParams())
            scores.append(0.0)
            continue
        column = np.zeros(len(labelled), np.int64)
        for c in sources:
            column |= labelled[_LABEL[c]].to_numpy(np.int64)
        values = [sig[name] for sig in signals]
        params, f1 = tune_channel_rema(values, [column[s.rows] for s in segs])
        chosen.append(params)
        scores.append(f1)
    return tuple(chosen), scores


def channel_grad_config(rec: BaselineRecipe) -> TrainConfig:
    """The channel GRAD's training settings under ``rec``: the paper's window (W =
    :data:`GRU_WINDOW`), the sensor-grid bias classes, early stopping on the validation
    F1 at the recall-floor threshold, and the recipe's loop settings (seed, budget,
    patience) shared with every baseline. Imports torch."""
    from .torch_gru import TrainConfig

    return TrainConfig(
        bias_classes=SENSOR_BIAS_CLASSES,
        mode="window",
        window=GRU_WINDOW,
        progress=False,
        early_stopping="floor-f1",
        normal_recall_floor=NORMAL_RECALL_FLOOR,
        **rec.loop_settings(),
    )


def dataset_channel_grad(
    dataset: str,
    data_dir: str | Path | None = None,
    recipe: BaselineRecipe | None = None,
    threshold: str = "floor",
) -> ChannelGradModel:
    """Channel GRAD trained on ``dataset`` under ``sensor-grid`` with ``recipe`` (cached).

    ``threshold="floor"``: GRAD's threshold (best validation F1 keeping
    validation normal recall >= :data:`NORMAL_RECALL_FLOOR`); ``"f1"``: the
    same model with the baselines' rule (best validation F1, no floor), for
    comparison (detector ``grad-f1``).
    """
    if threshold not in ("floor", "f1"):
        raise ConfigError(f"threshold must be 'floor' or 'f1', got {threshold!r}")
    rec = recipe or BaselineRecipe()
    features = FeatureParams(speed_heading=False)
    inputs = inputs_for("sensor-grid", rec)
    extra = {
        "features": asdict(features),
        "rema_grid": [list(g) for g in REMA_GRID],
        "recall_floor": NORMAL_RECALL_FLOOR,
        "design": "channel-grad-4b",
    }
    target = baseline_dir("channel-grad", dataset, "sensor-grid", rec, data_dir, extra)
    if not (target / "config.json").is_file():
        # torch only when training
        from .torch_gru import train_model

        train, val = splits(dataset, data_dir)
        rema, rema_f1 = _tuned_rema(val, rec)
        config = channel_grad_config(rec)
        val_seqs = _sequences(val, (rec.val_seed,), features, rema, rec)
        trained = train_model(_sequences(train, rec.seeds, features, rema, rec), val_seqs, config)
        mean = trained.network.scaler_mean.detach().numpy().astype(np.float64)
        std = trained.network.scaler_std.detach().numpy().astype(np.float64)
        gru = GRUModel(trained.weights(), mean, std, mode="window", window=GRU_WINDOW)
        probability = np.concatenate([gru.predict(f).anomaly for f, _, _ in val_seqs])
        truth = np.concatenate([y for _, y, _ in val_seqs]).astype(bool)
        floor_threshold = recall_floor_threshold(truth, probability)
        # The baselines' rule (best validation F1, no floor), kept for comparison (grad-f1).
        threshold_f1 = best_f1_threshold(truth, probability)
        target.mkdir(parents=True, exist_ok=True)
        np.savez(target / "weights.npz", allow_pickle=False, **trained.weights())
        cfg = {
            "threshold": floor_threshold,
            "threshold_f1": threshold_f1,
            "inputs": inputs,
            "mode": "window",
            "window": GRU_WINDOW,
            "rema": [asdict(p) for p in rema],
            "rema_val_f1": rema_f1,
            "scaler": {
                "mean": mean.tolist(),
                "std": std.tolist(),
            },
            "best_epoch": trained.best_epoch,
            "stop_reason": trained.stop_reason,
            "row": rec.row,
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
            mode=str(cfg["mode"]),
            window=int(cfg["window"]),
        )
        rema = tuple(replace(RemaParams(), **p).checked() for p in cfg["rema"])
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise ModelError(
            f"{target}: unusable channel-GRAD model ({exc}); delete it to retrain"
        ) from exc
    value = float(cfg["threshold" if threshold == "floor" else "threshold_f1"])
    if not 0.0 < value < 1.0:
        raise ConfigError(f"{target}: threshold {value} outside (0, 1)")
    return ChannelGradModel(gru, value, features, rema, str(cfg["inputs"]))
