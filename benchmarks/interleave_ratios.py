"""The figures behind the ``interleaved sources`` input check (no detector involved).

Per real data set of ``../shared/data``, every split, at its own rate and decimated
to 0.5 Hz, clean and with protocol ``grad`` / ``gnss`` faults (seed 0): the median
second difference over consecutive fixes, over every other fix, and their ratio
(:meth:`gradgps._tracks.input_checks.InputChecks.interleaved`; the check wants 3).
Then the NL motorway validation receivers two by two, merged into one track with the
second's times shifted by 0.3 and 0.5 s (as ``benchmarks/merged_receivers.py`` does):
the same medians, and the quartiles of the merged steps. Run:

    python benchmarks/interleave_ratios.py [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from gradgps._data.datasets import DATASETS, TEST_ONLY, load_dataset
from gradgps._eval.robustness import decimate
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes
from gradgps.inject import inject_gnss, inject_grad


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    print("| data set | split | rate | faults | consecutive m | every other m | ratio |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for name in DATASETS:
        if name == "simulated":
            continue
        for split in ("test",) if name in TEST_ONLY else ("train", "validation", "test"):
            table = load_dataset(name, split, data_dir=args.data_dir)
            if table.empty:
                continue
            cmap = to_fixes(table).attrs["columns"]
            for rate, data in (("native", table), ("0.5 Hz", decimate(table, cmap, 2.0))):
                for faults in (None, inject_grad, inject_gnss):
                    seen = data
                    if faults is not None:
                        seen = faults(data, seed=0, columns=cmap)[list(data.columns)]
                    zigzag, smooth, _ = InputChecks().add(to_fixes(seen, cmap)).interleaved()
                    ratios.append(zigzag / smooth)
                    label = "-" if faults is None else faults.__name__.removeprefix("inject_")
                    print(
                        f"| {name} | {split} | {rate} | {label} | {zigzag:.2f} | {smooth:.2f} "
                        f"| {zigzag / smooth:.2f} |"
                    )
    print(f"\nratio over all {len(ratios)} rows: {min(ratios):.2f} - {max(ratios):.2f}\n")
    fixes = to_fixes(load_dataset("nl_motorway", "validation", data_dir=args.data_dir))
    print("| receivers | shift s | consecutive m | every other m | ratio | steps q25 / q75 s |")
    print("|---|---|---|---|---|---|")
    tracks = sorted(fixes["track"].unique())
    for segment in sorted({n.rsplit("_", 1)[1] for n in tracks}):
        here = [n for n in tracks if n.endswith("_" + segment)]
        for a, b in itertools.combinations(here, 2):
            pair = fixes[fixes["track"].isin([a, b])]
            for shift in (0.3, 0.5):
                moved = pair.assign(t=pair["t"] + shift * (pair["track"] == b), track="")
                merged = moved.sort_values("t", kind="stable").reset_index(drop=True)
                zigzag, smooth, _ = InputChecks().add(merged).interleaved()
                q25, q75 = np.percentile(np.diff(merged["t"].to_numpy()), [25, 75])
                names = " + ".join(n.removeprefix("trip02_") for n in (a, b))
                print(
                    f"| {names} | {shift:g} | {zigzag:.2f} | {smooth:.2f} | "
                    f"{zigzag / smooth:.2f} | {q25:.2f} / {q75:.2f} |"
                )


if __name__ == "__main__":
    main()
