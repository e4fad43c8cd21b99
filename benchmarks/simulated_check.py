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

from gradgps._data.simulator import simulate_fleet
from gradgps._eval.robustness import _cell
from gradgps._grad.detector import Detector
from gradgps._tracks.track import ColumnMap

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
        cell = _cell(det, drives, ["track", "t", "lat", "lon"], POSITIONS)
        print(
            f"| {rate:g} Hz | {len(drives):,} | {100 * cell['clean']['false_alarm_rate']:.2f} % "
            f"| {cell['grad']['anomaly']['f1']:.3f} | {cell['grad']['normal']['recall']:.3f} |"
        )


if __name__ == "__main__":
    main()
