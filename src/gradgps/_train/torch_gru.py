"""Training the GRAD network in PyTorch (paper sections 4.5 and 5.3).

Only training code and tests import this module (it imports torch; the
``train`` extra). Inference is :mod:`gradgps._grad.gru`, which never needs torch:
:func:`gradgps._grad.model_io.export_torch` turns the trained module into plain
arrays.

The input is generic: a list of per-segment ``(features (n, F) float32,
anomaly (n,) int 0/1, bias (n,) int 0..K-1)`` tuples, whatever features the
extractor produced and whatever bias classes the labelling protocol uses.

Two feeding modes, matching inference exactly:

* ``window`` (the paper's feed sliding window): one sample per point, the
  last W points ending at it, run from a zero state; only the last step is a
  target. The first W-1 points of a segment are targets of the segment's
  first window (whose step ``t`` has seen exactly the points ``0..t``, as at
  inference), so every point is a target exactly once.
* ``stream``: truncated backpropagation through time. Segments are cut into
  pieces of at most ``stream_piece_length`` points, the pieces are laid end
  to end in ``batch_size`` lanes, and each optimiser step processes one
  ``chunk_length`` chunk of every lane, carrying (detached) hidden states
  from chunk to chunk and resetting them to zero where a new piece starts.

Determinism: everything random comes from ``seed`` (torch generator and
NumPy ``default_rng``), torch runs on one CPU thread with deterministic
algorithms, so the same data, config and seed give bit-identical weights --
unless the time budget cuts training short at a different point.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np
import torch
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from torch import nn

from .._exceptions import ConfigError
from .._grad.gru import MODES
from .._grad.model_io import export_torch, torch_state
from .._result import f1_score
from .labels import IGNORE_LABEL
from .thresholds import best_f1_threshold, recall_floor_threshold

__all__ = [
    "EpochMetrics",
    "GRADNet",
    "NetOutput",
    "TrainConfig",
    "TrainedModel",
    "merge_networks",
    "network_from_arrays",
    "train_ensemble",
    "train_model",
]

LabelledSequence = tuple[np.ndarray, np.ndarray, np.ndarray]
_IGNORE = IGNORE_LABEL  # torch's CrossEntropyLoss ignore_index: padding, non-target, unknowable


@dataclass
class TrainConfig:
    """Everything that decides a training run (all plain values, JSON-able)."""

    bias_classes: tuple[str, ...] = ("none", "noise", "jump")
    mode: str = "window"
    window: int = 10
    chunk_length: int = 200
    stream_piece_length: int = 1000
    hidden1: int = 32
    hidden2: int = 16
    batch_size: int = 256  # windows per step (window mode) or TBPTT lanes (stream mode)
    learning_rate: float = 3e-3
    lr_schedule: str = "constant"  # or "cosine": decays to 1/20 of it over max_epochs
    grad_clip: float = 0.0  # clip the gradient norm to this (0: no clipping)
    normal_recall_floor: float = 0.0  # > 0: best validation F1 keeping normal recall >= it
    max_epochs: int = 100
    patience: int = 6
    # "loss" (validation loss), "f1" (validation anomaly F1 at 0.5) or "floor-f1" (validation
    # anomaly F1 at the threshold normal_recall_floor picks: the model is chosen by the rule
    # it will be thresholded with)
    early_stopping: str = "loss"
    time_budget_s: float = 180.0
    max_samples_per_epoch: int = 100_000  # window mode: windows drawn per epoch
    bias_loss_weight: float = 1.0
    max_class_weight: float = 50.0
    seed: int = 0
    progress: bool = True
    #: Train a second anomaly head that judges the previous step (:class:`GRADNet`); stream mode.
    confirm_head: bool = False

    def validate(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        if self.confirm_head and self.mode != "stream":
            raise ConfigError("confirm_head needs mode 'stream' (it judges the previous step)")
        if self.lr_schedule not in ("constant", "cosine"):
            raise ConfigError(
                f"lr_schedule must be 'constant' or 'cosine', got {self.lr_schedule!r}"
            )
        if not (0.0 <= self.normal_recall_floor < 1.0):
            raise ConfigError(
                f"normal_recall_floor must be in [0, 1), got {self.normal_recall_floor!r}"
            )
        if not (math.isfinite(self.grad_clip) and self.grad_clip >= 0):
            raise ConfigError(f"grad_clip must be >= 0, got {self.grad_clip!r}")
        if self.early_stopping not in ("loss", "f1", "floor-f1"):
            raise ConfigError(
                f"early_stopping must be 'loss', 'f1' or 'floor-f1', got {self.early_stopping!r}"
            )
        if self.early_stopping == "floor-f1" and self.normal_recall_floor <= 0:
            raise ConfigError("early_stopping 'floor-f1' needs a normal_recall_floor > 0")
        if len(self.bias_classes) < 2:
            raise ConfigError("bias_classes needs 'none' plus at least one fault type")
        for name in (
            "window",
            "chunk_length",
            "stream_piece_length",
            "hidden1",
            "hidden2",
            "batch_size",
            "max_epochs",
            "patience",
            "max_samples_per_epoch",
        ):
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not (
            self.learning_rate > 0
            and self.time_budget_s > 0
            and self.max_class_weight >= 1
            and self.bias_loss_weight >= 0
        ):
            raise ConfigError(
                "learning_rate and time_budget_s must be > 0, max_class_weight >= 1, "
                "bias_loss_weight >= 0"
            )


class NetOutput(NamedTuple):
    """One run of :class:`GRADNet`: per-step logits of each head and the final states."""

    anomaly: torch.Tensor  # (B, T, 2): the fix just read
    bias: torch.Tensor  # (B, T, K)
    confirm: torch.Tensor | None  # (B, T, 2): the fix before it; None without the head
    state: tuple[torch.Tensor, torch.Tensor]


class GRADNet(nn.Module):
    """Scaler -> GRU(hidden1) -> GRU(hidden2) -> per-step anomaly (2) and bias-type (K) logits,
    and with ``confirm_head`` a second anomaly head (2) that judges the *previous* step.

    The scaler is two buffers (``scaler_mean``, ``scaler_std``) so it travels
    with the module; non-finite scaled inputs become 0, as in inference.

    Why a confirm head: from positions alone the first fix after a fault
    ends and a fix that starts a new one read alike until the next fix shows
    where the track goes (on the validation drives most false alarms sit 1-3
    fixes after a fault's end). The confirm head has seen that next fix; the
    anomaly head still answers at once. It is made after the other layers, so
    a seed starts every other weight as a network without it does.
    """

    scaler_mean: torch.Tensor
    scaler_std: torch.Tensor

    def __init__(
        self,
        n_features: int,
        n_bias_classes: int,
        hidden1: int = 32,
        hidden2: int = 16,
        *,
        confirm_head: bool = False,
    ) -> None:
        super().__init__()
        self.register_buffer("scaler_mean", torch.zeros(n_features))
        self.register_buffer("scaler_std", torch.ones(n_features))
        self.gru1 = nn.GRU(n_features, hidden1, batch_first=True)
        self.gru2 = nn.GRU(hidden1, hidden2, batch_first=True)
        self.anomaly_head = nn.Linear(hidden2, 2)
        self.bias_head = nn.Linear(hidden2, n_bias_classes)
        self.confirm_head = nn.Linear(hidden2, 2) if confirm_head else None

    def run(
        self,
        x: torch.Tensor,
        state: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> NetOutput:
        """``x`` (B, T, F) raw features -> every head's logits and the final states."""
        scaled = (x - self.scaler_mean) / self.scaler_std
        scaled = torch.where(torch.isfinite(scaled), scaled, torch.zeros_like(scaled))
        h1, h2 = (None, None) if state is None else state
        out1, h1_n = self.gru1(scaled, h1)
        out2, h2_n = self.gru2(out1, h2)
        confirm = None if self.confirm_head is None else self.confirm_head(out2)
        return NetOutput(self.anomaly_head(out2), self.bias_head(out2), confirm, (h1_n, h2_n))

    def forward(
        self,
        x: torch.Tensor,
        state: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """``x`` (B, T, F) raw features -> anomaly logits (B, T, 2), bias logits (B, T, K), final states."""
        out = self.run(x, state)
        return out.anomaly, out.bias, out.state


@dataclass
class EpochMetrics:
    """One epoch: mean training loss, validation loss and anomaly F1 (threshold 0.5), bias accuracy
    on true anomalies, wall seconds since training started."""

    epoch: int
    train_loss: float
    val_loss: float
    val_f1: float
    val_bias_accuracy: float
    seconds: float


@dataclass
class TrainedModel:
    """A trained network (best validation epoch) plus what is needed to deploy it."""

    network: GRADNet
    config: TrainConfig
    n_features: int
    anomaly_threshold: float
    best_epoch: int
    stop_reason: str
    history: list[EpochMetrics] = field(default_factory=list)
    #: An ensemble's members (:func:`train_ensemble`), each as trained; empty for one network.
    members: tuple[TrainedModel, ...] = ()
    #: The confirm head's threshold (picked as the anomaly head's, against the previous
    #: step's labels); None without the head.
    confirm_threshold: float | None = None

    def weights(self) -> dict[str, np.ndarray]:
        """Network weights as float32 arrays named as in :data:`gradgps._grad.gru.WEIGHT_NAMES`."""
        return export_torch(self.network)

    def model_config(
        self,
        feature_names: Sequence[str],
        feature_params: dict[str, Any],
        rema_params: dict[str, Any],
    ) -> dict[str, Any]:
        """The ``config.json`` content for :func:`gradgps._grad.model_io.save_model`.

        ``feature_params`` and ``rema_params`` are opaque here: whatever the
        feature extractor and REMA need to reproduce the training features.
        """
        if len(feature_names) != self.n_features:
            raise ConfigError(
                f"{len(feature_names)} feature names for a model with {self.n_features} features"
            )
        cfg = self.config
        architecture: dict[str, Any] = {
            "n_features": self.n_features,
            "hidden1": self.network.gru1.hidden_size,
            "hidden2": self.network.gru2.hidden_size,
            "n_bias_classes": len(cfg.bias_classes),
        }
        thresholds: dict[str, float] = {"anomaly": self.anomaly_threshold}
        if self.network.confirm_head is not None:
            if self.confirm_threshold is None:
                raise ConfigError("a network with a confirm head needs its confirm_threshold")
            architecture["confirm_head"] = True
            thresholds["confirm"] = self.confirm_threshold
        out: dict[str, Any] = {
            "architecture": architecture,
            "mode": cfg.mode,
            "window": cfg.window,
            "features": {"names": list(feature_names), "params": dict(feature_params)},
            "scaler": {
                "mean": self.network.scaler_mean.tolist(),
                "std": self.network.scaler_std.tolist(),
            },
            "thresholds": thresholds,
            "rema": dict(rema_params),
            "class_names": {"anomaly": ["normal", "anomaly"], "bias": list(cfg.bias_classes)},
            "training": {
                "best_epoch": self.best_epoch,
                "stop_reason": self.stop_reason,
                "config": {**asdict(cfg), "bias_classes": list(cfg.bias_classes)},
                "history": _history(self.history),
            },
        }
        if self.members:
            # The merged network's own record is its members': seed, best epoch and
            # threshold of each, as trained (the top-level ones are the first's).
            out["training"]["members"] = [
                {
                    "seed": m.config.seed,
                    "best_epoch": m.best_epoch,
                    "stop_reason": m.stop_reason,
                    "anomaly_threshold": m.anomaly_threshold,
                    **(
                        {"confirm_threshold": m.confirm_threshold}
                        if m.confirm_threshold is not None
                        else {}
                    ),
                    "history": _history(m.history),
                }
                for m in self.members
            ]
        return out


def _history(history: Sequence[EpochMetrics]) -> list[dict[str, Any]]:
    return [
        {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in vars(m).items()}
        for m in history
    ]


# ----------------------------------------------------------------------------
# Data layout: every sequence right-padded (zeros, label _IGNORE) and laid end
# to end in one array, so batches are fancy-indexed gathers, no Python loops.
# ----------------------------------------------------------------------------


@dataclass
class _Packed:
    features: np.ndarray  # (N, F) float32
    anomaly: np.ndarray  # (N,) int64, _IGNORE on padding
    bias: np.ndarray  # (N,) int64
    starts: np.ndarray  # (S,) offset of each sequence
    lengths: np.ndarray  # (S,) real length of each sequence
    #: (N,) int64: the anomaly label of the step before, in the same sequence (the confirm
    #: head's target); _IGNORE at a sequence's first step and on padding.
    previous: np.ndarray


def _check_sequences(sequences: Sequence[LabelledSequence], n_bias: int, what: str) -> int:
    if len(sequences) == 0:
        raise ConfigError(f"{what}: no sequences given")
    n_features = -1
    for i, seq in enumerate(sequences):
        if len(seq) != 3:
            raise ConfigError(
                f"{what}[{i}]: expected (features, anomaly, bias), got {len(seq)} items"
            )
        features, anomaly, bias = (np.asarray(a) for a in seq)
        if features.ndim != 2 or features.shape[0] == 0:
            raise ConfigError(
                f"{what}[{i}]: features must be a non-empty (n, F) array, got shape {features.shape}"
            )
        if n_features < 0:
            n_features = features.shape[1]
        if features.shape[1] != n_features:
            raise ConfigError(
                f"{what}[{i}]: {features.shape[1]} features, sequence 0 has {n_features}"
            )
        if anomaly.shape != (len(features),) or bias.shape != (len(features),):
            raise ConfigError(
                f"{what}[{i}]: need one anomaly and one bias label per row "
                f"({len(features)}), got {anomaly.shape} and {bias.shape}"
            )
        if not np.isin(anomaly, (0, 1, _IGNORE)).all():
            raise ConfigError(f"{what}[{i}]: anomaly labels must be 0, 1 or {_IGNORE} (ignored)")
        counted = bias[bias != _IGNORE]
        if counted.size and (counted.min() < 0 or counted.max() >= n_bias):
            raise ConfigError(
                f"{what}[{i}]: bias labels must be in 0..{n_bias - 1} (one per bias class)"
            )
    return n_features


def _pack(sequences: Sequence[LabelledSequence], min_length: int, multiple: int) -> _Packed:
    """Lay sequences end to end, each padded to >= ``min_length`` and a multiple of ``multiple``."""
    lengths = np.array([len(s[0]) for s in sequences], np.int64)
    padded = np.maximum(lengths, min_length)
    padded = -(-padded // multiple) * multiple
    starts = np.concatenate([[0], np.cumsum(padded)[:-1]]).astype(np.int64)
    total = int(padded.sum())
    n_features = np.asarray(sequences[0][0]).shape[1]
    features = np.zeros((total, n_features), np.float32)
    anomaly = np.full(total, _IGNORE, np.int64)
    bias = np.full(total, _IGNORE, np.int64)
    previous = np.full(total, _IGNORE, np.int64)
    for (f, a, b), s, n in zip(sequences, starts, lengths, strict=True):
        features[s : s + n] = f
        anomaly[s : s + n] = a
        bias[s : s + n] = b
        previous[s + 1 : s + n] = a[:-1]
    return _Packed(features, anomaly, bias, starts, lengths, previous)


def _window_samples(packed: _Packed, window: int) -> tuple[np.ndarray, np.ndarray]:
    """``(start offsets, is_first)`` of every window; the first window of a sequence targets all its steps."""
    starts, first = [], []
    for s, n in zip(packed.starts, packed.lengths, strict=True):
        count = max(int(n) - window + 1, 1)
        starts.append(s + np.arange(count))
        first.append(np.arange(count) == 0)
    return np.concatenate(starts), np.concatenate(first)


def _window_batch(
    packed: _Packed,
    starts: np.ndarray,
    first: np.ndarray,
    window: int,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    idx = starts[:, None] + np.arange(window)
    target = first[:, None] | (np.arange(window) == window - 1)
    anomaly = np.where(target, packed.anomaly[idx], _IGNORE)
    bias = np.where(target, packed.bias[idx], _IGNORE)
    return torch.from_numpy(packed.features[idx]), torch.from_numpy(anomaly), torch.from_numpy(bias)


def _stream_lanes(
    packed: _Packed,
    n_lanes: int,
    chunk: int,
    piece_points: int,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Chunk start offsets (lanes, steps) and reset flags; pieces shuffled, lanes balanced greedily.

    Sequences are packed padded to a multiple of ``chunk``; a piece is a run of
    whole chunks. Empty slots point at chunk 0 with reset=True and are fully
    ignored via :func:`_chunk_labels` (``valid=False``).
    """
    pieces: list[np.ndarray] = []  # chunk offsets of each piece
    for s, n in zip(packed.starts, packed.lengths, strict=True):
        chunks = s + chunk * np.arange(-(-int(n) // chunk))
        pieces += np.array_split(chunks, max(1, math.ceil(len(chunks) * chunk / piece_points)))
    order = rng.permutation(len(pieces))
    n_lanes = min(n_lanes, len(pieces))
    lanes: list[list[tuple[int, bool]]] = [[] for _ in range(n_lanes)]
    for p in order:
        shortest = min(range(n_lanes), key=lambda k: len(lanes[k]))
        lanes[shortest] += [(int(c), j == 0) for j, c in enumerate(pieces[p])]
    steps = max(len(lane) for lane in lanes)
    offsets = np.full((n_lanes, steps), -1, np.int64)
    resets = np.ones((n_lanes, steps), bool)
    for k, lane in enumerate(lanes):
        offsets[k, : len(lane)] = [c for c, _ in lane]
        resets[k, : len(lane)] = [r for _, r in lane]
    return offsets, resets


def _fit_scaler(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and std over the finite values (float32).

    A feature with no finite value gets mean 0; a (near) constant one gets
    std 1, so scaling never divides by zero and such a feature scales to ~0.
    """
    finite = np.isfinite(features)
    count = np.maximum(finite.sum(axis=0), 1)
    values = np.where(finite, features, 0.0).astype(np.float64)
    mean = values.sum(axis=0) / count
    std = np.sqrt((np.where(finite, values - mean, 0.0) ** 2).sum(axis=0) / count)
    std[std < 1e-6 * np.maximum(1.0, np.abs(mean))] = 1.0
    return mean.astype(np.float32), std.astype(np.float32)


def _class_weights(labels: np.ndarray, n_classes: int, cap: float) -> torch.Tensor:
    """Inverse-frequency ("balanced") weights, capped; classes absent from training get 1."""
    labels = labels[labels != _IGNORE]
    counts = np.bincount(labels, minlength=n_classes).astype(np.float64)
    weights = np.ones(n_classes)
    present = counts > 0
    balanced = labels.size / (present.sum() * counts[present])
    weights[present] = np.clip(balanced / balanced.min(), 1.0, cap)  # most frequent class: 1
    return torch.tensor(weights, dtype=torch.float32)


class _Loss:
    def __init__(
        self, anomaly_weights: torch.Tensor, bias_weights: torch.Tensor, bias_factor: float
    ) -> None:
        self.anomaly = nn.CrossEntropyLoss(weight=anomaly_weights, ignore_index=_IGNORE)
        self.bias = nn.CrossEntropyLoss(weight=bias_weights, ignore_index=_IGNORE)
        self.bias_factor = bias_factor

    def __call__(
        self,
        anomaly_logits: torch.Tensor,
        bias_logits: torch.Tensor,
        anomaly: torch.Tensor,
        bias: torch.Tensor,
        confirm_logits: torch.Tensor | None = None,
        previous: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Anomaly plus weighted bias-type cross-entropy; with a confirm head, plus its
        cross-entropy against ``previous`` (the step before's labels, the anomaly weights)."""
        loss: torch.Tensor = self.anomaly(anomaly_logits.reshape(-1, 2), anomaly.reshape(-1))
        bias_loss: torch.Tensor = self.bias(
            bias_logits.reshape(-1, bias_logits.shape[-1]), bias.reshape(-1)
        )
        loss = loss + self.bias_factor * bias_loss
        if confirm_logits is not None and previous is not None:
            loss = loss + self.anomaly(confirm_logits.reshape(-1, 2), previous.reshape(-1))
        return loss


@dataclass
class _Predicted:
    """A network's logits on every scored point of a packed set, labels alongside.

    ``confirm``/``previous``: the confirm head's logits on the points whose previous
    step has a label, and those labels (None, empty without the head).
    """

    anomaly: torch.Tensor
    bias: torch.Tensor
    a_true: np.ndarray
    b_true: np.ndarray
    confirm: torch.Tensor | None
    previous: np.ndarray


def _predict_packed(net: GRADNet, packed: _Packed, config: TrainConfig) -> _Predicted:
    """Logits for every real point of ``packed`` fed the config's way; labels alongside."""
    with torch.no_grad():
        if config.mode == "window":
            starts, first = _window_samples(packed, config.window)
            a_logits, b_logits, a_labels, b_labels = [], [], [], []
            for lo in range(0, len(starts), 4096):
                x, a, b = _window_batch(
                    packed, starts[lo : lo + 4096], first[lo : lo + 4096], config.window
                )
                la, lb, _ = net(x)
                keep = a != _IGNORE
                a_logits.append(la[keep])
                b_logits.append(lb[keep])
                a_labels.append(a[keep].numpy())
                b_labels.append(b[keep].numpy())
            return _Predicted(
                torch.cat(a_logits),
                torch.cat(b_logits),
                np.concatenate(a_labels),
                np.concatenate(b_labels),
                None,  # window mode has no confirm head (TrainConfig.validate)
                np.empty(0, np.int64),
            )
        # Whole sequences from zero state, in groups of similar length so
        # right-padding (harmless: the GRU is causal) wastes little memory.
        order = np.argsort(packed.lengths, kind="stable")
        parts: list[tuple[torch.Tensor, torch.Tensor, np.ndarray, np.ndarray]] = []
        confirm: list[tuple[torch.Tensor, np.ndarray]] = []
        for lo in range(0, len(order), 64):
            group = order[lo : lo + 64]
            longest = int(packed.lengths[group].max())
            idx = np.minimum(
                packed.starts[group, None] + np.arange(longest), len(packed.features) - 1
            )
            # Real points with a label to score: not padding, not an ignored (unknowable)
            # point, which the window branch above drops the same way.
            valid = (np.arange(longest) < packed.lengths[group, None]) & (
                packed.anomaly[idx] != _IGNORE
            )
            out = net.run(torch.from_numpy(packed.features[idx]))
            keep = torch.from_numpy(valid)
            parts.append(
                (
                    out.anomaly[keep],
                    out.bias[keep],
                    packed.anomaly[idx][valid],
                    packed.bias[idx][valid],
                )
            )
            if out.confirm is not None:
                real = np.arange(longest) < packed.lengths[group, None]
                judged = real & (packed.previous[idx] != _IGNORE)
                confirm.append(
                    (out.confirm[torch.from_numpy(judged)], packed.previous[idx][judged])
                )
        return _Predicted(
            torch.cat([p[0] for p in parts]),
            torch.cat([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]),
            np.concatenate([p[3] for p in parts]),
            torch.cat([c[0] for c in confirm]) if confirm else None,
            np.concatenate([c[1] for c in confirm]) if confirm else np.empty(0, np.int64),
        )


def train_model(
    sequences: Sequence[LabelledSequence],
    val_sequences: Sequence[LabelledSequence],
    config: TrainConfig | None = None,
    *,
    console: Console | None = None,
) -> TrainedModel:
    """Train the GRAD network on labelled feature sequences; early-stop on the validation set.

    Returns the weights of the best validation epoch, with the anomaly
    threshold tuned for validation F1. Training stops at ``max_epochs``,
    after ``patience`` epochs without improvement, or when ``time_budget_s``
    is spent (checked after every optimiser step).
    """
    config = TrainConfig() if config is None else config
    config.validate()
    n_bias = len(config.bias_classes)
    n_features = _check_sequences(sequences, n_bias, "sequences")
    if _check_sequences(val_sequences, n_bias, "val_sequences") != n_features:
        raise ConfigError("val_sequences have a different number of features than sequences")

    threads, deterministic = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(1)
    torch.use_deterministic_algorithms(True)
    try:
        return _train(sequences, val_sequences, config, n_features, console)
    finally:
        torch.set_num_threads(threads)
        torch.use_deterministic_algorithms(deterministic)


#: ``(anomaly logits, bias logits, anomaly labels, bias labels, confirm logits, previous
#: labels)``; the last two None without a confirm head.
_Batch = tuple[
    torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor | None, torch.Tensor | None
]


def _window_batches(
    net: GRADNet,
    train: _Packed,
    config: TrainConfig,
    rng: np.random.Generator,
    all_starts: np.ndarray,
    all_first: np.ndarray,
) -> Iterator[_Batch]:
    """One epoch of window mode: per batch of random windows, the network's anomaly and
    bias logits and the labels (:data:`_Batch`; window mode has no confirm head)."""
    pick = rng.permutation(len(all_starts))[: config.max_samples_per_epoch]
    for lo in range(0, len(pick), config.batch_size):
        chosen = pick[lo : lo + config.batch_size]
        x, a, b = _window_batch(train, all_starts[chosen], all_first[chosen], config.window)
        la, lb, _ = net(x)
        yield la, lb, a, b, None, None


def _stream_batches(
    net: GRADNet, train: _Packed, config: TrainConfig, rng: np.random.Generator
) -> Iterator[_Batch]:
    """One epoch of stream mode: per chunk of every lane, a :data:`_Batch`, the hidden
    state carried (detached) from the lane's previous chunk and reset where a lane starts
    a new piece (where the confirm head has not seen the step before: not scored). The
    caller steps the optimiser before asking for the next chunk."""
    offsets, resets = _stream_lanes(
        train, config.batch_size, config.chunk_length, config.stream_piece_length, rng
    )
    state: tuple[torch.Tensor, torch.Tensor] | None = None
    for step in range(offsets.shape[1]):
        idx = np.maximum(offsets[:, step], 0)[:, None] + np.arange(config.chunk_length)
        valid = (offsets[:, step] >= 0)[:, None]
        a = torch.from_numpy(np.where(valid, train.anomaly[idx], _IGNORE))
        b = torch.from_numpy(np.where(valid, train.bias[idx], _IGNORE))
        if state is not None:
            keep = torch.from_numpy(~resets[:, step]).to(torch.float32)[None, :, None]
            state = (state[0].detach() * keep, state[1].detach() * keep)
        out = net.run(torch.from_numpy(train.features[idx]), state)
        state = out.state
        previous = None
        if out.confirm is not None:
            labels = np.where(valid, train.previous[idx], _IGNORE)
            labels[resets[:, step], 0] = _IGNORE
            previous = torch.from_numpy(labels)
        yield out.anomaly, out.bias, a, b, out.confirm, previous


def _train(
    sequences: Sequence[LabelledSequence],
    val_sequences: Sequence[LabelledSequence],
    config: TrainConfig,
    n_features: int,
    console: Console | None,
) -> TrainedModel:
    n_bias = len(config.bias_classes)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    began = time.perf_counter()

    is_window = config.mode == "window"
    train = _pack(
        sequences, config.window if is_window else 1, 1 if is_window else config.chunk_length
    )
    val = _pack(val_sequences, config.window if is_window else 1, 1)

    net = GRADNet(
        n_features, n_bias, config.hidden1, config.hidden2, confirm_head=config.confirm_head
    )
    mean, std = _fit_scaler(train.features[train.anomaly != _IGNORE])
    net.scaler_mean.copy_(torch.from_numpy(mean))
    net.scaler_std.copy_(torch.from_numpy(std))

    loss_fn = _Loss(
        _class_weights(train.anomaly, 2, config.max_class_weight),
        _class_weights(train.bias, n_bias, config.max_class_weight),
        config.bias_loss_weight,
    )
    optimizer = torch.optim.Adam(net.parameters(), lr=config.learning_rate)

    if is_window:
        all_starts, all_first = _window_samples(train, config.window)
        steps_per_epoch = math.ceil(
            min(len(all_starts), config.max_samples_per_epoch) / config.batch_size
        )
    else:
        steps_per_epoch = _stream_lanes(
            train,
            config.batch_size,
            config.chunk_length,
            config.stream_piece_length,
            np.random.default_rng(0),
        )[0].shape[1]

    history: list[EpochMetrics] = []
    best = _BestEpoch(net, config.patience)
    out_of_time = False
    progress = Progress(
        TextColumn("[bold]training GRU[/]"),
        BarColumn(),
        TextColumn("{task.description}"),
        TimeElapsedColumn(),
        console=console,
        disable=not config.progress,
        transient=False,
    )
    with progress:
        task = progress.add_task("epoch 1", total=config.max_epochs * steps_per_epoch)
        for epoch in range(1, config.max_epochs + 1):
            net.train()
            if config.lr_schedule == "cosine":
                # Small noisy batches: a decaying rate lets the last epochs settle
                # instead of jittering around the minimum (validation F1 swung by
                # 0.1 between epochs at a constant rate).
                share = (epoch - 1) / max(config.max_epochs - 1, 1)
                factor = 0.05 + 0.95 * 0.5 * (1.0 + math.cos(math.pi * share))
                for group in optimizer.param_groups:
                    group["lr"] = config.learning_rate * factor
            losses: list[float] = []
            batches = (
                _window_batches(net, train, config, rng, all_starts, all_first)
                if is_window
                else _stream_batches(net, train, config, rng)
            )
            for batch in batches:
                losses.append(_optimise(optimizer, loss_fn(*batch), net, config.grad_clip))
                progress.advance(task)
                if time.perf_counter() - began > config.time_budget_s:
                    out_of_time = True
                    break

            net.eval()
            pred = _predict_packed(net, val, config)
            la, lb, a_true, b_true = pred.anomaly, pred.bias, pred.a_true, pred.b_true
            val_loss = float(
                loss_fn(
                    la,
                    lb,
                    torch.from_numpy(a_true),
                    torch.from_numpy(b_true),
                    pred.confirm,
                    torch.from_numpy(pred.previous),
                )
            )
            p_anomaly = torch.softmax(la, -1)[:, 1].numpy()
            cut = (
                recall_floor_threshold(a_true == 1, p_anomaly, config.normal_recall_floor)
                if config.early_stopping == "floor-f1"
                else 0.5
            )
            val_f1 = f1_score(a_true == 1, p_anomaly >= cut)
            on_anomaly = a_true == 1
            bias_acc = (
                float(np.mean(lb.argmax(-1).numpy()[on_anomaly] == b_true[on_anomaly]))
                if on_anomaly.any()
                else math.nan
            )
            metrics = EpochMetrics(
                epoch,
                float(np.mean(losses)) if losses else math.nan,
                val_loss,
                val_f1,
                bias_acc,
                time.perf_counter() - began,
            )
            history.append(metrics)
            progress.update(
                task, description=f"epoch {epoch} val loss {val_loss:.4f} F1 {val_f1:.3f}"
            )
            if config.progress:
                progress.console.print(
                    f"epoch {epoch:3d}  train loss {metrics.train_loss:.4f}  val loss {val_loss:.4f}  "
                    f"val F1 {val_f1:.4f}  bias acc {bias_acc:.3f}  {metrics.seconds:6.1f}s"
                )
            score = val_loss if config.early_stopping == "loss" else -val_f1
            if best.stop(epoch, score, out_of_time):
                break

    best.restore()
    net.eval()
    pred = _predict_packed(net, val, config)
    threshold = _pick_threshold(pred.a_true, pred.anomaly, config)
    confirm_threshold = (
        None if pred.confirm is None else _pick_threshold(pred.previous, pred.confirm, config)
    )
    return TrainedModel(
        net,
        config,
        n_features,
        threshold,
        best.epoch,
        best.stop_reason,
        history,
        confirm_threshold=confirm_threshold,
    )


def _pick_threshold(truth: np.ndarray, logits: torch.Tensor, config: TrainConfig) -> float:
    """The config's rule on validation: best F1 keeping normal recall >= the floor, or best F1."""
    probability = torch.softmax(logits, -1)[:, 1].numpy()
    if config.normal_recall_floor > 0:
        return recall_floor_threshold(truth == 1, probability, config.normal_recall_floor)
    return best_f1_threshold(truth == 1, probability)


def _train_members(
    sequences: Sequence[LabelledSequence],
    val_sequences: Sequence[LabelledSequence],
    configs: Sequence[TrainConfig],
    jobs: int,
) -> list[TrainedModel]:
    """The members, ``jobs`` at a time in worker processes (one thread each), in order.

    Workers are spawned, not forked: a fork of a process whose torch thread
    pool has started can hang in the child. Each worker receives the
    sequences once per member it trains (pickled), so memory grows by a copy of
    the training set per job.
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    quiet = [replace(c, progress=False) for c in configs]
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        futures = [pool.submit(train_model, sequences, val_sequences, c) for c in quiet]
        with Progress(
            TextColumn("members"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total}"),
            TimeElapsedColumn(),
            disable=not configs[0].progress,
        ) as progress:
            task = progress.add_task("members", total=len(futures))
            trained = []
            for future in futures:
                trained.append(future.result())
                progress.advance(task)
    # The members report the caller's progress setting, as trained one by one.
    return [replace(m, config=c) for m, c in zip(trained, configs, strict=True)]


def train_ensemble(
    sequences: Sequence[LabelledSequence],
    val_sequences: Sequence[LabelledSequence],
    config: TrainConfig,
    members: int,
    *,
    jobs: int = 1,
) -> TrainedModel:
    """``members`` networks trained as :func:`train_model` trains one, with seeds
    ``config.seed``, ``config.seed + 1``, ..., merged by :func:`merge_networks` into one
    network whose threshold is the mean of the members' (each picked on validation by
    the members' rule).

    Why: networks trained on the same data with different seeds disagree most
    where the data say least (a fix just after a fault ends, a hard stop at
    0.5 Hz), and which seed is shipped moved a validation drive's F1 by up to
    0.045 and its clean false alarms from 0.24 to 0.91 %. The mean of a few members' logits
    keeps what they agree on. Each member is exactly the network
    ``train_model`` returns for its seed, so an ensemble's members can be
    checked one by one.

    ``jobs`` > 1 trains that many members at a time, each in its own process on
    one thread: the same networks, bit for bit (each member's randomness comes
    from its seed alone), in about ``1 / jobs`` of the time on as many cores.
    """
    if members < 1:
        raise ConfigError(f"members must be at least 1, got {members}")
    if jobs < 1:
        raise ConfigError(f"jobs must be at least 1, got {jobs}")
    configs = [replace(config, seed=config.seed + k) for k in range(members)]
    if jobs > 1 and members > 1:
        trained = _train_members(sequences, val_sequences, configs, min(jobs, members))
    else:
        trained = [train_model(sequences, val_sequences, c) for c in configs]
    if members == 1:
        return trained[0]
    merged = merge_networks([m.network for m in trained])
    first = trained[0]
    # The members' mean threshold, not one picked afresh: on the validation drives
    # the recall-floor rule re-run on the merged network chose 0.83 (members 0.864,
    # 0.870) and doubled the clean false alarms on the Austin logger (0.24 -> 0.55 %)
    # for F1 the mean threshold also reached (docs/model-card.md).
    threshold = float(np.mean([m.anomaly_threshold for m in trained]))
    confirm = [m.confirm_threshold for m in trained if m.confirm_threshold is not None]
    return TrainedModel(
        merged,
        config,
        first.n_features,
        threshold,
        first.best_epoch,
        first.stop_reason,
        first.history,
        members=tuple(trained),
        confirm_threshold=float(np.mean(confirm)) if confirm else None,
    )


def merge_networks(nets: Sequence[GRADNet]) -> GRADNet:
    """One :class:`GRADNet` whose logits are the mean of ``nets``' logits, exactly.

    The members' GRUs run side by side in one wider GRU: each gate's rows are
    the members' rows one after the other, the recurrent weights (and the
    second layer's input weights) are block-diagonal, so a member's units see
    only the shared features and its own units; the heads read all units with
    the members' weights divided by their number. A GRU's gates act unit by
    unit, so nothing mixes, and the detector, its numba kernel, the ONNX
    export and the state files run the result as any other network. The
    members must share the scaler (the same training data gives the same one).
    """
    if not nets:
        raise ConfigError("merge_networks needs at least one network")
    first = nets[0]
    shape = (first.gru1.input_size, first.gru1.hidden_size, first.gru2.hidden_size)
    n_bias = first.bias_head.out_features
    confirm = first.confirm_head is not None
    for net in nets[1:]:
        if (
            (net.gru1.input_size, net.gru1.hidden_size, net.gru2.hidden_size) != shape
            or net.bias_head.out_features != n_bias
            or (net.confirm_head is not None) != confirm
        ):
            raise ConfigError("networks to merge must have the same architecture")
        if not (
            torch.equal(net.scaler_mean, first.scaler_mean)
            and torch.equal(net.scaler_std, first.scaler_std)
        ):
            raise ConfigError("networks to merge must share the feature scaler")
    n_features, hidden1, hidden2 = shape
    k = len(nets)
    merged = GRADNet(n_features, n_bias, k * hidden1, k * hidden2, confirm_head=confirm)
    with torch.no_grad():
        merged.scaler_mean.copy_(first.scaler_mean)
        merged.scaler_std.copy_(first.scaler_std)
        for layer, hidden, block_in in (("gru1", hidden1, 0), ("gru2", hidden2, hidden1)):
            for name, block in (
                ("weight_ih_l0", block_in),
                ("weight_hh_l0", hidden),
                ("bias_ih_l0", 0),
                ("bias_hh_l0", 0),
            ):
                parts = [getattr(getattr(net, layer), name) for net in nets]
                getattr(getattr(merged, layer), name).copy_(_side_by_side(parts, hidden, block))
        for head in ("anomaly_head", "bias_head") + (("confirm_head",) if confirm else ()):
            getattr(merged, head).weight.copy_(
                torch.cat([getattr(net, head).weight for net in nets], 1) / k
            )
            getattr(merged, head).bias.copy_(
                torch.stack([getattr(net, head).bias for net in nets]).mean(0)
            )
    return merged


def network_from_arrays(
    weights: Mapping[str, np.ndarray], mean: np.ndarray, std: np.ndarray
) -> GRADNet:
    """The :class:`GRADNet` that :func:`export_torch` would turn into ``weights``, with the
    scaler ``mean``/``std``: the inverse of the export (sizes and the confirm head read
    from the arrays), to check inference against torch or to merge saved models."""
    net = GRADNet(
        int(weights["gru1.weight_ih"].shape[1]),
        int(weights["bias_head.bias"].shape[0]),
        int(weights["gru1.weight_hh"].shape[1]),
        int(weights["gru2.weight_hh"].shape[1]),
        confirm_head="confirm_head.weight" in weights,
    )
    state = {path: torch.from_numpy(array) for path, array in torch_state(weights).items()}
    state["scaler_mean"] = torch.tensor(np.asarray(mean, np.float32))
    state["scaler_std"] = torch.tensor(np.asarray(std, np.float32))
    net.load_state_dict(state)
    return net


def _side_by_side(parts: Sequence[torch.Tensor], hidden: int, block: int) -> torch.Tensor:
    """Stack the members' (r, z, n) gate rows gate by gate; ``block`` > 0: member ``j``
    reads only input columns ``j * block`` to ``(j + 1) * block`` (0: all inputs shared)."""
    k = len(parts)
    if parts[0].dim() == 1:
        out = torch.zeros(3 * k * hidden)
    else:
        out = torch.zeros(3 * k * hidden, k * block if block else parts[0].shape[1])
    for j, w in enumerate(parts):
        for g in range(3):
            rows = slice((g * k + j) * hidden, (g * k + j + 1) * hidden)
            src = w[g * hidden : (g + 1) * hidden]
            if not block:  # shared inputs, or a bias
                out[rows] = src
            else:
                out[rows, j * block : (j + 1) * block] = src
    return out


class _BestEpoch:
    """Early stopping as every trainer here does it (GRAD's GRU, the window baselines).

    Keeps a copy of the weights of the epoch with the lowest validation
    score, stops once the time budget is spent or ``patience`` epochs passed
    without a lower one, and puts the kept weights back at the end: the
    model returned is the best epoch's, not the last one's.
    """

    def __init__(self, net: nn.Module, patience: int) -> None:
        self.net = net
        self.patience = patience
        self.score = math.inf
        self.epoch = 0
        self.state: dict[str, torch.Tensor] | None = None
        self.stop_reason = "max_epochs"

    def stop(self, epoch: int, score: float, out_of_time: bool) -> bool:
        """Record ``epoch``'s score (lower is better); whether to stop training now."""
        if score < self.score:
            self.score, self.epoch = score, epoch
            self.state = {k: v.detach().clone() for k, v in self.net.state_dict().items()}
        if out_of_time:
            self.stop_reason = "time_budget"
            return True
        if epoch - self.epoch >= self.patience:
            self.stop_reason = "patience"
            return True
        return False

    def restore(self) -> None:
        """Load the best epoch's weights into the net (no epoch ran: leave it as it is)."""
        if self.state is not None:
            self.net.load_state_dict(self.state)


def _optimise(
    optimizer: torch.optim.Optimizer,
    loss: torch.Tensor,
    net: nn.Module | None = None,
    clip: float = 0.0,
) -> float:
    """One optimiser step; with ``clip`` > 0 the gradient norm of ``net`` is clipped to it."""
    optimizer.zero_grad(set_to_none=True)
    loss.backward()  # type: ignore[no-untyped-call]
    if clip > 0 and net is not None:
        torch.nn.utils.clip_grad_norm_(net.parameters(), clip)
    optimizer.step()
    return float(loss.detach())
