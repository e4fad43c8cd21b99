"""Where the flags on an untouched drive sit: each run of flagged fixes, positions only.

What a user sees first on a clean file (issue 13): how many fixes are flagged and
why. For a data set's split (``--dataset``, ``--split``; the test split is read
only to look at a number already measured) or any file with ``t``, ``lat``,
``lon`` (``--file``; a ``track`` column if it has several tracks): the shipped
model (or ``--model``) on t, lat, lon alone, then per run of flagged fixes its
rows, length, bias and time type, and the steps around it: the largest step
from the fix before the run to the fix after it, as a speed, against the median
step speed of the five fixes before. Run:

    python benchmarks/tried/clean_flag_runs.py --dataset austin2006 --split test
    python benchmarks/tried/clean_flag_runs.py --file drive.csv
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._grad.detector import Detector

_M_PER_DEG = 111_320.0


def step_speeds(frame: pd.DataFrame) -> np.ndarray:
    """Speed of the step into each fix (m/s) from its track's fix before; NaN at a track's
    first fix."""
    lat, lon, t = (frame[c].to_numpy(np.float64) for c in ("lat", "lon", "t"))
    north = np.diff(lat) * _M_PER_DEG
    east = np.diff(lon) * _M_PER_DEG * np.cos(np.radians(lat[1:]))
    speed = np.r_[np.nan, np.hypot(east, north) / np.diff(t)]
    new_track = np.r_[True, frame["track"].to_numpy()[1:] != frame["track"].to_numpy()[:-1]]
    speed[new_track] = np.nan
    return speed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset")
    parser.add_argument("--split", default="validation")
    parser.add_argument("--file")
    parser.add_argument("--model", default=None)
    args = parser.parse_args()
    if (args.dataset is None) == (args.file is None):
        parser.error("give --dataset or --file")
    table = load_dataset(args.dataset, args.split) if args.dataset else pd.read_csv(args.file)
    if "track" not in table:
        table = table.assign(track="1")
    frame = table[["track", "t", "lat", "lon"]].reset_index(drop=True)
    result = Detector(args.model).detect(frame)
    flagged = result["anomaly"].to_numpy() == 1
    speed = step_speeds(frame)
    rows = np.flatnonzero(flagged)
    runs = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1) if rows.size else []
    print(f"{int(flagged.sum()):,} of {len(frame):,} fixes flagged, in {len(runs)} runs")
    print("| rows | fixes | track | bias | time type | largest step speed m/s | speed before m/s |")
    print("|---|---|---|---|---|---|---|")
    for run in runs:
        first, last = int(run[0]), int(run[-1])
        around = speed[first : min(last + 2, len(frame))]
        before = speed[max(first - 5, 0) : first]
        print(
            f"| {first}-{last} | {len(run)} | {frame['track'].iloc[first]} "
            f"| {result['bias_type'].iloc[first]} | {result['time_type'].iloc[last]} "
            f"| {np.nanmax(around) if np.isfinite(around).any() else float('nan'):.1f} "
            f"| {np.nanmedian(before) if np.isfinite(before).any() else float('nan'):.1f} |"
        )


if __name__ == "__main__":
    main()
