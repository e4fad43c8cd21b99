"""How far REMA's prediction strays from the fixes along one file, as the report draws it.

A user's check that REMA never drifts away from the track: for every segment
the Detector forms, REMA's bounds are driven point by point exactly as in
detection (:func:`gradgps._grad.pipeline.grad_features`, the same bounds the
HTML report draws), and the distance from the bounds' centre to each fix is
summarised: median, 99th percentile, maximum, and every run of fixes where
it exceeds ``--far`` metres, with the distance at the fix after the run (a
REMA that re-acquires is back near the track there). Run:

    python benchmarks/rema_excursions.py FILE.csv [--model DIR] [--far 50]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import grad_features
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import to_fixes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", help="CSV with t, lat, lon (and track) columns")
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--far", type=float, default=50.0, help="metres that count as far")
    args = parser.parse_args()
    params = Detector(args.model).model_.params
    fixes = to_fixes(pd.read_csv(args.file))
    usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
    prepared = grad_points(fixes.iloc[usable], params.max_gap_s)
    pts = prepared.points
    t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
    speed = heading = np.full(len(pts), np.nan)  # positions only, as the file gives them
    distances = []
    for k, sl in prepared.segment_slices():
        frame = prepared.segment_frames[k]
        bounds = grad_features(
            params, frame, t[sl], lat[sl], lon[sl], speed[sl], heading[sl]
        ).rema_bounds
        east, north = frame.to_local(lat[sl], lon[sl])
        centre_e = (bounds[:, 0] + bounds[:, 1]) / 2
        centre_n = (bounds[:, 2] + bounds[:, 3]) / 2
        d = np.hypot(centre_e - east, centre_n - north)
        distances.append(d[np.isfinite(d)])
        far = np.flatnonzero(d > args.far)
        for run in np.split(far, np.flatnonzero(np.diff(far) > 1) + 1) if far.size else []:
            after = d[run[-1] + 1] if run[-1] + 1 < d.size else float("nan")
            print(
                f"segment {k}: fixes {run[0]}-{run[-1]} ({run.size}) up to {d[run].max():.1f} m "
                f"from REMA's centre; at the next fix {after:.1f} m"
            )
    d_all = np.concatenate(distances)
    print(
        f"{len(distances)} segments, {d_all.size:,} fixes: REMA centre to fix median "
        f"{np.median(d_all):.1f} m, 99th percentile {np.percentile(d_all, 99):.1f} m, "
        f"max {d_all.max():.1f} m; {int((d_all > args.far).sum())} fixes farther than "
        f"{args.far:g} m"
    )


if __name__ == "__main__":
    main()
