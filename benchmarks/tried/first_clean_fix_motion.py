"""The first clean fix after a fault: was the motion model rejecting it, and was it flagged?

Protocol ``grad`` (seed 0) on the real validation drives (never a test split),
positions only, at the native rate (``--period 2``: 0.5 Hz). For every first normal
fix after a faulty one: whether the motion model was dead-reckoning through it
(``motion_run_s`` > 0: "gated") or following the fixes, whether it had taken the
fault's last fix in ("prev-accepted") or not, and whether the detector flagged it.
Run from the repository root with the sources to judge on ``PYTHONPATH``:

    python benchmarks/tried/first_clean_fix_motion.py [--model DIR] [--period 2]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import pipeline_feature_names
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _segment_features import segment_features
from _validation_drives import validation_positions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--period", type=float, default=0.0, help="seconds; 0 = native")
    args = parser.parse_args()
    det = Detector(args.model)
    run_s = pipeline_feature_names(det.model_.params).index("motion_run_s")
    counts: Counter[tuple[str, str, str]] = Counter()
    for _, data, cols, cmap, _ in validation_positions(args.period or None):
        labelled = inject_grad(data, seed=0, columns=cmap)
        faulty = labelled["label_anomaly"].to_numpy() == 1
        fixes = to_fixes(labelled[cols], cmap)
        flagged = det.detect(fixes)["anomaly"].to_numpy() == 1
        run = np.zeros(len(faulty))
        for rows, _, features in segment_features(det, fixes):
            run[rows] = features[:, run_s]
        for i in np.flatnonzero(~faulty[1:] & faulty[:-1]) + 1:
            counts[
                (
                    "gated" if run[i] > 0 else "followed",
                    "prev-accepted" if run[i - 1] == 0 else "prev-gated",
                    "flagged" if flagged[i] else "not flagged",
                )
            ] += 1
    print("| motion model at the fix | at the fault's last fix | verdict | fixes |")
    print("|---|---|---|---|")
    for key, n in sorted(counts.items()):
        print(f"| {' | '.join(key)} | {n} |")


if __name__ == "__main__":
    main()
