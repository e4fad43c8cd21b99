"""The offset tracker alone on simulated drives from noisier receivers than a logger.

How often the tracker, without the network, holds an offset above 8 m on clean
fixes of an untouched drive ("clean phantom"), and, under protocol ``grad``
(seed 0), on normal fixes ("injected phantom") and how many jump fixes it holds
(``tracker_accuracy.py``'s definitions), per receiver (the simulator's logger and
the three noisier ones of ``receiver_noise_check.py``) and rate (1, 0.5, 5 Hz),
on six fresh 15-minute simulated drives (seed 4242, positions only). Run from the
repository root with the sources to judge on ``PYTHONPATH``:

    python benchmarks/tried/tracker_noise_check.py [--set K=V,...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.track import ColumnMap, to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from receiver_noise_check import RECEIVERS, receiver_drives
from tracker_accuracy import THRESHOLD_M, accuracy, tracker_offsets, tracker_settings

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="", help="tracker settings k=v,... over the defaults")
    args = parser.parse_args()
    params = PipelineParams()
    tracker = tracker_settings(params.offset, args.set)
    print(tracker)
    print("| receiver | rate | clean phantom | injected phantom | jump fixes held |")
    print("|---|---|---|---|---|")
    for name, noise in RECEIVERS:
        for hz in (1.0, 0.5, 5.0):
            sim = receiver_drives(noise, hz)
            clean = tracker_offsets(tracker, params.max_gap_s, to_fixes(sim, POSITIONS))
            labelled = inject_grad(sim, seed=0, columns=POSITIONS)
            held_offsets = tracker_offsets(tracker, params.max_gap_s, to_fixes(labelled, POSITIONS))
            phantom, held, _ = accuracy(labelled, sim, POSITIONS, held_offsets)
            print(
                f"| {name} | {hz:g} Hz | "
                f"{100 * np.mean((np.abs(clean) > THRESHOLD_M).any(axis=1)):.2f} % | "
                f"{100 * phantom:.2f} % | {100 * held:.1f} % |"
            )


if __name__ == "__main__":
    main()
