"""How often a real receiver's reported speed and heading agree with its positions: the
numbers behind the input checks' ``reported speed`` / ``reported heading`` limits.

Per split of every real data set with a speed or heading (the test splits too: this
reads the data, no detector), clean and with protocol ``grad`` or ``gnss`` faults
injected (seed 0): the share of moving steps whose speed and heading agree with the
chords (:meth:`gradgps._tracks.input_checks.InputChecks.speed_agreement`,
``heading_agreement``), the typical ratio of reported to chord speed, and whether a
warning fires. Run:

    python benchmarks/witness_agreement.py [--data-dir DIR]
"""

from __future__ import annotations

import argparse

from gradgps._data.datasets import load_dataset
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes
from gradgps.inject import inject_gnss, inject_grad

DATASETS = ("driveplotr", "tuc", "nl_motorway_gopro", "nevada", "ublox_f9k")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    print(
        "| data set | split | faults | steps | speed agrees | typical ratio | heading agrees | warning |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in DATASETS:
        for split in ("train", "validation", "test"):
            if name == "ublox_f9k" and split != "test":
                continue  # test only
            table = load_dataset(name, split, data_dir=args.data_dir)
            cmap = to_fixes(table).attrs["columns"]
            for label, faults in (("none", None), ("grad", inject_grad), ("gnss", inject_gnss)):
                data = table if faults is None else faults(table, seed=0, columns=cmap)
                checks = InputChecks().add(to_fixes(data[list(table.columns)], cmap))
                share, typical, n = checks.speed_agreement()
                heading, _ = checks.heading_agreement()
                said = any(w.startswith("reported") for w in checks.warnings())
                print(
                    f"| {name} | {split} | {label} | {n:,} | {100 * share:.0f} % | {typical:.2f} "
                    f"| {'-' if heading != heading else f'{100 * heading:.0f} %'} | {said} |"
                )


if __name__ == "__main__":
    main()
