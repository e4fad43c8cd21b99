"""Long phantom offsets of the offset tracker on the recipe's validation drives, with and
without the frozen fixes the recipe injects.

The tracker alone (no network), positions as the pipeline prepares them, on the
training recipe's validation drives with the faults ``gradgps calibrate`` injects
(protocol ``grad`` at the recipe's validation seed, frozen fixes and stale starts;
``--no-freeze``: protocol ``grad`` only). Per group of drives (a real data set, the
simulated drives at one rate): the normal fixes (no injected fault), the share where
the tracker holds an offset above 8 m (a *phantom*: a clean fix read as displaced),
and the shares where that phantom's fault age exceeds 60 s and 180 s. A tracker
should re-acquire the real track within a bounded time after any fault (issue 13);
these are the fixes where it had not. Never a test split. Run with the sources to
judge on ``PYTHONPATH``:

    python benchmarks/tried/freeze_phantoms.py [--no-freeze] [--set K=V,...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._grad.offset import OFFSET_FEATURES
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.track import to_fixes
from gradgps._train.calibrate import inject_validation_faults, recipe_group
from gradgps._train.recipe import recipe_faults, recipe_tables

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for tracker_accuracy
from tracker_accuracy import tracker_features, tracker_settings

THRESHOLD_M = 8.0
NORM, AGE = OFFSET_FEATURES.index("offset_norm"), OFFSET_FEATURES.index("fault_age_s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-freeze", action="store_true", help="protocol grad faults only")
    parser.add_argument("--set", default="", help="tracker settings k=v,... over the defaults")
    args = parser.parse_args()
    params = PipelineParams()
    tracker = tracker_settings(params.offset, args.set)
    spec = recipe_faults()
    counts: dict[str, np.ndarray] = {}
    for table in recipe_tables("validation"):
        cmap = to_fixes(table).attrs["columns"]
        labelled = (
            inject_grad(table, seed=spec.val_seed, columns=cmap)
            if args.no_freeze
            else inject_validation_faults(table, spec)
        )
        rows = tracker_features(tracker, params.max_gap_s, to_fixes(labelled, cmap), np.nan)
        normal = (labelled["label_anomaly"].to_numpy() == 0) & np.isfinite(rows[:, NORM])
        phantom = normal & (rows[:, NORM] > THRESHOLD_M)
        groups = np.array([recipe_group(str(s)) for s in labelled["track"].astype(str)])
        for g in dict.fromkeys(groups):
            m = groups == g
            counts.setdefault(g, np.zeros(4))
            counts[g] += [
                np.sum(normal & m),
                np.sum(phantom & m),
                np.sum(phantom & m & (rows[:, AGE] > 60)),
                np.sum(phantom & m & (rows[:, AGE] > 180)),
            ]
    print(tracker)
    print("| drives | normal fixes | phantom | phantom older than 60 s | older than 180 s |")
    print("|---|---|---|---|---|")
    for g, c in [*counts.items(), ("all", np.sum(list(counts.values()), axis=0))]:
        print(
            f"| {g} | {int(c[0]):,} | {100 * c[1] / c[0]:.2f} % | "
            f"{100 * c[2] / c[0]:.2f} % | {100 * c[3] / c[0]:.2f} % |"
        )


if __name__ == "__main__":
    main()
