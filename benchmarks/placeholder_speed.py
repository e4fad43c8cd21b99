"""A speed or heading column an export fills with zeros: what the detector does, what the checks say.

Exports often write a speed (and a heading) column whatever the receiver gave,
as zeros where it gave none. For every real validation drive with a reported
speed and heading (native rate), the share of clean fixes the shipped model
flags as recorded, with the speed set to 0, the heading set to 0, and both, and
the kinds of input warning (:class:`gradgps._tracks.input_checks.InputChecks`).
No fault is injected: every flag is a false alarm. Never the test splits. Run:

    python benchmarks/placeholder_speed.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import warnings

import pandas as pd
from _validation_drives import validation_positions

from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes

FILLS = {
    "as recorded": {},
    "speed 0": {"speed": 0.0},
    "heading 0": {"heading": 0.0},
    "both 0": {"speed": 0.0, "heading": 0.0},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model) if args.model else Detector()
    print("| drive | fixes | " + " | ".join(FILLS) + " |")
    print("|---|---|" + "---|" * len(FILLS))
    drives = validation_positions(None, args.data_dir, keep_native=True, variant="+speed+heading")
    for name, table, cols, cmap, _ in drives:
        fixes = to_fixes(table[cols], cmap)
        roles = ("track", "t", "lat", "lon", "speed", "heading")
        base = pd.DataFrame({c: fixes[c].to_numpy() for c in roles})
        cells = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for fill in FILLS.values():
                filled = base.assign(**fill)
                share = det.detect(filled)["anomaly"].mean()
                kinds = [k for k, _ in InputChecks().add(to_fixes(filled)).findings()]
                cells.append(f"{100 * share:.2f} % ({', '.join(kinds) or '-'})")
        print(f"| {name} | {len(base):,} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
