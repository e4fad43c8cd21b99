"""Where the errors sit on the real validation drives: which faults are missed, where
the false positives fall, and what the offset tracker says at the fix after a fault.

For choosing what to work on in issue 13, never the test splits. Per data set with
a validation split, positions only, at the native rate (``--period 0``, the
default) or decimated to one fix per ``--period`` seconds, protocol ``grad`` (seed
0), the shipped model (or ``--model``), settled verdicts:

* the injected faulty fixes by bias and time type: how many, how many missed, how
  many of the misses are an episode's first fix, and the median distance of the
  missed fixes from the truth (m);
* the false positives by how many fixes after an episode's end they sit (1, 2, ...,
  6 or more) and how many before the next episode's start (1 is a fix between two
  episodes);
* every fix right after an episode (its first normal fix), grouped by the ended
  episode's bias: how many, flagged at once, flagged settled; and the medians of
  the tracker's and motion model's features there, flagged settled against not.

Run:

    python benchmarks/tried/error_places.py [--period 0|2] [--model DIR] [--data-dir DIR]
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for lagged_verdict_check
from _segment_features import segment_features
from _validation_drives import validation_positions
from lagged_verdict_check import at_once as at_once_detector

FEATURES = ("offset_norm", "clean_distance", "fault_age_s", "motion_nis")
_M_PER_DEG = 111_320.0


def episode_distances(truth: np.ndarray, track: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per fix: its index inside its episode (-1 outside), and for normal fixes how
    many fixes after an episode's end and before the next one's start (a large number
    where there is none)."""
    inside = np.full(len(truth), -1)
    after = np.full(len(truth), 10**6)
    before = np.full(len(truth), 10**6)
    for name in pd.unique(track):
        rows = np.flatnonzero(track == name)
        k, since = -1, 10**6
        for i in rows:
            if truth[i]:
                k, since = k + 1, 0
                inside[i] = k
            else:
                k, since = -1, since + 1
                after[i] = since
        until = 10**6
        for i in rows[::-1]:
            until = 0 if truth[i] else until + 1
            if not truth[i]:
                before[i] = until
    return inside, after, before


def _after_features(det: Detector, fixes: pd.DataFrame, rows: np.ndarray) -> np.ndarray:
    """The :data:`FEATURES` (decompressed) at ``rows`` of ``fixes``."""
    names = pipeline_feature_names(det.model_.params)
    want = [names.index(f) for f in FEATURES]
    out = np.full((len(fixes), len(FEATURES)), np.nan)
    for seg_rows, _, values in segment_features(det, fixes):
        out[seg_rows] = values[:, want]
    return out[rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--period", type=float, default=0.0, help="seconds; 0 = native")
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    once_det = at_once_detector(det)
    period = None if args.period == 0 else args.period
    after_rows = []
    for name, data, _, cmap, _ in validation_positions(period, args.data_dir, keep_native=True):
        labelled = inject_grad(data, seed=0, columns=cmap)
        fixes = to_fixes(labelled, cmap)
        settled = det.detect(fixes)["anomaly"].to_numpy() == 1
        once = once_det.detect(fixes)["anomaly"].to_numpy() == 1
        truth = labelled["label_anomaly"].to_numpy() == 1
        track = fixes["track"].to_numpy()
        inside, after, before = episode_distances(truth, track)
        cos = np.cos(np.radians(data["lat"].to_numpy()))
        off = np.hypot(
            (labelled["lat"] - data["lat"]).to_numpy() * _M_PER_DEG,
            (labelled["lon"] - data["lon"]).to_numpy() * _M_PER_DEG * cos,
        )
        missed, false = truth & ~settled, settled & ~truth
        print(
            f"## {name}: {len(truth)} fixes, {truth.sum()} faulty, {missed.sum()} missed, "
            f"{false.sum()} false positives\n"
        )
        faulty = pd.DataFrame(
            {
                "bias": labelled["label_bias"].to_numpy()[truth],
                "time": labelled["label_time"].to_numpy()[truth],
                "missed": missed[truth],
                "missed_first": (missed & (inside == 0))[truth],
                "offset_missed": np.where(missed, off, np.nan)[truth],
            }
        )
        table = faulty.groupby(["bias", "time"]).agg(
            fixes=("missed", "size"),
            missed=("missed", "sum"),
            missed_first=("missed_first", "sum"),
            median_m_missed=("offset_missed", "median"),
        )
        print(table.round(1).to_string() + "\n")
        spots = np.minimum(after[false], 6), np.minimum(before[false], 6)
        print(
            "false positives, fixes after an episode's end (1..5, 6 or more): "
            f"{np.bincount(spots[0], minlength=7)[1:].tolist()}; before the next "
            f"episode's start: {np.bincount(spots[1], minlength=7)[1:].tolist()}\n"
        )
        first_after = np.flatnonzero(after == 1)
        ended = np.array([labelled["label_bias"].iloc[i - 1] for i in first_after], dtype=object)
        feats = _after_features(det, fixes, first_after)
        for j, i in enumerate(first_after):
            after_rows.append((name, ended[j], once[i], settled[i], *feats[j]))
    frame = pd.DataFrame(after_rows, columns=["data set", "ended", "at once", "settled", *FEATURES])
    print("## The first normal fix after an episode\n")
    counts = frame.groupby(["data set", "ended"]).agg(
        fixes=("at once", "size"), at_once=("at once", "sum"), settled=("settled", "sum")
    )
    print(counts.to_string() + "\n")
    medians = frame.groupby(["ended", "settled"])[list(FEATURES)].median()
    print("medians of the features there (settled: flagged or not):\n")
    print(medians.round(1).to_string())


if __name__ == "__main__":
    main()
