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

from collections.abc import Callable

import numpy as np
from _clean_variants import Rewrite, print_table


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


def _rounding(rounded: Callable[[np.ndarray], np.ndarray]) -> Rewrite:
    """The fixes with their latitudes and longitudes written by ``rounded``."""
    return lambda t: t.assign(lat=rounded(t["lat"].to_numpy()), lon=rounded(t["lon"].to_numpy()))


if __name__ == "__main__":
    print_table(__doc__.splitlines()[0], {name: _rounding(r) for name, r in ROUNDINGS.items()})
