"""How often the training data shows a long fault *end*, by sampling rate.

The hypothesis tried (docs/deviations.md, "training data: longer simulated
drives at low rates", not kept): a network that only ever sees long faults run to
the end of their drive learns that a long fault never ends, and keeps flagging
clean fixes after one (``hangover_check.py`` found 50 fixes flagged after a
permanent jump on a simulated 0.5 Hz drive). Protocol ``grad`` places a permanent
fault (20-100 points) at the end of each 400-point stretch of a track, so on a
drive shorter than about 400 points every permanent fault runs to the drive's
end. This script injects the recipe's training tables once (protocol ``grad``,
seed 101, the first training seed) and counts, per source (simulated, real) and
sampling period, the fault runs of 20 fixes or more (either channel) and the
share followed by at least 10 clean fixes of the same track. ``--sim-minutes``
and ``--sim-tracks`` set the recipe's simulated drives (default: the recipe's
own); ``--sim-minutes`` takes one length, or one per rate with
``long_low_rate_drives.patch`` applied (the tried recipe: 40-minute drives at
0.5 Hz, 20 at 1 Hz). Train split only. Run:

    python benchmarks/tried/fault_endings.py
    git apply benchmarks/tried/long_low_rate_drives.patch   # then, on those sources:
    python benchmarks/tried/fault_endings.py
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._tracks.track import to_fixes
from gradgps._train.recipe import DefaultRecipe, recipe_tables


def long_faults(labelled: pd.DataFrame, min_points: int = 20, after: int = 10) -> pd.DataFrame:
    """One row per fault run of ``min_points`` or more: its track's period (s) and
    whether ``after`` clean fixes of the same track follow it."""
    rows = []
    for name, g in labelled.groupby("track", sort=False):
        y = g["label_anomaly"].to_numpy() == 1
        t = g["t"].to_numpy(np.float64)
        period = float(np.median(np.diff(t))) if len(t) > 1 else np.nan
        edges = np.diff(np.concatenate([[0], y.astype(np.int8), [0]]))
        for start, stop in zip(
            np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True
        ):
            if stop - start >= min_points:
                ended = stop + after <= len(y) and not y[stop : stop + after].any()
                source = "simulated" if str(name).startswith("sim") else "real"
                rows.append({"source": source, "period_s": round(period, 1), "ended": ended})
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sim-minutes", default=None, help="comma-separated, one per rate")
    parser.add_argument("--sim-tracks", default=None, help="comma-separated, one per rate")
    args = parser.parse_args()
    recipe = DefaultRecipe()
    if args.sim_minutes is not None:
        values = tuple(float(v) for v in args.sim_minutes.split(","))
        # One length for all rates (the shipped recipe) or one per rate (the patch).
        per_rate = isinstance(recipe.sim_minutes, tuple)
        recipe = replace(recipe, sim_minutes=values if per_rate else values[0])
    if args.sim_tracks is not None:
        recipe = replace(recipe, sim_tracks=tuple(int(v) for v in args.sim_tracks.split(",")))
    runs = []
    for table in recipe_tables("train", recipe):
        cmap = to_fixes(table).attrs["columns"]
        runs.append(long_faults(inject_grad(table, seed=101, columns=cmap)))
    counts = pd.concat(runs).groupby(["source", "period_s"])["ended"].agg(["size", "mean"])
    print(f"sim_minutes {recipe.sim_minutes}, sim_tracks {recipe.sim_tracks}")
    print("| drives | period s | faults of 20+ fixes | share followed by 10 clean fixes |")
    print("|---|---|---|---|")
    for (source, period), row in counts.iterrows():
        print(f"| {source} | {period:g} | {int(row['size'])} | {row['mean']:.2f} |")


if __name__ == "__main__":
    main()
