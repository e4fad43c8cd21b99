"""Normal recall and anomaly F1 per group of the recipe's validation drives, per rate band.

What ``gradgps calibrate`` (``gradgps._train.calibrate``) chooses its thresholds on:
the model as shipped (``--model``, default the shipped one) run on the training
recipe's validation drives with the training's faults (protocol ``grad`` seed 7,
frozen fixes, stale starts). Per group (a real data set, the simulated drives at
one rate) and band (faster than every 1.5 s, that or slower): points, share
faulty, and the settled verdicts' anomaly F1 and normal recall at the members'
pooled thresholds (``thresholds.pooled``, or the model's own where it has none)
and at the model's thresholds for that band. Validation only, never a test split:

    python benchmarks/tried/calibration_groups.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._result import f1_score
from gradgps._train.calibrate import SLOW_FROM_PERIOD_S, calibration_points
from gradgps._train.recipe import recipe_faults, recipe_tables


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    config = json.loads((Path(det.model_.path) / "config.json").read_text())["thresholds"]
    pooled = config.get("pooled") or config
    points = calibration_points(
        det, recipe_tables("validation", data_dir=args.data_dir), recipe_faults()
    )
    settled = np.isfinite(points.confirm)
    slow = points.period >= SLOW_FROM_PERIOD_S
    print(
        f"pooled confirm threshold {pooled['confirm']:.3f}; the model's per band: "
        f"{det.model_.params.thresholds_at(1.0)[1]:.3f} / {det.model_.params.thresholds_at(2.0)[1]:.3f}"
    )
    print(
        "| group | band | settled points | faulty | F1 pooled | normal recall pooled | F1 model | normal recall model |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for band, in_band in (("< 1.5 s", ~slow), (">= 1.5 s", slow)):
        model_confirm = det.model_.params.thresholds_at(2.0 if band != "< 1.5 s" else 1.0)[1]
        groups = [*dict.fromkeys(points.group[in_band]), "all"]
        for g in groups:
            m = in_band & settled & ((points.group == g) if g != "all" else True)
            truth = points.truth[m]
            row = f"| {g} | {band} | {int(m.sum()):,} | {truth.mean():.3f} |"
            for threshold in (pooled["confirm"], model_confirm):
                flagged = points.confirm[m] >= threshold
                row += f" {f1_score(truth, flagged):.3f} | {np.mean(~flagged[~truth]):.4f} |"
            print(row)


if __name__ == "__main__":
    main()
