"""What a model costs per fix, next to the shipped one (for model choice, issue 13/17).

Six simulated drives of 30 minutes at 1 Hz (seed 4242), positions only: batch
``Detector.detect`` (best of three runs) and a stream of ``Detector.update``
over one drive, in microseconds per fix, for the shipped model and each
``--model`` given. One process, on whatever core it runs; pin it
(``taskset -c 1``) and keep the machine otherwise idle for numbers to compare.
Run:

    python benchmarks/tried/model_speed.py --model DIR [--model DIR ...]
"""

from __future__ import annotations

import argparse
import time

from gradgps import Detector, simulate_fleet


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", action="append", default=[], help="model directory")
    args = parser.parse_args()
    drives = simulate_fleet(6, 30.0, 1.0, 4242, imu=False)[["track", "t", "lat", "lon"]]
    one = list(drives[drives["track"] == drives["track"].iloc[0]].itertuples(index=False))
    print("| model | batch us/fix | stream us/fix |")
    print("|---|---|---|")
    for model in [None, *args.model]:
        det = Detector(model)
        det.detect(drives.iloc[:50])  # compiled before the clock starts
        runs = []
        for _ in range(3):
            started = time.perf_counter()
            det.detect(drives)
            runs.append(time.perf_counter() - started)
        stream = Detector(model)
        for r in one[:20]:
            stream.update(r.t, r.lat, r.lon)
        stream = Detector(model)
        started = time.perf_counter()
        for r in one:
            stream.update(r.t, r.lat, r.lon)
        per_fix = (time.perf_counter() - started) / len(one)
        print(
            f"| {model or 'shipped'} | {1e6 * min(runs) / len(drives):.1f} | {1e6 * per_fix:.1f} |"
        )


if __name__ == "__main__":
    main()
