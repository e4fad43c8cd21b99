"""Normal recall of each group of validation drives at given thresholds, in one rate band,
read-only: which group the calibration's floor binds on.

Why: `gradgps calibrate` (and `gradgps train --dataset recipe`) picks, per band of
sampling periods, the best validation F1 that keeps normal recall >= 0.99 on every
group of drives (each real data set, the simulated drives at each rate), and where no
threshold keeps it on all, the one with the highest worst-group normal recall. A model
whose slow-band threshold comes out far above the shipped one (0.983 against 0.936
for the confirm head) loses recall in every 0.5 Hz cell; this says which group held
it there. The model is copied to a scratch folder and calibrated as trained (its
pooled thresholds at every rate, as :func:`gradgps._train.calibrate.calibrate_model`
does), so its own ``config.json`` is left alone. Never a test split. Run:

    python benchmarks/tried/calibration_groups_at.py MODEL_DIR 0.936 0.983 [--band slow|fast]
        [--head confirm|anomaly]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._train.calibrate import (
    SLOW_FROM_PERIOD_S,
    calibration_points,
    recipe_group,
    scored_normals,
    thresholds_as_trained,
)
from gradgps._train.recipe import recipe_faults, recipe_tables


def group_normal_recall(
    truth: np.ndarray, score: np.ndarray, group: np.ndarray, threshold: float
) -> dict[str, float]:
    """Per group (in order of first appearance), the share of its normal points
    (``truth`` 0) scored below ``threshold``, over the points the calibration counts
    (:func:`gradgps._train.calibrate.scored_normals`: those without a score left out,
    groups without normal points too)."""
    _, scored, normals, _ = scored_normals(truth, score, group)
    return {g: float(np.mean(scored[normal] < threshold)) for g, normal in normals.items()}


def as_trained(model: str, scratch: str) -> Detector:
    """``model`` copied into ``scratch`` with its pooled thresholds at every rate, as
    :func:`gradgps._train.calibrate.calibrate_model` scores it before choosing per-rate
    ones; the model's own ``config.json`` is left alone."""
    copy = Path(scratch) / "model"
    shutil.copytree(model, copy)
    thresholds_as_trained(copy)
    return Detector(copy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model")
    parser.add_argument("thresholds", nargs="+", type=float)
    parser.add_argument("--band", choices=("slow", "fast"), default="slow")
    parser.add_argument("--head", choices=("confirm", "anomaly"), default="confirm")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        points = calibration_points(
            as_trained(args.model, scratch),
            recipe_tables("validation"),
            recipe_faults(),
            recipe_group,
        )
    slow = points.period >= SLOW_FROM_PERIOD_S
    band = slow if args.band == "slow" else ~slow
    score = points.confirm if args.head == "confirm" else points.score
    print(
        f"{args.model}: normal recall per group of validation drives, {args.band} band, {args.head} head"
    )
    print()
    for t in args.thresholds:
        recall = group_normal_recall(points.truth[band], score[band], points.group[band], t)
        print(f"threshold {t:g}: " + ", ".join(f"{g} {r:.4f}" for g, r in recall.items()))


if __name__ == "__main__":
    main()
