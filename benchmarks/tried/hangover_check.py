"""Where the false positives sit: right after an injected fault's end (hang-over) or not.

For each injected episode (protocol ``grad``, seed 0, positions only), the
run of *normal* fixes flagged right after the episode's last fix: how many
such runs, how many fixes they hold against all false positives, and the
longest in fixes and seconds. On fresh simulated drives (seed 4242, 6 x 15
minutes, as ``benchmarks/simulated_check.py`` draws them) at 10, 5 and 1 Hz,
and on the real validation drives at their native rate. The shipped model
unless ``--model``. Never the test splits. ``--sim-seed`` and ``--inject-seed``
draw other simulated drives and other faults (training's simulated drives use
seeds from 30,000 up). Run:

    python benchmarks/tried/hangover_check.py [--model DIR] [--data-dir DIR]
        [--rates 10,5,1,0.5] [--sim-seed N] [--inject-seed K] [--simulated-only]
    python benchmarks/tried/hangover_check.py --longest 10   # the longest run, described
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
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")


def hangover(det: Detector, table: pd.DataFrame, cmap: ColumnMap, inject_seed: int = 0) -> str:
    """One table row: false positives, hang-over runs, their fixes, the longest."""
    labelled = inject_grad(table, seed=inject_seed, columns=cmap)
    fixes = to_fixes(labelled, cmap)
    flag = det.detect(fixes)["anomaly"].to_numpy() == 1
    truth = labelled["label_anomaly"].to_numpy() == 1
    track = fixes["track"].to_numpy()
    t = fixes["t"].to_numpy(np.float64)
    runs: list[tuple[int, float]] = []
    for name in pd.unique(track):
        rows = np.flatnonzero(track == name)
        f, y, tt = flag[rows], truth[rows], t[rows]
        for i in range(len(rows)):
            if y[i] and (i + 1 == len(rows) or not y[i + 1]):  # an episode ends at i
                j = i + 1
                while j < len(rows) and f[j] and not y[j]:
                    j += 1
                if j > i + 1:
                    runs.append((j - i - 1, tt[j - 1] - tt[i]))
    fixes_in = sum(n for n, _ in runs)
    longest = max(runs, default=(0, 0.0))
    return (
        f"{int((flag & ~truth).sum())} | {len(runs)} | {fixes_in} | "
        f"{longest[0]} fixes, {longest[1]:.1f} s |"
    )


def longest_run(det: Detector, hz: float, sim_seed: int = 4242, inject_seed: int = 0) -> str:
    """The simulated drives' longest hang-over run at ``hz``: the episode before it (its
    fixes, how many of them flagged, the last flagged one) and the run's length."""
    drives = simulate_fleet(6, 15.0, hz, sim_seed, imu=False)[["track", "t", "lat", "lon"]]
    labelled = inject_grad(drives, seed=inject_seed, columns=POSITIONS)
    fixes = to_fixes(labelled, POSITIONS)
    flag = det.detect(fixes)["anomaly"].to_numpy() == 1
    truth = labelled["label_anomaly"].to_numpy() == 1
    track = fixes["track"].to_numpy()
    best = (0, 0, 0)  # run length, episode start, episode end (rows of fixes)
    for name in pd.unique(track):
        rows = np.flatnonzero(track == name)
        f, y = flag[rows], truth[rows]
        for i in range(len(rows)):
            if y[i] and (i + 1 == len(rows) or not y[i + 1]):
                j = i + 1
                while j < len(rows) and f[j] and not y[j]:
                    j += 1
                start = i
                while start > 0 and y[start - 1]:
                    start -= 1
                best = max(best, (j - i - 1, int(rows[start]), int(rows[i])))
    n, start, end = best
    inside = flag[start : end + 1]
    last = int(np.flatnonzero(inside)[-1]) + 1 if inside.any() else 0
    return (
        f"simulated {hz:g} Hz, longest run after a fault: {n} fixes, after an episode of "
        f"{end - start + 1} fixes ({labelled['label_bias'].iloc[end]}, "
        f"{labelled['label_time'].iloc[end]}) of which {int(inside.sum())} flagged, the "
        f"last flagged its fix {last}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument(
        "--longest", type=float, metavar="HZ", help="describe the longest run at this rate"
    )
    parser.add_argument("--rates", default="10,5,1", help="simulated rates, Hz, comma-separated")
    parser.add_argument("--sim-seed", type=int, default=4242)
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument(
        "--simulated-only", action="store_true", help="leave the validation drives out"
    )
    args = parser.parse_args()
    det = Detector(args.model)
    if args.longest is not None:
        print(longest_run(det, args.longest, args.sim_seed, args.inject_seed))
        return
    print("| drives | false positives | hang-over runs | fixes in them | longest |")
    print("|---|---|---|---|---|")
    for hz in (float(r) for r in args.rates.split(",")):
        drives = simulate_fleet(6, 15.0, hz, args.sim_seed, imu=False)
        drives = drives[["track", "t", "lat", "lon"]]
        row = hangover(det, drives, POSITIONS, args.inject_seed)
        print(f"| simulated {hz:g} Hz | " + row)
    if args.simulated_only:
        return
    for name, data, _, cmap, _ in validation_positions(None, args.data_dir, keep_native=True):
        print(f"| {name} validation | " + hangover(det, data, cmap, args.inject_seed))


if __name__ == "__main__":
    main()
