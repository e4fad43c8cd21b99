"""Phantom offsets of the offset tracker after protocol ``gnss`` faults, on the real
validation drives, positions only: how long the tracker stays off the real track.

The tracker alone (no network), positions as the pipeline prepares them, on every
data set's validation split with protocol ``gnss`` (seed ``--seed``) injected, as
``benchmarks/tried/gnss_validation.py`` scores it. Per data set: the normal fixes
(no injected fault), the share where the tracker holds an offset above 8 m (a
*phantom*: a clean fix read as displaced), the shares where that phantom's fault
age exceeds 60 s and 180 s, and the oldest phantom (s). ``--origin`` adds, per
data set, the bias type of the fault where each phantom older than 60 s began (the
fix where its age was smallest; ``after X`` where that fix is a normal one, X the
last fault before it): which faults leave the tracker on a wrong track.
A tracker should re-acquire the real track within a bounded time after any fault
(issue 13). Never a test split. Run with the sources to judge on ``PYTHONPATH``:

    python benchmarks/tried/gnss_phantoms.py [--seed 0] [--set K=V,...] [--origin]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_gnss
from gradgps._grad.offset import OFFSET_FEATURES
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for tracker_accuracy
from _validation_drives import validation_positions
from tracker_accuracy import tracker_features, tracker_settings

THRESHOLD_M = 8.0
NORM, AGE = OFFSET_FEATURES.index("offset_norm"), OFFSET_FEATURES.index("fault_age_s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", default="", help="tracker settings k=v,... over the defaults")
    parser.add_argument("--origin", action="store_true", help="where the old phantoms began")
    args = parser.parse_args()
    params = PipelineParams()
    tracker = tracker_settings(params.offset, args.set)
    print(tracker)
    print("| data set | normal fixes | phantom | older than 60 s | older than 180 s | oldest (s) |")
    print("|---|---|---|---|---|---|")
    total = np.zeros(4)
    origins: dict[str, Counter[str]] = {}
    for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
        labelled = inject_gnss(table, seed=args.seed)
        fixes = to_fixes(labelled[cols], cmap)
        rows = tracker_features(tracker, params.max_gap_s, fixes, np.nan)
        norm = np.nan_to_num(rows[:, NORM])
        normal = labelled["label_anomaly"].to_numpy() == 0
        phantom = normal & (norm > THRESHOLD_M)
        age = rows[:, AGE]
        old = phantom & (age > 60)
        c = np.array([normal.sum(), phantom.sum(), old.sum(), (phantom & (age > 180)).sum()])
        total += c
        oldest = float(age[phantom].max()) if phantom.any() else 0.0
        print(
            f"| {name} | {c[0]:,} | {100 * c[1] / c[0]:.2f} % | {100 * c[2] / c[0]:.2f} % | "
            f"{100 * c[3] / c[0]:.2f} % | {oldest:.0f} |"
        )
        if args.origin:
            bias = labelled["label_bias"].to_numpy(dtype=object)
            found = origins.setdefault(name, Counter())
            for idx in fixes.groupby("track", sort=False).indices.values():
                for k in np.flatnonzero(old[idx]):
                    start = k  # walk back while the fault's age falls: where it began
                    while (
                        start > 0
                        and np.isfinite(age[idx[start - 1]])
                        and (age[idx[start - 1]] < age[idx[start]])
                    ):
                        start -= 1
                    kind = str(bias[idx[start]])
                    if kind == "none":  # began on a normal fix: name the fault before it
                        before = [str(b) for b in bias[idx[:start]] if b != "none"]
                        kind = f"after {before[-1]}" if before else "none"
                    found[kind] += 1
    print(
        f"| all | {int(total[0]):,} | {100 * total[1] / total[0]:.2f} % | "
        f"{100 * total[2] / total[0]:.2f} % | {100 * total[3] / total[0]:.2f} % | |"
    )
    for name, found in origins.items():
        print(
            f"{name}: phantoms older than 60 s began at "
            + ", ".join(f"{kind} {n}" for kind, n in found.most_common())
        )


if __name__ == "__main__":
    main()
