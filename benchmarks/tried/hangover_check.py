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
    python benchmarks/tried/hangover_check.py --rates 0.5 --sim-minutes 60 --by-ended 5

``--sim-minutes`` sets the simulated drives' length (default 15). ``--by-ended N``
prints, for the simulated drives and each validation drive set (positions only,
native rate, or decimated to one fix per ``--period`` seconds) and pooled over N fault draws (seeds ``--inject-seed`` on), the false positives by how many fixes after an episode's
end they sit and by that episode's bias and time type (flagged of normal fixes).
Why: on drives long enough for protocol ``grad`` to end a permanent fault in
their middle (about 400 fixes or more), a permanent fault's end is where a
low-rate detector errs most.
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


def since_last_fault(faulty: np.ndarray, track: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per fix, how many fixes it sits after the last faulty fix of its track (0 on a
    faulty fix, -1 before any) and that fix's row (-1 before any)."""
    since = np.full(len(faulty), -1)
    last = np.full(len(faulty), -1)
    for rows in pd.Series(track).groupby(track, sort=False).indices.values():
        count, at = -1, -1
        for i in rows:
            if faulty[i]:
                count, at = 0, i
            elif count >= 0:
                count += 1
            since[i], last[i] = count, at
    return since, last


def fixes_since_fault(
    truth: np.ndarray, track: np.ndarray, bias: np.ndarray, kind: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Per fix, how many fixes it sits after the last faulty fix of its track (0 on a
    faulty fix, -1 before any) and that fix's ``"bias time"`` type ("" before any)."""
    since, last = since_last_fault(truth, track)
    ended = np.array([f"{bias[j]} {kind[j]}" if j >= 0 else "" for j in last], dtype=object)
    return since, ended


def by_ended(
    det: Detector, drives: pd.DataFrame, seeds: range, cmap: ColumnMap = POSITIONS
) -> pd.DataFrame:
    """Flagged / normal fixes by fixes since the last faulty fix of the same track (1, 2,
    3-5, 6-10, 11-30, over 30) and the bias and time type of that fix, over ``seeds``."""
    parts = []
    for seed in seeds:
        labelled = inject_grad(drives, seed=seed, columns=cmap)
        fixes = to_fixes(labelled, cmap)
        flag = det.detect(fixes)["anomaly"].to_numpy() == 1
        truth = labelled["label_anomaly"].to_numpy() == 1
        since, ended = fixes_since_fault(
            truth,
            fixes["track"].to_numpy(),
            labelled["label_bias"].to_numpy(dtype=object),
            labelled["label_time"].to_numpy(dtype=object),
        )
        keep = ~truth & (since > 0)
        parts.append(pd.DataFrame({"flag": flag[keep], "since": since[keep], "ended": ended[keep]}))
    df = pd.concat(parts)
    df["fixes after"] = pd.cut(
        df["since"], [0, 1, 2, 5, 10, 30, np.inf], labels=["1", "2", "3-5", "6-10", "11-30", ">30"]
    )
    table = df.groupby(["ended", "fixes after"], observed=True)["flag"].agg(["sum", "size"])
    cells = table["sum"].astype(int).astype(str) + " of " + table["size"].astype(str)
    return cells.unstack("fixes after").fillna("-")


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
    parser.add_argument("--sim-minutes", type=float, default=15.0)
    parser.add_argument("--by-ended", type=int, default=0, metavar="N")
    parser.add_argument(
        "--period", type=float, default=None, help="--by-ended: validation drives decimated"
    )
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument(
        "--simulated-only", action="store_true", help="leave the validation drives out"
    )
    args = parser.parse_args()
    det = Detector(args.model)
    if args.longest is not None:
        print(longest_run(det, args.longest, args.sim_seed, args.inject_seed))
        return
    if args.by_ended:
        for hz in (float(r) for r in args.rates.split(",")):
            drives = simulate_fleet(6, args.sim_minutes, hz, args.sim_seed, imu=False)
            seeds = range(args.inject_seed, args.inject_seed + args.by_ended)
            print(f"simulated {hz:g} Hz, 6 x {args.sim_minutes:g} min, fault draws {list(seeds)}")
            print(by_ended(det, drives[["track", "t", "lat", "lon"]], seeds).to_string())
            print()
        if args.simulated_only:
            return
        seeds = range(args.inject_seed, args.inject_seed + args.by_ended)
        drives_at = validation_positions(args.period, args.data_dir, keep_native=True)
        for name, data, _, cmap, _ in drives_at:
            rate = "native" if args.period is None else f"one fix per {args.period:g} s"
            print(f"{name} validation, positions only, {rate}, fault draws {list(seeds)}")
            print(by_ended(det, data, seeds, cmap).to_string())
            print()
        return
    print("| drives | false positives | hang-over runs | fixes in them | longest |")
    print("|---|---|---|---|---|")
    for hz in (float(r) for r in args.rates.split(",")):
        drives = simulate_fleet(6, args.sim_minutes, hz, args.sim_seed, imu=False)
        drives = drives[["track", "t", "lat", "lon"]]
        row = hangover(det, drives, POSITIONS, args.inject_seed)
        print(f"| simulated {hz:g} Hz | " + row)
    if args.simulated_only:
        return
    for name, data, _, cmap, _ in validation_positions(None, args.data_dir, keep_native=True):
        print(f"| {name} validation | " + hangover(det, data, cmap, args.inject_seed))


if __name__ == "__main__":
    main()
