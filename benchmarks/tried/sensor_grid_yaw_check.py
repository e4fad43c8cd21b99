"""Channel GRAD on the sensor grid's validation split: the yaw-rate residuals and CUSUMs tried.

    python benchmarks/tried/sensor_grid_yaw_check.py [--rows ROW,ROW] [--seed N]
        [--variant nocusum,noyaw,headonly] [--json FILE]
    python benchmarks/tried/sensor_grid_yaw_check.py --separability

Trains (or takes from ``$GRADGPS_CACHE``) the channel GRAD of each row with the
sensor-grid table's per-row recipe (``run_all._grid_recipe``, speed from the
fixes; ``--seed`` sets the training seed) and scores it on the *validation*
split injected with seeds 0, 1 and 2 pooled (the thresholds come from
validation seed 7, as in training), at the shipped normal-recall floor (0.995,
the model's own threshold) and at 0.99 (the threshold re-chosen on validation
seed 7's probabilities). Prints per row point F1 (%), normal recall and the
share of each channel's faulty readings flagged. Never reads the test split.

Works on the shipped sources (design ``channel-grad-4b``) and on them with
``benchmarks/tried/channel_grad_yaw_cusum.patch`` applied (design
``channel-grad-5``: the yaw rate against the course from the fixes and the
reported heading, and two one-sided CUSUMs per consistency residual;
docs/deviations.md, "channel GRAD: yaw-rate consistency ... tried"). With the
patch, ``--variant`` drops parts of it in this process only (give each
variant its own ``GRADGPS_CACHE``: the cache key names the design, not the
variant): ``nocusum``, ``noyaw``, ``headonly`` (the reported-heading residual
only). ``--separability`` (patch only) prints, on the train split (injection
seed 101), how far the yaw residuals and the yaw rate itself separate a yaw-rate
fault from normal readings at the normal readings' 99th percentile, on
straight driving and in turns.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from run_all import _grid_recipe

ROWS = (
    "bias-5-3,bias-5-10,bias-3-10,bias-1-10,drift-4-10,drift-2-10,drift-2-20,"
    "mixed,constant-5-3,instant-100"
)
SCORE_SEEDS = (0, 1, 2)
CHANNELS = ("speed_mps", "accel_x_mps2", "gyro_z_dps")


def _apply_variant(variant: str) -> None:
    if not variant:
        return
    import gradgps._baselines.channel_grad as cg

    if not hasattr(cg, "fix_references"):
        raise SystemExit("--variant needs benchmarks/tried/channel_grad_yaw_cusum.patch applied")
    flags = set(variant.split(","))
    if "nocusum" in flags:
        cg._cusum = lambda z, slack=0.5: ()  # type: ignore[assignment]
    if "noyaw" in flags:
        cg._YAW_REFERENCES = {}
    if "headonly" in flags:
        cg._YAW_REFERENCES = {"yaw_rate_minus_heading_rate": "heading_rate_dps"}


def _row_report(row: str, base: Any, val: pd.DataFrame) -> dict[str, Any]:
    from gradgps._baselines.channel_grad import ChannelGradDetector
    from gradgps._result import f1_score
    from gradgps._train.baseline_recipe import labelled_fixes
    from gradgps._train.channel_grad import dataset_channel_grad
    from gradgps._train.thresholds import recall_floor_threshold

    rec = replace(base, row=row)
    began = time.perf_counter()
    model = dataset_channel_grad("driveplotr", None, rec)
    trained_s = time.perf_counter() - began
    det = ChannelGradDetector(model)

    def scores(seed: int) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
        fixes, truth, labelled = labelled_fixes(val, "sensor-grid", seed, recipe=rec)
        p = np.nan_to_num(det.detect(fixes)["score"].to_numpy(np.float64))
        return p, truth.astype(bool), labelled

    p7, y7, _ = scores(rec.val_seed)
    parts = [scores(s) for s in SCORE_SEEDS]
    p = np.concatenate([x[0] for x in parts])
    y = np.concatenate([x[1] for x in parts])
    labelled = pd.concat([x[2] for x in parts], ignore_index=True)
    out: dict[str, Any] = {"seconds": round(trained_s, 1)}
    for floor in (0.995, 0.99):
        threshold = model.threshold if floor == 0.995 else recall_floor_threshold(y7, p7, floor)
        flagged = p >= threshold
        by_channel = {
            c: round(float(flagged[labelled[f"label_{c}"].to_numpy(bool)].mean()), 3)
            for c in CHANNELS
        }
        out[str(floor)] = {
            "f1": round(100 * f1_score(y, flagged), 1),
            "normal_recall": round(float(np.mean(~flagged[~y])), 4),
            "recall_by_channel": by_channel,
        }
    return out


def _separability() -> None:
    from gradgps._baselines.base import segments
    from gradgps._baselines.channel_grad import _signals, fix_references  # patch only
    from gradgps._train.baseline_recipe import BaselineRecipe, labelled_fixes, splits

    train, _ = splits("driveplotr", None)
    names = ("gyro_z_dps", "yaw_rate_minus_heading_rate", "yaw_rate_minus_course_rate")
    print(
        "train split, injection seed 101: |departure from the median of the previous 30| "
        "averaged over k steps; threshold: the 99th percentile of the normal readings in "
        "the same driving state (straight: |heading rate| < 2 deg/s)"
    )
    for row in ("bias-5-10", "bias-3-10", "bias-1-10", "drift-4-10", "drift-2-20"):
        recipe = BaselineRecipe(fix_speed=True, row=row)
        fixes, truth, labelled = labelled_fixes(train, "sensor-grid", 101, recipe=recipe)
        y = truth.astype(bool)
        gyro_fault = labelled["label_gyro_z_dps"].to_numpy(bool)
        ref = np.full(len(fixes), np.nan)
        feats: dict[tuple[str, int], np.ndarray] = {}
        for seg in segments(fixes, "sensor-fix")[0]:
            refs = fix_references(fixes, seg)
            ref[seg.rows] = refs["heading_rate_dps"]
            signals = _signals(seg, "sensor-fix", refs)
            for name in names:
                r = signals[name]
                level = pd.Series(r).shift(1).rolling(30, min_periods=3).median().to_numpy()
                for k in (1, 10):
                    mean = pd.Series(r - level).rolling(k, min_periods=1).mean().to_numpy()
                    feats.setdefault((name, k), np.full(len(fixes), np.nan))[seg.rows] = mean
        shares = [np.mean(np.abs(ref[gyro_fault]) < 2), np.mean(np.abs(ref[gyro_fault]) >= 2)]
        print(
            f"{row}: yaw-rate fault readings {shares[0]:.2f} straight, {shares[1]:.2f} turning, "
            f"{1 - sum(shares):.2f} too slow for a heading"
        )
        for state, where in (("straight", np.abs(ref) < 2), ("turning", np.abs(ref) >= 2)):
            for (name, k), x in feats.items():
                ok = where & np.isfinite(x)
                threshold = np.quantile(np.abs(x[~y & ok]), 0.99)
                recall = np.mean(np.abs(x[gyro_fault & ok]) > threshold)
                print(f"  {state:8s} {name:28s} k={k:2d}: p99 {threshold:6.2f} recall {recall:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default=ROWS)
    parser.add_argument("--seed", type=int, default=0, help="training seed of the recipe")
    parser.add_argument("--variant", default="", help="patch only: nocusum, noyaw, headonly")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--separability", action="store_true")
    args = parser.parse_args()
    import torch

    torch.set_num_threads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    _apply_variant(args.variant)
    if args.separability:
        _separability()
        return
    from gradgps._train.baseline_recipe import splits

    base = replace(_grid_recipe(False), fix_speed=True, seed=args.seed)
    _, val = splits("driveplotr", None)
    report = {}
    for row in args.rows.split(","):
        report[row] = _row_report(row, base, val)
        r = report[row]
        print(
            f"{row:14s} trained {r['seconds']:5.1f} s | "
            + " | ".join(
                f"floor {f}: F1 {r[f]['f1']:5.1f} normal recall {r[f]['normal_recall']:.3f} "
                f"by channel {r[f]['recall_by_channel']}"
                for f in ("0.995", "0.99")
            ),
            flush=True,
        )
    for floor in ("0.995", "0.99"):
        mean = np.mean([r[floor]["f1"] for r in report.values()])
        print(f"mean point F1 at floor {floor}: {mean:.1f}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
