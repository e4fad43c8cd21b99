"""The real validation drives rewritten the ways users' files differ, detected clean.

Shared by ``coarse_coordinates.py`` and ``placeholder_speed.py``: per validation
drive (native rate) and per rewriting of its table, the share of fixes the model
flags (no fault injected: every flag is a false alarm) and the kinds of input
warning (:class:`gradgps._tracks.input_checks.InputChecks`). Never the test splits.
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Callable, Mapping

import pandas as pd
from _validation_drives import validation_positions

from gradgps._grad.detector import Detector
from gradgps._tracks.input_checks import InputChecks
from gradgps._tracks.track import to_fixes

Rewrite = Callable[[pd.DataFrame], pd.DataFrame]


def print_table(title: str, rewrites: Mapping[str, Rewrite], variant: str = "positions") -> None:
    """Parse ``--model``/``--data-dir`` and print the table of ``rewrites`` (name: a function
    of the canonical fixes ``track, t, lat, lon`` and, with ``variant`` ``+speed+heading``,
    ``speed, heading``) over the validation drives that have ``variant``'s columns."""
    parser = argparse.ArgumentParser(description=title)
    parser.add_argument("--model", default=None)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model) if args.model else Detector()
    roles = ["track", "t", "lat", "lon"] + (["speed", "heading"] if "+" in variant else [])
    print("| drive | fixes | " + " | ".join(rewrites) + " |")
    print("|---|---|" + "---|" * len(rewrites))
    drives = validation_positions(None, args.data_dir, keep_native=True, variant=variant)
    for name, table, cols, cmap, _ in drives:
        fixes = to_fixes(table[cols], cmap)
        base = pd.DataFrame({c: fixes[c].to_numpy() for c in roles})
        cells = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for rewrite in rewrites.values():
                rewritten = rewrite(base)
                share = det.detect(rewritten)["anomaly"].mean()
                kinds = [k for k, _ in InputChecks().add(to_fixes(rewritten)).findings()]
                cells.append(f"{100 * share:.2f} % ({', '.join(kinds) or '-'})")
        print(f"| {name} | {len(base):,} | " + " | ".join(cells) + " |", flush=True)
