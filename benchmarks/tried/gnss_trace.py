"""The offset tracker and the verdicts, fix by fix, on a validation drive under protocol ``gnss``.

Why: ``tried/gnss_validation.py --after`` counts false positives after each kind of
episode; this shows why, for one stretch of rows. It injects protocol ``gnss`` (seed
``--seed``) into a data set's validation split, positions only, and prints every
``--step``-th row of ``--rows A:B`` (rows of the whole injected table): the injected
bias, then for two trackers side by side the offset norm (m), the fault evidence
(nats) and the fault's age (s), as the pipeline computes them on the detector's own
segments (``_segment_features.segment_features``), and the verdict of the network
paired with each.
The first pair is the model's own tracker settings and network (the shipped model
unless ``--model``); the second overrides tracker settings with ``--set K=V,...`` and
runs ``--model-b``'s network (default: the first). With the sources to judge on
``PYTHONPATH`` (a setting that main lacks needs its patch). Never the test splits.
Run:

    python benchmarks/tried/gnss_trace.py --dataset driveplotr --rows 745:935 --step 3
        [--seed 0] [--model DIR] [--model-b DIR] [--set noise_near=0.7]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_gnss
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import pipeline_feature_names
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _segment_features import segment_features
from _validation_drives import validation_positions
from tracker_accuracy import tracker_settings

SHOWN = ("offset_norm", "fault_evidence", "fault_age_s")


def _tracker_columns(det: Detector, fixes: pd.DataFrame) -> np.ndarray:
    """Per row of ``fixes``: the :data:`SHOWN` features of ``det``'s pipeline (NaN on
    rows outside its segments)."""
    names = pipeline_feature_names(det.model_.params)
    at = [names.index(k) for k in SHOWN]
    out = np.full((len(fixes), len(SHOWN)), np.nan)
    for rows, _, values in segment_features(det, fixes):
        out[rows] = values[:, at]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--rows", required=True, help="A:B, rows of the injected table")
    parser.add_argument("--step", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--model", default=None)
    parser.add_argument("--model-b", default=None)
    parser.add_argument("--set", default="", help="tracker settings k=v,... for the second")
    args = parser.parse_args()
    first, last = (int(x) for x in args.rows.split(":"))
    det_a = Detector(args.model)
    det_b = Detector(args.model_b or args.model)
    params_b = det_b.model_.params
    offset_b = tracker_settings(params_b.offset, args.set)
    det_b.model_ = replace(det_b.model_, params=replace(params_b, offset=offset_b))
    print(f"A: {det_a.model_.params.offset}\nB: {offset_b}\n")
    for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
        if name != args.dataset:
            continue
        labelled = inject_gnss(table, seed=args.seed)
        fixes = to_fixes(labelled[cols], cmap)
        shown = [_tracker_columns(d, fixes) for d in (det_a, det_b)]
        hits = [d.detect(fixes)["anomaly"].to_numpy() for d in (det_a, det_b)]
        bias = labelled["label_bias"].to_numpy(dtype=object)
        print(
            f"{name}: rows {first}-{last} of track {fixes['track'].iloc[first]}, seed {args.seed}"
        )
        print(
            "| row | bias | A offset m | A evidence | A age s | A flag "
            "| B offset m | B evidence | B age s | B flag |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for row in range(first, min(last, len(fixes) - 1) + 1, args.step):
            cells = []
            for values, hit in zip(shown, hits, strict=True):
                cells += [f"{v:.1f}" for v in values[row]] + [str(int(hit[row]))]
            print(f"| {row} | {bias[row]} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
