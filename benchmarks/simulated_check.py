"""A model on fresh simulated drives: clean false alarms, injected-fault F1 and normal recall.

A third opinion next to the real validation drives (``validation_check.py``)
for tuning and model choice, never the test splits: the project's simulator
(``gradgps simulate``) with a seed the training recipe does not use (its
drives are seeds 30,000-30,041), positions only (t, lat, lon), at 0.5, 1 and
5 Hz, protocol ``grad`` (seed 0). The real validation drives are few, and the
threshold and best epoch were chosen on them; these drives were not. Run:

    python benchmarks/simulated_check.py [--model DIR] [--seed N] [--tracks N] [--minutes M]
"""

from __future__ import annotations

import argparse

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._result import f1_score
from gradgps._tracks.track import ColumnMap, to_fixes

RATES_HZ = (0.5, 1.0, 5.0)
POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--seed", type=int, default=4242, help="simulator seed (default 4242)")
    parser.add_argument("--tracks", type=int, default=6)
    parser.add_argument("--minutes", type=float, default=15.0)
    args = parser.parse_args()
    det = Detector(args.model)
    print(
        f"simulator seed {args.seed}, {args.tracks} drives x {args.minutes:g} min, positions only"
    )
    print("| rate | fixes | clean false alarms | anomaly F1 | normal recall |")
    print("|---|---|---|---|---|")
    for rate in RATES_HZ:
        drives = simulate_fleet(args.tracks, args.minutes, rate, args.seed, imu=False)
        table = drives[["track", "t", "lat", "lon"]]
        clean = det.detect(to_fixes(table, POSITIONS))
        false_alarms = float(np.mean(clean["anomaly"].to_numpy() == 1))
        labelled = inject_grad(table, seed=0, columns=POSITIONS)
        result = det.detect(to_fixes(labelled, POSITIONS))
        truth = labelled["label_anomaly"].to_numpy() == 1
        flagged = result["anomaly"].to_numpy() == 1
        print(
            f"| {rate:g} Hz | {len(table):,} | {100 * false_alarms:.2f} % "
            f"| {f1_score(truth, flagged):.3f} | {float(np.mean(~flagged[~truth])):.3f} |"
        )


if __name__ == "__main__":
    main()
