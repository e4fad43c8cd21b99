"""How noisy the real drives' fixes are, against simulated receivers: the numbers behind the
``noisy fixes`` input warning and the noisy-receiver rows of docs/deviations.md.

Per real data set with train and validation splits (never a test split), and per
simulated receiver of ``receiver_noise_check.py`` (1 Hz, six 15-minute drives, seed
4242): the median and the lower quartile of the second differences the input checks compute,
on the clean drives and with protocol ``grad`` (seed 0) faults injected
(:meth:`gradgps._tracks.input_checks.InputChecks.second_difference_median` and
``second_difference_quartile``, which the warning reads: how far a fix lands from the
line its two predecessors draw, over evenly spaced triples, exact repeats left out of
the quartile, m), at the drives' own rate and decimated to 0.5 Hz, and whether the
warning fires. Run from the repository root:

    python benchmarks/tried/receiver_noise_levels.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._eval.robustness import decimate
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import ColumnMap, to_fixes
from gradgps.inject import inject_grad

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _validation_drives import DATASETS
from receiver_noise_check import RECEIVERS, receiver_drives


def main() -> None:
    print(
        "| drives | rate | median second difference m | lower quartile m | noisy-fixes warning "
        "| with faults: median m | quartile m | warning |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in DATASETS:
        for split in ("train", "validation"):
            table = load_dataset(name, split)
            cmap = to_fixes(table).attrs["columns"]
            for rate, data in (("native", table), ("0.5 Hz", decimate(table, cmap, 2.0))):
                _row(f"{name} {split}", rate, data, cmap)
    for name, noise in RECEIVERS:
        drives = receiver_drives(noise, 1.0)
        _row(f"simulated {name}", "1 Hz", drives, to_fixes(drives).attrs["columns"])


def _row(name: str, rate: str, table: pd.DataFrame, cmap: ColumnMap) -> None:
    cells = []
    faulty = inject_grad(table, seed=0, columns=cmap)[list(table.columns)]
    for data in (table, faulty):
        checks = InputChecks().add(to_fixes(data, cmap))
        noisy = any(w.startswith("noisy fixes") for w in checks.warnings())
        median = checks.second_difference_median()
        quartile = checks.second_difference_quartile()[0]
        cells.append(f"{median:.2f} | {quartile:.2f} | {noisy}")
    print(f"| {name} | {rate} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
