"""Two receivers in one file without a track column: what the detector does, what the checks say.

The NL motorway trips were logged by four receivers in one car at once. Merged
into one table by time with no track column (as a user might concatenate two
loggers' exports), two receivers' fixes alternate a few metres apart. For each
validation trip segment and each pair of receivers (positions only), the share of
rows the shipped model flags and the kinds of input warning
(:class:`gradgps._tracks.input_checks.InputChecks`), with the second receiver's
times as logged (most fixes share a timestamp with the first's) and shifted by
each of ``--shifts`` seconds (0.3 and 0.5 by default: the fixes interleave). No fault
is injected: every flag is a false alarm. Never the test splits. Run:

    python benchmarks/merged_receivers.py [--model DIR] [--data-dir DIR] [--shifts 0.3,0.5]
"""

from __future__ import annotations

import argparse
import itertools
import warnings

from gradgps._data.datasets import load_dataset
from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--shifts", default="0.3,0.5", help="seconds, comma-separated")
    args = parser.parse_args()
    shifts = [0.0] + [float(x) for x in args.shifts.split(",")]
    det = Detector(args.model) if args.model else Detector()
    fixes = to_fixes(load_dataset("nl_motorway", "validation", data_dir=args.data_dir))
    shifted = "".join(f" shifted {x:g} s | warnings |" for x in shifts[1:])
    print("| segment | receivers | rows | each alone | merged | warnings |" + shifted)
    print("|---|---|---|---|---|---|" + "---|---|" * (len(shifts) - 1))
    tracks = sorted(fixes["track"].unique())
    segments = sorted({name.rsplit("_", 1)[1] for name in tracks})
    for segment in segments:
        here = [name for name in tracks if name.endswith("_" + segment)]
        for a, b in itertools.combinations(here, 2):
            pair = fixes[fixes["track"].isin([a, b])][["track", "t", "lat", "lon"]]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                alone = det.detect(pair)["anomaly"].mean()
                cells = []
                for shift in shifts:
                    moved = pair.assign(t=pair["t"] + shift * (pair["track"] == b))
                    merged = moved.sort_values("t", kind="stable")[["t", "lat", "lon"]]
                    merged = merged.reset_index(drop=True)
                    share = det.detect(merged)["anomaly"].mean()
                    kinds = [k for k, _ in InputChecks().add(to_fixes(merged)).findings()]
                    cells.append(f"{100 * share:.2f} % | {', '.join(kinds) or '-'}")
            names = " + ".join(n.rsplit("_", 1)[0].removeprefix("trip02_") for n in (a, b))
            print(
                f"| {segment} | {names} | {len(pair):,} | {100 * alone:.2f} % | "
                + " | ".join(cells)
                + " |",
                flush=True,
            )


if __name__ == "__main__":
    main()
