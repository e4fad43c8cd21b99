"""Which rule should decide a settled verdict? (issue 13 experiment, validation only)

For a model with a confirm head, on the real validation drives (positions
only, native and 0.5 Hz, protocol ``grad`` seed 0, as
``lagged_verdict_check.py`` scores them): clean false alarms, anomaly F1 and
normal recall when a fix with a next fix in its segment is decided by
``confirm`` (the confirm head's read at the next fix against
``thresholds.confirm``: what the pipeline does) or by ``mean`` (the mean of
that read and the anomaly head's own at-once probability, against the mean of
the two thresholds). A segment's last fix keeps its verdict at once in both.
Run:

    python benchmarks/tried/settle_rules.py --model DIR [--rules confirm,mean]
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
from gradgps._grad.pipeline import O_CONFIRM, O_FLAG, O_SCORE
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from lagged_verdict_check import _drives


def flags(det: Detector, fixes: pd.DataFrame, rule: str) -> np.ndarray:
    """Per row, the verdict under ``rule`` (an unusable fix flagged, as detect() does)."""
    params = det.model_.params
    assert params.confirm_threshold is not None
    _, usable, prepared, out = det._point_outputs(fixes)
    p, c = out[:, O_SCORE], out[:, O_CONFIRM]
    if rule == "confirm":
        late = c >= params.confirm_threshold
    elif rule == "mean":
        late = (p + c) / 2 >= (params.threshold + params.confirm_threshold) / 2
    else:
        raise SystemExit(f"unknown rule {rule!r}: confirm or mean")
    final = np.where(np.isnan(c), out[:, O_FLAG] == 1, late)  # NaN: decided at once
    rows = np.ones(len(fixes), bool)
    rows[usable] = prepared.to_rows(final.astype(float), fill=1.0) == 1
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True)
    parser.add_argument("--rules", default="confirm,mean")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    if not det.model_.params.settles(det.model_.dims):
        raise SystemExit(f"{args.model} has no confirm head")
    rules = args.rules.split(",")
    print("| data set | rate | " + " | ".join(f"{r}: FA / F1 / NR" for r in rules) + " |")
    print("|---|---|" + "---|" * len(rules))
    for name, rate, data, cols, cmap, ordinary in _drives(False, args.data_dir):
        labelled = inject_grad(data, seed=0, columns=cmap)
        truth = (labelled["label_anomaly"].to_numpy() == 1)[ordinary]
        cells = []
        for rule in rules:
            clean = flags(det, to_fixes(data, cmap), rule)[ordinary]
            hit = flags(det, to_fixes(labelled[cols], cmap), rule)[ordinary]
            s = class_scores(truth, hit)
            cells.append(
                f"{100 * clean.mean():.2f} % / {s['anomaly']['f1']:.3f} / "
                f"{s['normal']['recall']:.3f}"
            )
        print(f"| {name} | {rate} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
