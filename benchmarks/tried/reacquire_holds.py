"""How long the pipeline's offset tracker holds the 100-fix jump of
``tests/test_reacquire.py::test_a_100_fix_jump_then_clean_driving``, case by case.

Per case of that test (sampling period, speed, radius; a 150 m shift east on fixes
200-299 of a 600-fix drive, positions only, the test's own drive and features): the
share of the jump's fixes read with an offset above 8 m, how many of its first fixes
in a row, and how many fixes after its end still carry one (a phantom). With the
sources to judge on ``PYTHONPATH`` (a tracker change restates what the test may
assert):

    python benchmarks/tried/reacquire_holds.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
import test_reacquire as case


def main() -> None:
    print(
        "| period (s) | speed (m/s) | radius (m) | jump held | first fixes held | phantom fixes after |"
    )
    print("|---|---|---|---|---|---|")
    for period, speed, radius in case.CASES:
        t, east, north = case._drive(600, period, speed, radius, seed=1)
        shifted = east.copy()
        shifted[200:300] += 150.0
        norm = case._features(t, shifted, north)["offset_norm"]
        held = norm[200:300] > case.THRESHOLD_M
        first = int(np.argmin(held)) if not held.all() else held.size
        after = case._last_true(norm[300:] > case.THRESHOLD_M)
        print(f"| {period:g} | {speed:g} | {radius:g} | {held.mean():.2f} | {first} | {after} |")


if __name__ == "__main__":
    main()
