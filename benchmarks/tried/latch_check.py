"""Where a run of false positives comes from: the detector started afresh at later rows.

A network can *latch*: after a fault it keeps flagging fixes whose features are all
clean again (no offset, no evidence, REMA and the motion model quiet), sometimes to
its segment's end (docs/model-card.md, "Limits"). Its state then carries something
an earlier stretch put there. This runs the shipped model (or ``--model``) on the
segment that holds row ``--row`` of the drives ``simulated_trace.py`` draws
(simulator seed ``--sim-seed``, ``--hz``, protocol ``grad`` seed ``--inject-seed``,
positions only), first whole, then starting at each row of ``--starts`` (rows of the
whole table, in the same segment) with a fresh state, and counts the false positives
from ``--row`` on: the latest start that still gives them brackets the stretch that
set the latch. Never the test splits. Run:

    python benchmarks/tried/latch_check.py --hz 0.5 --sim-seed 4242 --inject-seed 0 \\
        --row 400 --starts 100,200,300,340,372
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for simulated_trace
from simulated_trace import drive_arguments, drives


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    drive_arguments(parser, simulated_only=True)  # simulated drives, as simulated_trace.py
    parser.add_argument("--row", type=int, required=True, help="count false positives from here")
    parser.add_argument("--starts", required=True, help="rows to start afresh at, comma-separated")
    args = parser.parse_args()

    labelled, cmap = drives(args)
    fixes = to_fixes(labelled, cmap)
    truth = labelled["label_anomaly"].to_numpy() == 1
    track = fixes["track"].to_numpy()
    rows = np.flatnonzero(track == track[args.row])  # the drive that holds --row
    detector = Detector(args.model)
    print("| start row | false positives from the row on | false positives in all |")
    print("|---|---|---|")
    for start in [int(rows[0]), *(int(s) for s in args.starts.split(","))]:
        if not rows[0] <= start <= args.row:
            raise SystemExit(f"start {start} is not between the drive's first row and --row")
        part = rows[rows >= start]
        flag = detector.detect(fixes.iloc[part].reset_index(drop=True))["anomaly"].to_numpy() == 1
        false = flag & ~truth[part]
        print(f"| {start} | {int(false[part >= args.row].sum())} | {int(false.sum())} |")


if __name__ == "__main__":
    main()
