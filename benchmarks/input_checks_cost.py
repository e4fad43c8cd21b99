"""What the honest-input checks cost beside detection, in µs per fix.

``Detector.detect`` runs the checks once over the table it is given (its
:class:`gradgps.InputWarning`); the chunked CLI runs them chunk by chunk. This times, on
simulated drives (``--tracks`` x ``--minutes`` at 1 Hz, seed 7) with and without a speed
and heading: :func:`gradgps._tracks.input_checks.input_warnings` on the whole table, the
same fed in chunks of 200,000 rows, and ``Detector.detect_fixes`` (detection without the
checks), each the best of ``--repeats`` runs, one thread. Run:

    python benchmarks/input_checks_cost.py [--tracks N] [--minutes M] [--repeats K]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import pandas as pd

from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks, input_warnings
from gradgps._tracks.track import to_fixes


def best_us(run: Callable[[], object], rows: int, repeats: int) -> float:
    """The fastest of ``repeats`` runs, µs per row."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / rows


def chunked(fixes: pd.DataFrame) -> None:
    checks = InputChecks()
    for lo in range(0, len(fixes), 200_000):
        checks.add(fixes.iloc[lo : lo + 200_000])
    checks.warnings()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tracks", type=int, default=50)
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    drives = simulate_fleet(args.tracks, args.minutes, 1.0, 7, imu=False)
    det = Detector()
    print(f"{len(drives):,} fixes ({args.tracks} simulated drives x {args.minutes:g} min, 1 Hz)")
    print("| columns | checks, whole table | checks, chunks | detection | checks / detection |")
    print("|---|---|---|---|---|")
    for name, cols in (
        ("positions", ["track", "t", "lat", "lon"]),
        ("+speed+heading", ["track", "t", "lat", "lon", "speed", "heading"]),
    ):
        fixes = to_fixes(drives[cols])
        det.detect_fixes(fixes.iloc[:200])  # compile and load
        whole = best_us(lambda f=fixes: input_warnings(f), len(fixes), args.repeats)
        parts = best_us(lambda f=fixes: chunked(f), len(fixes), args.repeats)
        found = best_us(lambda f=fixes: det.detect_fixes(f), len(fixes), args.repeats)
        print(
            f"| {name} | {whole:.2f} µs | {parts:.2f} µs | {found:.2f} µs "
            f"| {100 * whole / found:.0f} % |"
        )


if __name__ == "__main__":
    main()
