"""A model's verdicts on the validation drives, taken at once or one fix late (issue 13 experiment).

For model choice and experiments, never the test splits. Per real data set
with a validation split, positions only, native and 0.5 Hz: the share of the
untouched drive's fixes flagged, and the anomaly F1 and normal recall under
protocol ``grad`` (seed 0, or ``--inject-seed``'s), over the rows without a real ``glitch``. With
``--lag k`` the verdict for a fix is the model's flag ``k`` fixes later in the
same track (a model trained by ``lagged_verdict_train.py`` with that lag; the
last ``k`` fixes of a track take the flag at its last fix, the nearest there
is). With ``--confirm`` (a model trained with
``gradgps train --confirm-head``) the verdict for a fix is its confirm head's,
read at the next point of the same segment against ``thresholds.confirm``; a
segment's last point keeps the at-once verdict, and so does a fix the drift
witness flagged. ``--simulated`` scores fresh simulated drives instead, drawn
as ``benchmarks/simulated_check.py`` draws them (seed 4242, 6 drives of 15
minutes, positions only), at 0.5, 1, 5 and 10 Hz. ``--as-trained`` scores the
model at the thresholds its training chose on the pooled validation sequences
(``thresholds.pooled``) at every rate, not the per-rate ones ``gradgps train``
then calibrates: that calibration reads the network against each point's own
label, so for a network trained on labels moved later it is not the network's
rule. Run:

    python benchmarks/tried/lagged_verdict_check.py --model DIR [--lag K | --confirm] \
        [--as-trained] [--simulated] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._eval.metrics import class_scores
from gradgps._grad.detector import Detector
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions
from receiver_consensus import runs_of

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/tried/
from calibration_groups_at import as_trained


def at_once(det: Detector) -> Detector:
    """``det`` deciding every fix at once, also where its model has a confirm head (whose
    verdicts the pipeline settles one fix late)."""
    m = det.model_
    once = Detector(m.path)
    once.model_ = replace(m, params=replace(m.params, confirm_threshold=None))
    return once


def verdicts(det: Detector, fixes: pd.DataFrame, lag: int) -> np.ndarray:
    """Per row: the at-once flag ``lag`` fixes later in the same track (rows in track order)."""
    return flags_later(
        at_once(det).detect(fixes)["anomaly"].to_numpy() == 1,
        fixes["track"].astype(str).to_numpy(),
        lag,
    )


def flags_later(flag: np.ndarray, track: np.ndarray, lag: int) -> np.ndarray:
    """``flag[i + lag]`` where row ``i + lag`` is of row ``i``'s track, else the flag at the
    track's last row after ``i`` (a track's last ``lag`` rows have no later verdict)."""
    late = flag.copy()
    for _ in range(lag):  # one row at a time, never across a track's end
        late[:-1] = np.where(track[1:] == track[:-1], late[1:], late[:-1])
    return late


def confirmed(det: Detector, fixes: pd.DataFrame) -> np.ndarray:
    """Per row: the settled verdict, the pipeline's own for a model with a confirm head
    (:func:`gradgps._grad.pipeline.grad_step`; the module doc says the rule)."""
    m = det.model_
    if not m.params.settles(m.dims):
        raise SystemExit(f"--confirm needs a model with a confirm head; {m.path} has none")
    return det.detect(fixes)["anomaly"].to_numpy() == 1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True)
    parser.add_argument("--lag", type=int, default=0)
    parser.add_argument("--confirm", action="store_true")
    parser.add_argument("--as-trained", action="store_true")
    parser.add_argument("--inject-seed", type=int, default=0, help="protocol grad seed")
    parser.add_argument(
        "--clean-runs", action="store_true", help="list the runs of flagged clean fixes"
    )
    parser.add_argument("--simulated", action="store_true")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        det = as_trained(args.model, scratch) if args.as_trained else Detector(args.model)
        report(det, args)


def report(det: Detector, args: argparse.Namespace) -> None:
    """Print the table of :func:`main`'s cells for ``det``."""
    mode = (
        "confirm head, one point late"
        if args.confirm
        else (f"{args.lag} fix(es) late" if args.lag else "at once")
    )
    print(
        f"model {args.model}, verdict {mode}"
        + (", thresholds as trained" if args.as_trained else "")
    )

    def judge(fixes: pd.DataFrame) -> np.ndarray:
        return confirmed(det, fixes) if args.confirm else verdicts(det, fixes, args.lag)

    print("| data set | rate | clean false alarms | anomaly F1 | normal recall |")
    print("|---|---|---|---|---|")
    runs = []
    for name, rate, data, cols, cmap, ordinary in _drives(args.simulated, args.data_dir):
        flagged = judge(to_fixes(data, cmap))
        clean = flagged[ordinary]
        track = data[cmap.track].astype(str).to_numpy()
        runs += [(name, rate, *run) for run in flagged_runs(flagged & ordinary, track)]
        labelled = inject_grad(data, seed=args.inject_seed, columns=cmap)
        truth = (labelled["label_anomaly"].to_numpy() == 1)[ordinary]
        hit = judge(to_fixes(labelled[cols], cmap))[ordinary]
        scores = class_scores(truth, hit)
        f1, normal_recall = scores["anomaly"]["f1"], scores["normal"]["recall"]
        print(f"| {name} | {rate} | {100 * clean.mean():.2f} % | {f1:.3f} | {normal_recall:.3f} |")
    if args.clean_runs:
        print("\nflagged clean fixes, runs (data set, rate, track, first row, fixes):")
        for run in runs:
            print("  " + ", ".join(str(v) for v in run))


def flagged_runs(flag: np.ndarray, track: np.ndarray) -> list[tuple[str, int, int]]:
    """``(track, first row, length)`` of every run of consecutive flagged rows of one track."""
    return [(str(track[first]), first, length) for first, length in runs_of(flag, track)]


def _drives(simulated: bool, data_dir: str | None) -> Iterator[tuple[Any, ...]]:
    """``(name, rate, table, columns, column map, ordinary rows)`` of every cell."""
    if simulated:
        cmap = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
        cols = ["track", "t", "lat", "lon"]
        for hz in (0.5, 1.0, 5.0, 10.0):
            drives = simulate_fleet(6, 15.0, hz, 4242, imu=False)[cols]
            yield "simulated", f"{hz:g} Hz", drives, cols, cmap, np.ones(len(drives), bool)
        return
    for rate, period in (("native", None), ("0.5 Hz", 2.0)):
        for name, data, cols, cmap, ordinary in validation_positions(period, data_dir):
            yield name, rate, data, cols, cmap, ordinary


if __name__ == "__main__":
    main()
