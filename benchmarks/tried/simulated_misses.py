"""Which injected faults a model misses on fresh simulated drives, by bias and time type.

``simulated_check.py`` gives one F1 per rate; when a model loses there, this says
where: the simulator (seeds the training recipe does not use) at one rate,
positions only, protocol ``grad`` (seed 0) on each simulator seed, and per bias
and time type the faulty fixes, the share flagged and the share of episodes'
first fixes flagged, for each ``--model`` (repeatable; ``default`` is the shipped
model). Never a test split. Run:

    python benchmarks/tried/simulated_misses.py --model default --model DIR [--rate 0.5]
        [--seeds 4242,11,123,31,808]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps import inject_grad, simulate_fleet
from gradgps._grad.detector import Detector

POSITIONS = ["track", "t", "lat", "lon"]


def recall_by_kind(labelled: pd.DataFrame, flagged: np.ndarray) -> pd.DataFrame:
    """Per (bias, time type) of the faulty rows: how many, the share flagged, and the
    share flagged among each run's first row (a run: consecutive faulty rows of a track)."""
    truth = labelled["label_anomaly"].to_numpy() == 1
    track = labelled["track"].to_numpy()
    new_track = np.r_[True, track[1:] != track[:-1]]
    first = truth & (new_track | np.r_[True, ~truth[:-1]])
    rows = pd.DataFrame(
        {
            "bias": labelled["label_bias"].astype(str).to_numpy(),
            "time": labelled["label_time"].astype(str).to_numpy(),
            "flagged": flagged,
            "first": first,
        }
    )[truth]
    out = rows.groupby(["bias", "time"]).agg(faulty=("flagged", "size"), recall=("flagged", "mean"))
    out["first_recall"] = rows[rows["first"]].groupby(["bias", "time"])["flagged"].mean()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", action="append", default=None)
    parser.add_argument("--rate", type=float, default=0.5, help="fixes per second")
    parser.add_argument("--seeds", default="4242,11,123,31,808", help="simulator seeds")
    parser.add_argument("--tracks", type=int, default=6)
    parser.add_argument("--minutes", type=float, default=15.0)
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    drives = [
        inject_grad(
            simulate_fleet(args.tracks, args.minutes, args.rate, s, imu=False)[POSITIONS], seed=0
        )
        for s in seeds
    ]
    print(
        f"simulator seeds {seeds}, {args.tracks} drives x {args.minutes:g} min each, "
        f"{args.rate:g} Hz, positions only, protocol grad seed 0"
    )
    print()
    print("| model | bias | time type | faulty fixes | flagged | first fixes flagged |")
    print("|---|---|---|---|---|---|")
    for model in args.model or ["default"]:
        det = Detector(None if model == "default" else model)
        parts = [
            (labelled, det.detect(labelled[POSITIONS])["anomaly"].to_numpy() == 1)
            for labelled in drives
        ]
        table = recall_by_kind(
            pd.concat([p[0] for p in parts], ignore_index=True),
            np.concatenate([p[1] for p in parts]),
        )
        for (bias, time), r in table.iterrows():
            print(
                f"| {model} | {bias} | {time} | {int(r.faulty)} | {r.recall:.3f} "
                f"| {r.first_recall:.3f} |"
            )


if __name__ == "__main__":
    main()
