"""How noisy the real drives' fixes are, against simulated receivers: the numbers behind the
``noisy fixes`` input warning and the noisy-receiver rows of docs/deviations.md.

Per real data set with train and validation splits (never a test split), and per
simulated receiver of ``receiver_noise_check.py`` (1 Hz, six 15-minute drives, seed
4242): the median second difference the input checks compute
(:meth:`gradgps._tracks.input_checks.InputChecks.second_difference_median`: how far a
fix lands from the line its two predecessors draw, over evenly spaced triples, m) and
whether the warning fires. Run from the repository root:

    python benchmarks/tried/receiver_noise_levels.py
"""

from __future__ import annotations

import sys
from pathlib import Path

from gradgps._data.datasets import load_dataset
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
from _validation_drives import DATASETS
from receiver_noise_check import RECEIVERS, receiver_drives


def main() -> None:
    print("| drives | median second difference m | noisy-fixes warning |")
    print("|---|---|---|")
    for name in DATASETS:
        for split in ("train", "validation"):
            checks = InputChecks().add(to_fixes(load_dataset(name, split)))
            noisy = any(w.startswith("noisy fixes") for w in checks.warnings())
            print(f"| {name} {split} | {checks.second_difference_median():.2f} | {noisy} |")
    for name, noise in RECEIVERS:
        checks = InputChecks().add(to_fixes(receiver_drives(noise, 1.0)))
        noisy = any(w.startswith("noisy fixes") for w in checks.warnings())
        print(f"| simulated {name}, 1 Hz | {checks.second_difference_median():.2f} | {noisy} |")


if __name__ == "__main__":
    main()
