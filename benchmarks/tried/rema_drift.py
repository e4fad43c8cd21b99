"""Whether REMA's prediction stays on the track: the distance from each fix to the middle
of its REMA bounds, as the report draws them, on any file of fixes.

A user's check (issue 13: "the REMA prediction drifts kilometres away after one false
permanent fault and never comes back"): per file, the median, 99th percentile and
largest distance (m, both channels), and every run of fixes where it exceeds
``--far`` metres (default 50) with its length: a run that ends is a re-acquisition, one
that lasts to the end of a segment a drift. Bounds from
:func:`gradgps._run.report.rema_bounds` with the shipped model (or ``--model``). Run:

    python benchmarks/tried/rema_drift.py FILE.csv [FILE ...] [--far 50] [--model DIR]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps._grad.detector import Detector
from gradgps._run.report import rema_bounds
from gradgps._tracks.track import to_fixes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--far", type=float, default=50.0)
    parser.add_argument("--model", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    for path in args.files:
        fixes = to_fixes(pd.read_csv(path))
        _, _, prepared, _ = det._point_outputs(fixes)
        segments = [k for k, _ in prepared.segment_slices()]
        quiet = np.zeros(len(prepared.points), dtype=bool)
        distances, runs = [], []
        for cb in rema_bounds(prepared, det.model_.params, quiet, segments):
            far = np.zeros(len(cb.t), dtype=bool)
            for z, lo, hi in (
                (cb.east, cb.east_lower, cb.east_upper),
                (cb.north, cb.north_lower, cb.north_upper),
            ):
                d = np.abs(z - (lo + hi) / 2)
                distances.append(d[np.isfinite(d)])
                far |= d > args.far
            idx = np.flatnonzero(far)
            for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1) if idx.size else []:
                end = "to the segment's end" if run[-1] == len(cb.t) - 1 else "ends"
                runs.append(f"segment {cb.segment} fixes {run[0]}-{run[-1]} ({run.size}, {end})")
        d = np.concatenate(distances)
        print(
            f"{path}: {len(segments)} segments; |fix - REMA prediction| median {np.median(d):.2f} m, "
            f"99th percentile {np.percentile(d, 99):.1f} m, largest {d.max():.1f} m; "
            f"runs beyond {args.far:g} m: {'; '.join(runs) or 'none'}"
        )


if __name__ == "__main__":
    main()
