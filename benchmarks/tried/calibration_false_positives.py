"""Where the calibration's false positives sit, per validation drive of one group.

``gradgps calibrate`` (``gradgps._train.calibrate``) picks thresholds on the training
recipe's validation drives with the training's faults; a group whose normal recall is
low at the members' pooled thresholds forces them up. Per track of the group
``GROUP`` (a track-name prefix, e.g. ``nl_motorway``): its normal points, the false
positives of the confirm head at the model's pooled thresholds, and their runs as
``first point+length``. Validation only, never a test split. Run with the sources to
judge on ``PYTHONPATH``:

    python benchmarks/tried/calibration_false_positives.py GROUP [--model DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._train.calibrate import calibration_points
from gradgps._train.recipe import recipe_faults, recipe_tables


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("group", help="track-name prefix, e.g. nl_motorway")
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    args = parser.parse_args()
    det = Detector(args.model)
    config = json.loads((Path(det.model_.path) / "config.json").read_text())["thresholds"]
    threshold = (config.get("pooled") or config)["confirm"]
    tables = [
        t
        for t in recipe_tables("validation")
        if t["track"].astype(str).str.startswith(args.group).any()
    ]
    points = calibration_points(det, tables, recipe_faults(), group=lambda track: track)
    total = 0
    print(f"confirm threshold {threshold:.3f}")
    print("| track | normal points | false positives | runs (first point+length) |")
    print("|---|---|---|---|")
    for track in dict.fromkeys(points.group):
        if not str(track).startswith(args.group):
            continue
        mine = points.group == track
        truth, confirm = points.truth[mine], points.confirm[mine]
        false = np.flatnonzero((confirm >= threshold) & ~truth & np.isfinite(confirm))
        total += len(false)
        runs = np.split(false, np.flatnonzero(np.diff(false) > 1) + 1) if len(false) else []
        listed = " ".join(f"{r[0]}+{len(r)}" for r in runs)
        print(f"| {track} | {int((~truth).sum()):,} | {len(false)} | {listed} |")
    print(f"| all | | {total} | |")


if __name__ == "__main__":
    main()
