"""Whether the offset tracker knew what the network missed: faulty fixes missed and clean
fixes flagged, split by what the tracker said there, on the validation drives.

For choosing between the tracker and the network as the next thing to change (issue
13), never the test splits. Per data set, positions only, native rate and decimated to
0.5 Hz, protocol ``grad`` with each of ``--seeds`` (default 0-4), the shipped model (or
``--model``), settled verdicts. A fix is *held* where the tracker's best hypothesis
carries an offset above 8 m with evidence for a fault of at least ``--evidence`` nats
(default 3: odds of e^3 = 20 to 1 in the tracker's own model). Printed per cell: the
faulty fixes, how many the network missed and how many of those the tracker held (it
knew; the network or its threshold did not follow), the clean fixes the network flagged
and how many of those the tracker held (it was wrong too), and the clean fixes the
tracker held that the network passed (the network overruled a wrong tracker). Run:

    python benchmarks/tried/tracker_knew.py [--model DIR] [--seeds 0,1,2,3,4] [--evidence 3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import pipeline_feature_names
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _segment_features import segment_features
from _validation_drives import validation_positions

HELD_M = 8.0


def held_fixes(det: Detector, fixes: pd.DataFrame, evidence: float) -> np.ndarray:
    """Per row of ``fixes`` (positions only): the tracker holds an offset above
    :data:`HELD_M` with at least ``evidence`` nats for a fault."""
    names = pipeline_feature_names(det.model_.params)
    norm_k, ev_k = names.index("offset_norm"), names.index("fault_evidence")
    out = np.zeros(len(fixes), dtype=bool)
    for rows, _, values in segment_features(det, fixes):
        out[rows] = (values[:, norm_k] > HELD_M) & (values[:, ev_k] >= evidence)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--seeds", default="0,1,2,3,4")
    parser.add_argument("--evidence", type=float, default=3.0)
    args = parser.parse_args()
    det = Detector(args.model)
    seeds = [int(s) for s in args.seeds.split(",")]
    print(f"fault draws {seeds}; held: offset > {HELD_M:g} m and evidence >= {args.evidence:g}")
    print(
        "| data set | rate | faulty | missed | of which held | false positives "
        "| of which held | clean held, passed |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for period, rate in ((None, "native"), (2.0, "0.5 Hz")):
        for name, data, _, cmap, ordinary in validation_positions(period, None, keep_native=False):
            counts = np.zeros(6, dtype=np.int64)
            for seed in seeds:
                labelled = inject_grad(data, seed=seed, columns=cmap)
                fixes = to_fixes(labelled, cmap)
                flag = det.detect(fixes)["anomaly"].to_numpy(dtype=np.int64) == 1
                faulty = labelled["label_anomaly"].to_numpy(dtype=np.int64) == 1
                held = held_fixes(det, fixes, args.evidence)
                flag, faulty, held = flag[ordinary], faulty[ordinary], held[ordinary]
                missed, false = faulty & ~flag, ~faulty & flag
                counts += [
                    faulty.sum(),
                    missed.sum(),
                    (missed & held).sum(),
                    false.sum(),
                    (false & held).sum(),
                    (~faulty & held & ~flag).sum(),
                ]
            print(f"| {name} | {rate} | " + " | ".join(f"{c:,}" for c in counts) + " |", flush=True)


if __name__ == "__main__":
    main()
