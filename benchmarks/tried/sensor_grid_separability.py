"""Sensor grid, validation split: is the channel GRAD's gap on ``bias``/``drift`` in the features or in training?

    python benchmarks/tried/sensor_grid_separability.py [--rows ROW,ROW] [--json FILE]
        [--methods grad,kf,cnn,cnn-kf,lstm-cnn,waved] [--oracle]

Per row, with the sensor-grid table's per-row recipe (``run_all._grid_recipe``,
speed from the fixes; models trained or taken from ``$GRADGPS_CACHE``):

* every method's score on the *validation* split, read two ways: at the
  method's own threshold, and at a 1 % false-positive rate (the threshold is
  the 99th percentile of the method's score on the normal readings of
  validation injection seed 7; everything is scored on validation injection
  seed 0). Reported: point F1, normal recall, and the share of the faulty
  readings of each channel (speed, acceleration, yaw rate) flagged;
* every single feature of the channel GRAD (its 118 columns) and a few
  windowed statistics of the consistency residuals (their causal means over
  3, 5, 10, 20 steps, raw and as the departure from the causal level), each
  thresholded at 1 % false positives on seed 7 (upper tail, lower tail or
  ``|x|``, whichever was best on seed 7) and scored on seed 0: per faulty
  channel, the best such feature (chosen on seed 7) and its recall on seed 0;
* with ``--oracle`` (``--oracle step``: the features at the step only): a
  gradient-boosted tree ensemble (scikit-learn
  ``HistGradientBoostingClassifier``, no time budget) on the channel GRAD's
  features at the step, the step before and the mean, max and min over the
  last 10 steps, trained on the train split (injection seeds 101, 102),
  thresholded at 1 % false positives on validation seed 7, scored on seed 0:
  what a learner with no budget makes of the same features.

Never reads the test split.
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
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from run_all import _grid_recipe

ROWS = "bias-1-10,bias-3-10,drift-2-10,drift-2-20"
METHODS = "grad,kf,cnn,cnn-kf,lstm-cnn,waved"
CHANNELS = ("speed_mps", "accel_x_mps2", "gyro_z_dps")
FPR = 0.01


def _feature_names(inputs: str) -> list[str]:
    from gradgps._baselines.base import input_names
    from gradgps._baselines.channel_grad import cross_names

    ms = ["slope", "intercept", "fit_err", "spread", "rsi", "range", "last", "rema_d"]
    ms += ["rema_w", "rema_flag", "rema_alpha"]
    out = []
    for c in input_names(inputs):
        out += [f"{c}:{m}" for m in ms]
        out += [f"{c}:{m}" for m in ("raw", "step", "step_z", "level_z", "held")]
    for r in cross_names(inputs):
        out += [f"{r}:{m}" for m in ("raw", "z", "dep", "dep_z", "ev3", "ev10", "ev20")]
        out += [f"{r}:{m}" for m in ms]
    return out


def _extra(seg: Any, inputs: str) -> tuple[list[str], np.ndarray]:
    """Windowed statistics of the consistency residuals (causal means, raw and departure)."""
    from gradgps._baselines.channel_grad import _departure, channel_signals, cross_names

    sig = channel_signals(seg, inputs)
    names, cols = [], []
    for r in cross_names(inputs):
        x = sig[r]
        d = _departure(x)
        for label, v in (("mean", x), ("depmean", d)):
            for k in (3, 5, 10, 20):
                names.append(f"{r}:{label}{k}")
                cols.append(pd.Series(v).rolling(k, min_periods=1).mean().to_numpy())
    return names, np.column_stack(cols)


def _features(fixes: pd.DataFrame, model: Any) -> tuple[list[str], np.ndarray]:
    from gradgps._baselines.base import segments
    from gradgps._baselines.channel_grad import channel_features

    names = _feature_names(model.inputs)
    out: np.ndarray | None = None
    extra_names: list[str] = []
    for seg in segments(fixes, model.inputs, model.max_gap_s)[0]:
        f = channel_features(seg, model.features, model.rema, model.inputs)
        extra_names, e = _extra(seg, model.inputs)
        block = np.hstack([f, e])
        if out is None:
            out = np.full((len(fixes), block.shape[1]), np.nan)
        out[seg.rows] = block
    assert out is not None
    return names + extra_names, out


def _at_fpr(score7: np.ndarray, y7: np.ndarray) -> float:
    return float(np.quantile(score7[~y7], 1.0 - FPR))


def _read(flagged: np.ndarray, y: np.ndarray, labelled: pd.DataFrame) -> dict[str, Any]:
    from gradgps._result import f1_score

    return {
        "f1": round(100 * f1_score(y, flagged), 1),
        "normal_recall": round(float(np.mean(~flagged[~y])), 4),
        "recall": round(float(np.mean(flagged[y])), 3),
        "by_channel": {
            c: round(float(flagged[labelled[f"label_{c}"].to_numpy(bool)].mean()), 3)
            for c in CHANNELS
        },
    }


def _windowed(f: np.ndarray, fixes: pd.DataFrame, window: bool = True) -> np.ndarray:
    """The features at the step, the step before, and mean / max / min over the last 10 steps
    (``window=False``: at the step only)."""
    if not window:
        return f.astype(np.float32)
    parts = [f]
    frame = pd.DataFrame(f)
    g = frame.groupby(fixes["track"].to_numpy())
    parts.append(g.shift(1).to_numpy())
    roll = g.rolling(10, min_periods=1)
    for stat in ("mean", "max", "min"):
        r = getattr(roll, stat)().reset_index(level=0, drop=True).sort_index()
        parts.append(r.to_numpy())
    return np.hstack(parts).astype(np.float32)


def _row(row: str, methods: list[str], oracle: str, train: Any, val: Any) -> dict[str, Any]:
    from gradgps._eval.bench import make_detector
    from gradgps._train.baseline_recipe import labelled_fixes
    from gradgps._train.channel_grad import dataset_channel_grad

    rec = replace(_grid_recipe(False), fix_speed=True, row=row)
    f7, t7, _ = labelled_fixes(val, "sensor-grid", 7, recipe=rec)
    f0, t0, lab0 = labelled_fixes(val, "sensor-grid", 0, recipe=rec)
    y7, y0 = t7.astype(bool), t0.astype(bool)
    out: dict[str, Any] = {"faulty_share": round(float(y0.mean()), 3), "methods": {}}
    for m in methods:
        det = make_detector(m, dataset="driveplotr", protocol="sensor-grid", recipe=rec)
        r7, r0 = det.detect(f7), det.detect(f0)
        s7 = np.nan_to_num(r7["score"].to_numpy(np.float64), nan=-np.inf)
        s0 = np.nan_to_num(r0["score"].to_numpy(np.float64), nan=-np.inf)
        own = r0["anomaly"].to_numpy() == 1
        cut = _at_fpr(s7, y7)
        out["methods"][m] = {"own": _read(own, y0, lab0), "fpr1": _read(s0 >= cut, y0, lab0)}
    model = dataset_channel_grad("driveplotr", None, rec)
    names, x7 = _features(f7, model)
    _, x0 = _features(f0, model)
    best: dict[str, Any] = {}
    lab7 = labelled_fixes(val, "sensor-grid", 7, recipe=rec)[2]
    for c in CHANNELS:
        fault7 = lab7[f"label_{c}"].to_numpy(bool)
        fault0 = lab0[f"label_{c}"].to_numpy(bool)
        cand = []
        for j, name in enumerate(names):
            for tail, tr in (("up", 1.0), ("down", -1.0), ("abs", 0.0)):
                v7 = np.abs(x7[:, j]) if tr == 0.0 else tr * x7[:, j]
                v0 = np.abs(x0[:, j]) if tr == 0.0 else tr * x0[:, j]
                v7, v0 = np.nan_to_num(v7, nan=-np.inf), np.nan_to_num(v0, nan=-np.inf)
                cut = _at_fpr(v7, y7)
                cand.append((float(np.mean(v7[fault7] > cut)), name, tail, v0, cut))
        cand.sort(key=lambda t: -t[0])
        top = []
        for r7, name, tail, v0, cut in cand[:3]:
            top.append(
                {
                    "feature": name,
                    "tail": tail,
                    "recall_seed7": round(r7, 3),
                    "recall_seed0": round(float(np.mean(v0[fault0] > cut)), 3),
                    "normal_recall_seed0": round(float(np.mean(v0[~y0] <= cut)), 4),
                }
            )
        best[c] = top
    out["best_single_feature"] = best
    if oracle:
        from sklearn.ensemble import HistGradientBoostingClassifier

        xs, ys = [], []
        for seed in (101, 102):
            ft, tt, _ = labelled_fixes(train, "sensor-grid", seed, recipe=rec)
            xs.append(_windowed(_features(ft, model)[1], ft, oracle == "window"))
            ys.append(tt.astype(bool))
        began = time.perf_counter()
        clf = HistGradientBoostingClassifier(max_iter=300, learning_rate=0.1, random_state=0)
        clf.fit(np.vstack(xs), np.concatenate(ys))
        p7 = clf.predict_proba(_windowed(x7[:, : len(names)], f7, oracle == "window"))[:, 1]
        p0 = clf.predict_proba(_windowed(x0[:, : len(names)], f0, oracle == "window"))[:, 1]
        cut = _at_fpr(p7, y7)
        out["oracle_hgb"] = {
            **_read(p0 >= cut, y0, lab0),
            "fit_s": round(time.perf_counter() - began),
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default=ROWS)
    parser.add_argument("--methods", default=METHODS)
    parser.add_argument(
        "--oracle",
        nargs="?",
        const="window",
        default="",
        choices=("window", "step"),
        help="also fit the tree ensemble (window: with the 10-step summaries; step: the step only)",
    )
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    import torch

    from gradgps._train.baseline_recipe import splits

    torch.set_num_threads(1)
    train, val = splits("driveplotr", None)
    report = {}
    for row in args.rows.split(","):
        r = _row(row, [m for m in args.methods.split(",") if m], args.oracle, train, val)
        report[row] = r
        print(f"== {row} (faulty share {r['faulty_share']})", flush=True)
        for m, v in r["methods"].items():
            for how in ("own", "fpr1"):
                b = v[how]
                print(
                    f"  {m:9s} {how:5s} F1 {b['f1']:5.1f} normal recall {b['normal_recall']:.4f} "
                    f"recall {b['recall']:.3f} by channel {b['by_channel']}"
                )
        for c, top in r["best_single_feature"].items():
            t = top[0]
            print(
                f"  best single feature for {c}: {t['feature']} ({t['tail']}) recall at 1 % FPR "
                f"seed 7 {t['recall_seed7']:.3f}, seed 0 {t['recall_seed0']:.3f} "
                f"(normal recall {t['normal_recall_seed0']:.4f}); next: "
                + ", ".join(f"{u['feature']} {u['recall_seed0']:.3f}" for u in top[1:])
            )
        if "oracle_hgb" in r:
            b = r["oracle_hgb"]
            print(
                f"  oracle HGB at 1 % FPR: F1 {b['f1']:5.1f} normal recall {b['normal_recall']:.4f} "
                f"recall {b['recall']:.3f} by channel {b['by_channel']} ({b['fit_s']} s fit)"
            )
        if args.json:
            args.json.write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
