"""The offset tracker's and motion model's features around one fix of a simulated drive
or of a real validation drive.

For reading a hang-over run that ``hangover_check.py`` found on simulated drives
(issue 13), or an error that ``error_places.py`` counted on the validation drives;
never the test splits. Draws the drives and faults as ``hangover_check.py`` does
(6 x 15 min at ``--hz``, simulator seed ``--sim-seed``, protocol ``grad`` seed
``--inject-seed``, positions only), or with ``--dataset NAME`` takes that data
set's validation split, positions only, at the native rate or decimated to one fix
per ``--period`` seconds (as ``validation_check.py`` and ``error_places.py`` do),
with protocol ``grad`` seed ``--inject-seed``. Runs the shipped model (or
``--model``), and prints for the fixes ``--before`` fixes before to ``--after``
after row ``--row`` (a row of the whole table, as ``hangover_check.py``'s runs are
counted) within its segment: the label, the verdicts at once and settled, the
injected bias and time type, the step (m, east and north) and the features
(decompressed: metres, seconds). ``--errors`` lists the longest runs of missed
faulty fixes and of false positives (length, first row) instead. Run:

    python benchmarks/tried/simulated_trace.py --hz 10 --sim-seed 555 --inject-seed 0 \\
        --row 27428 [--before 60] [--after 45] [--model DIR] [--features a,b,...]
    python benchmarks/tried/simulated_trace.py --dataset nl_motorway [--period 2] --errors
    python benchmarks/tried/simulated_trace.py --dataset nl_motorway --row 2984
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import pipeline_feature_names
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for lagged_verdict_check
from _segment_features import segment_features
from _validation_drives import validation_positions
from lagged_verdict_check import at_once as at_once_detector

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
DEFAULT_FEATURES = (
    "offset_east,offset_north,residual_east,residual_north,clean_distance,fault_age_s,"
    "motion_nis,motion_speed"
)


def drives(args: argparse.Namespace) -> tuple[pd.DataFrame, ColumnMap]:
    """The labelled drives (simulated, or a validation split) and their column map."""
    if args.dataset is None:
        if args.hz is None:
            raise SystemExit("give --hz (simulated drives) or --dataset (a validation split)")
        sim = simulate_fleet(6, 15.0, args.hz, args.sim_seed, imu=False)
        table, cmap = sim[["track", "t", "lat", "lon"]], POSITIONS
    else:
        period = None if args.period == 0 else args.period
        picked = [
            (data, cmap)
            for name, data, _, cmap, _ in validation_positions(period, keep_native=True)
            if name == args.dataset
        ]
        if not picked:
            raise SystemExit(f"no validation split named {args.dataset!r}")
        table, cmap = picked[0]
    return inject_grad(table, seed=args.inject_seed, columns=cmap), cmap


def error_runs(
    truth: np.ndarray, flag: np.ndarray, track: np.ndarray
) -> list[tuple[int, int, str]]:
    """Runs of missed faulty fixes and of false positives within a track: (length, first
    row, kind), longest first."""
    runs = []
    wrong = flag != truth
    i = 0
    while i < len(truth):
        if not wrong[i]:
            i += 1
            continue
        j = i
        while j < len(truth) and wrong[j] and truth[j] == truth[i] and track[j] == track[i]:
            j += 1
        runs.append((j - i, i, "missed" if truth[i] else "false positive"))
        i = j
    return sorted(runs, key=lambda r: (-r[0], r[1]))


def drive_arguments(parser: argparse.ArgumentParser, *, simulated_only: bool = False) -> None:
    """The arguments :func:`drives` reads (which drives, which faults) and ``--model``;
    ``simulated_only``: ``--hz`` is required and there is no ``--dataset``/``--period``."""
    parser.add_argument(
        "--hz", type=float, required=simulated_only, help="simulated drives at this rate"
    )
    parser.add_argument("--sim-seed", type=int, default=4242)
    if simulated_only:
        parser.set_defaults(dataset=None, period=0.0)
    else:
        parser.add_argument("--dataset", default=None, help="a data set's validation split instead")
        parser.add_argument("--period", type=float, default=0.0, help="seconds; 0 = native")
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument("--model", default=None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    drive_arguments(parser)
    parser.add_argument("--row", type=int, default=None)
    parser.add_argument("--errors", action="store_true", help="list the longest error runs")
    parser.add_argument("--before", type=int, default=30)
    parser.add_argument("--after", type=int, default=30)
    parser.add_argument("--features", default=DEFAULT_FEATURES)
    args = parser.parse_args()
    det = Detector(args.model)
    labelled, cmap = drives(args)
    fixes = to_fixes(labelled, cmap)
    settled = det.detect(fixes)["anomaly"].to_numpy() == 1
    once = at_once_detector(det).detect(fixes)["anomaly"].to_numpy() == 1
    truth = labelled["label_anomaly"].to_numpy() == 1
    track = fixes["track"].to_numpy()
    if args.errors:
        print("| fixes | first row | kind |\n|---|---|---|")
        for n, first_row, kind in error_runs(truth, settled, track)[:12]:
            print(f"| {n} | {first_row} | {kind} |")
        return
    if args.row is None:
        raise SystemExit("give --row (or --errors)")
    rows = np.flatnonzero(track == track[args.row])
    names = pipeline_feature_names(det.model_.params)
    wanted = args.features.split(",")
    local = args.row - rows[0]
    for k, (seg, pts, values) in enumerate(segment_features(det, fixes.iloc[rows])):
        if not seg[0] <= local <= seg[-1]:
            continue
        east, north = pts["east"].to_numpy(), pts["north"].to_numpy()
        head = ["fix", "faulty", "at once", "settled", "bias", "time", "step E", "step N", *wanted]
        print(f"track {track[args.row]}, segment {k} (rows {rows[seg[0]]}..{rows[seg[-1]]})")
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        at = local - seg[0]
        for i in range(max(at - args.before, 1), min(at + args.after, len(seg))):
            g = rows[seg[i]]
            cells = [str(g), str(int(truth[g])), str(int(once[g])), str(int(settled[g]))]
            cells += [str(labelled["label_bias"].iloc[g]), str(labelled["label_time"].iloc[g])]
            cells += [f"{east[i] - east[i - 1]:.1f}", f"{north[i] - north[i - 1]:.1f}"]
            cells += [f"{values[i, names.index(f)]:.1f}" for f in wanted]
            print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
