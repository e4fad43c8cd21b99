"""Coordinates rounded on export: what the detector does, and what the input checks say.

GPX and CSV exports, old loggers and some NMEA talkers write fewer digits than
the receiver solved: 5 decimals of a degree (1.1 m north-south), 4 (11 m), or
minutes to 3 decimals (ddmm.mmm, 1.9 m). For every real validation drive
(positions only, native rate) the table says, per rounding, the share of clean
fixes the shipped model flags and the kinds of input warning
(:class:`gradgps._tracks.input_checks.InputChecks`). No fault is injected: every
flag is a false alarm. Never the test splits. Run:

    python benchmarks/coarse_coordinates.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Callable

import numpy as np
import pandas as pd
from _validation_drives import validation_positions

from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes


def minutes(decimals: int) -> Callable[[np.ndarray], np.ndarray]:
    """Degrees written as NMEA's degrees and minutes with ``decimals`` decimals of a minute."""

    def rounded(x: np.ndarray) -> np.ndarray:
        whole = np.trunc(x)
        return whole + np.round((x - whole) * 60.0, decimals) / 60.0

    return rounded


ROUNDINGS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "as recorded": lambda x: x,
    "6 decimals": lambda x: np.round(x, 6),
    "5 decimals": lambda x: np.round(x, 5),
    "4 decimals": lambda x: np.round(x, 4),
    "ddmm.mmm": minutes(3),
    "ddmm.mm": minutes(2),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model) if args.model else Detector()
    print("| drive | fixes | " + " | ".join(ROUNDINGS) + " |")
    print("|---|---|" + "---|" * len(ROUNDINGS))
    for name, table, cols, cmap, _ in validation_positions(None, args.data_dir, keep_native=True):
        fixes = to_fixes(table[cols], cmap)
        base = pd.DataFrame({c: fixes[c].to_numpy() for c in ("track", "t", "lat", "lon")})
        cells = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for rounded in ROUNDINGS.values():
                table_now = base.assign(
                    lat=rounded(base["lat"].to_numpy()), lon=rounded(base["lon"].to_numpy())
                )
                share = det.detect(table_now)["anomaly"].mean()
                kinds = [k for k, _ in InputChecks().add(to_fixes(table_now)).findings()]
                cells.append(f"{100 * share:.2f} % ({', '.join(kinds) or '-'})")
        print(f"| {name} | {len(base):,} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
