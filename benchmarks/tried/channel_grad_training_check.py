"""Channel GRAD on the sensor grid's validation split: training settings compared on the same features.

    python benchmarks/tried/channel_grad_training_check.py [--rows ROW,ROW] [--seeds 0,1]
        [--variant NAME:key=value,key=value ...] [--json FILE]

Per row, the channel GRAD's features are built once (the sensor-grid table's
per-row recipe, ``run_all._grid_recipe``, speed from the fixes; REMA settings
from the cached shipped model of ``$GRADGPS_CACHE``): the train split with the
recipe's injection seeds (101-103), the validation split with seed 7 (early
stopping, thresholds) and seeds 0, 1, 2 (scoring). Each variant (``base`` is the
shipped ``TrainConfig``; a variant overrides some of its fields; ``transform=quantile``
maps every feature through its train-split empirical CDF before the network) is trained with
the recipe's 15-second budget for each training seed of ``--seeds``, then scored
on validation seeds 0-2 pooled: point F1 (%) and normal recall at the shipped
rule's threshold (best seed-7 F1 keeping seed-7 normal recall >= 0.995), the
lowest normal recall of the three scoring seeds, and F1 at a 1 % false-positive
rate (threshold: the seed-7 normal readings' 99th percentile). Never reads the
test split.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from run_all import _grid_recipe

ROWS = "bias-1-10,bias-3-10,drift-2-10,drift-2-20"
SCORE_SEEDS = (0, 1, 2)


def _parse(spec: str) -> tuple[str, dict[str, Any]]:
    name, _, rest = spec.partition(":")
    out: dict[str, Any] = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        out[key] = json.loads(value) if value[:1] in "0123456789-[{tfn" else value
    return name, out


#: Quantile levels of the rank transform (``transform=quantile``): fine in both tails.
_LEVELS = np.unique(
    np.r_[
        [0.0, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02],
        np.linspace(0.03, 0.97, 95),
        [0.98, 0.99, 0.995, 0.998, 0.999, 0.9995, 1.0],
    ]
)


def _rank_transform(train: list[Any], others: list[list[Any]]) -> tuple[list[Any], list[list[Any]]]:
    """Every feature mapped through its train-split empirical CDF (to [-1, 1], clipped)."""
    stacked = np.vstack([f for f, _, _ in train]).astype(np.float64)
    knots = np.nanquantile(stacked, _LEVELS, axis=0)
    y = 2.0 * _LEVELS - 1.0

    def one(f: np.ndarray) -> np.ndarray:
        out = np.empty_like(f)
        for j in range(f.shape[1]):
            xp = knots[:, j]
            keep = np.r_[True, np.diff(xp) > 0]
            out[:, j] = np.interp(f[:, j], xp[keep], y[keep]) if keep.sum() > 1 else 0.0
        return out

    def seqs(s: list[Any]) -> list[Any]:
        return [(one(f).astype(np.float32), a, b) for f, a, b in s]

    return seqs(train), [seqs(o) for o in others]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default=ROWS)
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--variant", action="append", default=[])
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    import torch

    from gradgps._grad.gru import GRUModel
    from gradgps._result import f1_score
    from gradgps._train.baseline_recipe import splits
    from gradgps._train.channel_grad import (
        GRU_WINDOW,
        _sequences,
        channel_grad_config,
        dataset_channel_grad,
    )
    from gradgps._train.thresholds import NORMAL_RECALL_FLOOR, recall_floor_threshold
    from gradgps._train.torch_gru import train_model

    torch.set_num_threads(1)
    variants = [_parse(v) for v in (args.variant or ["base:"])]
    seeds = [int(s) for s in args.seeds.split(",")]
    train, val = splits("driveplotr", None)
    report: dict[str, Any] = {}
    for row in args.rows.split(","):
        rec = replace(_grid_recipe(False), fix_speed=True, row=row)
        shipped = dataset_channel_grad("driveplotr", None, rec)
        feats = (shipped.features, shipped.rema, rec)
        tr = _sequences(train, rec.seeds, *feats)
        v7 = _sequences(val, (rec.val_seed,), *feats)
        score = _sequences(val, SCORE_SEEDS, *feats)
        per_seed = len(score) // len(SCORE_SEEDS)
        report[row] = {}
        for name, override in variants:
            override = dict(override)
            transform = override.pop("transform", "")
            tr_v, (v7_v, score_v) = (
                _rank_transform(tr, [v7, score]) if transform == "quantile" else (tr, [v7, score])
            )
            for seed in seeds:
                config = replace(channel_grad_config(replace(rec, seed=seed)), **override)
                began = time.perf_counter()
                trained = train_model(tr_v, v7_v, config)
                took = time.perf_counter() - began
                gru = GRUModel(
                    trained.weights(),
                    trained.network.scaler_mean.detach().numpy().astype(np.float64),
                    trained.network.scaler_std.detach().numpy().astype(np.float64),
                    mode="window",
                    window=GRU_WINDOW,
                )
                p7 = np.concatenate([gru.predict(f).anomaly for f, _, _ in v7_v])
                y7 = np.concatenate([y for _, y, _ in v7_v]).astype(bool)
                probs = [gru.predict(f).anomaly for f, _, _ in score_v]
                p = np.concatenate(probs)
                y = np.concatenate([y for _, y, _ in score]).astype(bool)
                cut = recall_floor_threshold(y7, p7, NORMAL_RECALL_FLOOR)
                cut1 = float(np.quantile(p7[~y7], 0.99))
                nr_seeds = []
                for k in range(len(SCORE_SEEDS)):
                    ps = np.concatenate(probs[k * per_seed : (k + 1) * per_seed])
                    ys = np.concatenate(
                        [s[1] for s in score[k * per_seed : (k + 1) * per_seed]]
                    ).astype(bool)
                    nr_seeds.append(float(np.mean(ps[~ys] < cut)))
                entry = {
                    "f1": round(100 * f1_score(y, p >= cut), 1),
                    "normal_recall": round(float(np.mean(p[~y] < cut)), 4),
                    "min_seed_normal_recall": round(min(nr_seeds), 4),
                    "f1_fpr1": round(100 * f1_score(y, p >= cut1), 1),
                    "normal_recall_fpr1": round(float(np.mean(p[~y] < cut1)), 4),
                    "best_epoch": trained.best_epoch,
                    "epochs": len(trained.history),
                    "stop": trained.stop_reason,
                    "seconds": round(took, 1),
                }
                report[row][f"{name}/{seed}"] = entry
                print(f"{row:12s} {name:14s} seed {seed}: {entry}", flush=True)
        if args.json:
            args.json.write_text(json.dumps(report, indent=1) + "\n")
    names = [n for n, _ in variants]
    for name in names:
        for seed in seeds:
            vals = [report[r][f"{name}/{seed}"] for r in report]
            print(
                f"mean {name:14s} seed {seed}: F1 {np.mean([v['f1'] for v in vals]):5.1f} "
                f"F1@1% {np.mean([v['f1_fpr1'] for v in vals]):5.1f} "
                f"min normal recall {min(v['min_seed_normal_recall'] for v in vals):.4f}"
            )


if __name__ == "__main__":
    main()
