"""A model's verdicts on the validation drives, taken at once or one fix late (issue 13 experiment).

For model choice and experiments, never the test splits. Per real data set
with a validation split, positions only, native and 0.5 Hz: the share of the
untouched drive's fixes flagged, and the anomaly F1 and normal recall under
protocol ``grad`` (seed 0), over the rows without a real ``glitch``. With
``--lag 1`` the verdict for a fix is the model's flag at the next fix of the
same track (a model trained by ``lagged_verdict_train.py``; the last fix of a
track keeps its own flag). Run:

    python benchmarks/tried/lagged_verdict_check.py --model DIR [--lag 0|1] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._eval.metrics import class_scores
from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions


def verdicts(det: Detector, fixes: pd.DataFrame, lag: int) -> np.ndarray:
    flag = det.detect(fixes)["anomaly"].to_numpy() == 1
    if lag == 0:
        return flag
    track = fixes["track"].astype(str).to_numpy()
    late = flag.copy()
    late[:-1] = np.where(track[1:] == track[:-1], flag[1:], flag[:-1])
    return late


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True)
    parser.add_argument("--lag", type=int, choices=(0, 1), default=0)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    print(f"model {args.model}, verdict {'one fix late' if args.lag else 'at once'}")
    print("| data set | rate | clean false alarms | anomaly F1 | normal recall |")
    print("|---|---|---|---|---|")
    for rate, period in (("native", None), ("0.5 Hz", 2.0)):
        for name, data, cols, cmap, ordinary in validation_positions(period, args.data_dir):
            clean = verdicts(det, to_fixes(data, cmap), args.lag)[ordinary]
            labelled = inject_grad(data, seed=0, columns=cmap)
            truth = (labelled["label_anomaly"].to_numpy() == 1)[ordinary]
            hit = verdicts(det, to_fixes(labelled[cols], cmap), args.lag)[ordinary]
            scores = class_scores(truth, hit)
            f1, normal_recall = scores["anomaly"]["f1"], scores["normal"]["recall"]
            print(
                f"| {name} | {rate} | {100 * clean.mean():.2f} % | {f1:.3f} | {normal_recall:.3f} |"
            )


if __name__ == "__main__":
    main()
