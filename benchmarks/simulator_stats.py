"""Compare the drive simulator with the real DrivePlotR drives (1 Hz) and print a markdown table.

Usage (from the repository root)::

    PYTHONPATH=src python benchmarks/simulator_stats.py [--data ../shared/data] [--tracks 40] [--minutes 15] [--seed 0]

The real column is every DrivePlotR drive; "real drives p5-p95" is the
spread of the statistic over 200 bootstrap resamples of whole real drives,
which shows how much the real value itself depends on which drives were
logged. docs/simulator.md holds the output and the machine it ran on.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.drive_stats import DISTRIBUTIONS, drive_statistics, summarize
from gradgps._data.simulator import simulate_fleet
from gradgps._tracks.track import to_fixes

REPO = Path(__file__).resolve().parents[1]


def load_real(data: Path) -> pd.DataFrame:
    """The DrivePlotR drives as canonical fixes (drive -> track, speed_mps -> speed ...)."""
    frame = pd.read_csv(data / "driveplotr_nds.csv")
    return to_fixes(frame)


def bootstrap_spread(
    real: pd.DataFrame, n: int = 200, seed: int = 0
) -> dict[str, tuple[float, ...]]:
    """p5 and p95 over drive-bootstrap resamples of each (median, p90, p99)."""
    rng = np.random.default_rng(seed)
    per_track = {k: g for k, g in real.groupby("track", sort=True)}
    ids = list(per_track)
    runs: dict[str, list[tuple[float, float, float]]] = {}
    for _ in range(n):
        pick = rng.choice(len(ids), len(ids), replace=True)
        sample = pd.concat(
            [per_track[ids[i]].assign(track=f"{j}") for j, i in enumerate(pick)], ignore_index=True
        )
        for name, value in summarize(drive_statistics(sample)).items():
            runs.setdefault(name, []).append(value)
    spread: dict[str, tuple[float, ...]] = {}
    for name, values in runs.items():
        arr = np.asarray(values)
        spread[name] = tuple(
            np.concatenate([np.percentile(arr, 5, axis=0), np.percentile(arr, 95, axis=0)])
        )
    return spread


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data",
        type=Path,
        default=Path(os.environ.get("GRADGPS_DATA", REPO.parent / "shared" / "data")),
    )
    parser.add_argument("--tracks", type=int, default=40)
    parser.add_argument("--minutes", type=float, default=15.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bootstrap", type=int, default=200)
    args = parser.parse_args(argv)

    started = time.perf_counter()
    sim = simulate_fleet(args.tracks, args.minutes, 1.0, args.seed)
    sim_seconds = time.perf_counter() - started
    real = load_real(args.data)
    sim_summary = summarize(drive_statistics(sim))
    real_summary = summarize(drive_statistics(real))
    spread = bootstrap_spread(real, args.bootstrap, args.seed)

    print(
        f"Simulated: {args.tracks} tracks x {args.minutes:g} min at 1 Hz, seed {args.seed} "
        f"({len(sim)} fixes, {sim_seconds:.2f} s). Real: DrivePlotR, {real['track'].nunique()} drives, "
        f"{len(real)} fixes.\n"
    )
    print(
        "| statistic | sim median | real median | sim p90 | real p90 | sim p99 | real p99 |"
        " real drives p5-p95 (median / p90 / p99) |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---|")
    for name in (*DISTRIBUTIONS, "stop_fraction", "zero_step_fraction"):
        s, r, b = sim_summary[name], real_summary[name], spread[name]
        if name in DISTRIBUTIONS:
            ranges = " / ".join(f"{b[i]:.3g}-{b[i + 3]:.3g}" for i in range(3))
            print(
                f"| {name} | {s[0]:.3g} | {r[0]:.3g} | {s[1]:.3g} | {r[1]:.3g} | {s[2]:.3g} | {r[2]:.3g} | {ranges} |"
            )
        else:
            print(f"| {name} | {s[0]:.3g} | {r[0]:.3g} | | | | | {b[0]:.3g}-{b[3]:.3g} |")
    print(
        f"\nMachine: {platform.platform()}, {platform.processor() or platform.machine()}, "
        f"Python {sys.version.split()[0]}, numpy {np.__version__}, pandas {pd.__version__}."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
