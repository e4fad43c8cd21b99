"""GRAD for scalar sensor channels: what ``grad`` means under protocol ``sensor-grid``.

The paper's comparison table corrupts sensor readings (speed, acceleration,
yaw rate), not positions, so the position pipeline of :class:`gradgps.Detector`
has nothing to look at there. GRAD's statistical core works on any 1-D
channel, so the channel-wise GRAD is the same method on other inputs:

per channel (``speed``, ``accel_x_mps2``, ``gyro_z_dps``) REMA + the MS-SW
features of :mod:`gradgps._grad.features` (the 11 per-channel features, no
cross-channel cues) -> the three channels' features side by side -> the same
stacked GRU (32, 16) with an anomaly head and a bias-type head over the
sensor-grid classes ``none``, ``instant``, ``constant``, ``bias``, ``drift``,
trained by :func:`gradgps._train.torch_gru.train_model` (stream mode, early stopping
on validation F1, 3-minute budget, the same injection seeds as GRAD, the
``mixed`` row), threshold tuned on validation.

Where it differs from position GRAD: no offset tracker, time classifier or
recovery (the protocol scores detection and type only), REMA with its
paper defaults in channel units, and batch inference only (the benchmark
measures ``detect``; the position GRAD is the streaming product). A missing
reading is carried forward from the previous one (0 at a segment start).
The features use the numba kernel of the position features with the second
(north) channel fed zeros and dropped: the same code GRAD runs, at twice
the arithmetic it needs.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, ModelError
from .._grad.features import N_CHANNEL, FeatureParams, features_batch_kernel
from .._grad.gru import GRUModel
from .._grad.rema import RemaParams
from .base import Segment, result_frame, segments

__all__ = ["SENSOR_BIAS_CLASSES", "ChannelGradDetector", "channel_features", "dataset_channel_grad"]

SENSOR_BIAS_CLASSES = ("none", "instant", "constant", "bias", "drift")


def _filled(x: np.ndarray) -> np.ndarray:
    """Missing readings carried forward (0 before the first reading)."""
    s = pd.Series(x).ffill().fillna(0.0)
    return np.ascontiguousarray(s.to_numpy(np.float64))


def channel_features(segment: Segment, features: FeatureParams, rema: RemaParams) -> np.ndarray:
    """(n, 11 C) per-channel REMA + MS-SW features of one sensor segment."""
    n = len(segment.t)
    period = float(segment.t[1] - segment.t[0]) if n > 1 and segment.t[1] > segment.t[0] else 1.0
    long_n, short_n = features.points(period)
    zeros, nan = np.zeros(n), np.full(n, np.nan)
    parts = [
        features_batch_kernel(
            _filled(segment.values[:, k]),
            zeros,
            nan,
            nan,
            period,
            long_n,
            short_n,
            rema.to_array(),
            False,
        )[:, :N_CHANNEL]
        for k in range(segment.values.shape[1])
    ]
    return np.hstack(parts)


@dataclass(frozen=True)
class ChannelGradModel:
    gru: GRUModel
    threshold: float
    features: FeatureParams
    rema: RemaParams
    max_gap_s: float = 5.0


class ChannelGradDetector:
    """Batch channel-wise GRAD detector over fixes carrying the three sensor channels."""

    def __init__(self, model: ChannelGradModel) -> None:
        self.model = model

    def detect(self, fixes: pd.DataFrame) -> pd.DataFrame:
        m = self.model
        segs, reason = segments(fixes, "sensor", m.max_gap_s)
        n = len(fixes)
        score = np.full(n, np.nan)
        bias = np.full(n, None, dtype=object)
        names = np.array(SENSOR_BIAS_CLASSES, dtype=object)
        for seg in segs:
            pred, _ = m.gru.predict_stream(channel_features(seg, m.features, m.rema))
            score[seg.rows] = pred.anomaly
            bias[seg.rows] = names[np.argmax(pred.bias, axis=1)]
        anomaly = np.nan_to_num(score) >= m.threshold
        bias = np.where(anomaly, bias, "none")
        bias[reason != ""] = None
        return result_frame(
            fixes,
            reason,
            anomaly,
            score,
            fixes["lat"].to_numpy(np.float64),
            fixes["lon"].to_numpy(np.float64),
            bias,
        )


def _sequences(
    table: pd.DataFrame, seeds: Sequence[int], features: FeatureParams, rema: RemaParams
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    from .._train.baselines import labelled_fixes

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
    from .. import __version__
    from .._data.datasets import find_data_dir
    from .._train.baselines import BaselineRecipe, _splits

    rec = recipe or BaselineRecipe()
    features, rema = FeatureParams(speed_heading=False), RemaParams()
    key: dict[str, Any] = {
        "version": __version__,
        "recipe": asdict(rec),
        "dataset": dataset,
        "features": asdict(features),
        "rema": asdict(rema),
    }
    if dataset != "simulated":
        key["files"] = sorted(
            (p.name, p.stat().st_size) for p in find_data_dir(data_dir).glob("*.csv")
        )
    digest = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:16]
    cache = Path(os.environ.get("GRADGPS_CACHE", Path.home() / ".cache" / "gradgps"))
    target = cache / "baselines" / f"channel-grad-{dataset}-{digest}"
    if not (target / "config.json").is_file():
        from .._train.torch_gru import TrainConfig, train_model

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
