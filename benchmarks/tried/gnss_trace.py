"""The offset tracker and the verdicts, fix by fix, on a validation drive under protocol ``gnss``.

Why: ``tried/gnss_validation.py --after`` counts false positives after each kind of
episode; this shows why, for one stretch of rows. It injects protocol ``gnss`` (seed
``--seed``) into a data set's validation split, positions only, and prints every
``--step``-th row of ``--rows A:B`` (rows of the whole injected table): the injected
bias, then for two trackers side by side the offset norm (m), the fault evidence
(nats) and the fault's age (s), and the verdict of the network paired with each.
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
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_gnss
from gradgps._grad.detector import Detector
from gradgps._grad.offset import OFFSET_FEATURES, offset_features
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions
from tracker_accuracy import tracker_settings


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
    prm_a = det_a.model_.params.offset
    prm_b = tracker_settings(det_b.model_.params.offset, args.set)
    print(f"A: {prm_a}\nB: {prm_b}\n")
    for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
        if name != args.dataset:
            continue
        labelled = inject_gnss(table, seed=args.seed)
        fixes = to_fixes(labelled[cols], cmap)
        hit_a = det_a.detect(fixes)["anomaly"].to_numpy()
        hit_b = det_b.detect(fixes)["anomaly"].to_numpy()
        bias = labelled["label_bias"].to_numpy(dtype=object)
        track = fixes["track"].to_numpy()
        rows = np.flatnonzero(track == track[first])
        lat = np.radians(fixes["lat"].to_numpy()[rows])
        lon = np.radians(fixes["lon"].to_numpy()[rows])
        t = fixes["t"].to_numpy(dtype=np.float64)[rows]
        east = (lon - lon[0]) * 6371000.0 * np.cos(lat[0])
        north = (lat - lat[0]) * 6371000.0
        dt = np.r_[0.0, np.diff(t)]
        feats = [offset_features(dt, east, north, None, None, p) for p in (prm_a, prm_b)]
        cols_at = [
            OFFSET_FEATURES.index(k) for k in ("offset_norm", "fault_evidence", "fault_age_s")
        ]
        print(f"{name}: track {track[first]} (rows {rows[0]}-{rows[-1]}), seed {args.seed}")
        print(
            "| row | bias | A offset m | A evidence | A age s | A flag | B offset m | B evidence | B age s | B flag |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for row in range(first, min(last, rows[-1]) + 1, args.step):
            i = row - rows[0]
            cells = []
            for f, hit in zip(feats, (hit_a, hit_b), strict=True):
                cells += [f"{f[i, c]:.1f}" for c in cols_at] + [str(int(hit[row]))]
            print(f"| {row} | {bias[row]} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
