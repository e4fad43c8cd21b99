"""How often the positions-only states misfire on clean real drives (validation splits).

For each real data set with a validation split, positions only (t, lat, lon),
at the native rate and decimated to 0.5 Hz: the share of fixes the motion
model dead-reckons through (``motion_run_s > 0``: it did not trust the fix)
and the share where the offset tracker holds a phantom offset above its
threshold. Neither state should fire on a clean drive; the GRU sees both.
With ``--injected``, protocol ``grad`` (seed 0) faults are injected first
and the shares count the *normal* fixes only: a state still firing there is
hang-over, a fault the detector has not let go of (issue 13: no state may
stay diverged after a fault ends). Validation splits only: these numbers are
for tuning. Run:

    python benchmarks/clean_states.py [--data-dir DIR] [--injected]
"""

from __future__ import annotations

import argparse

import numpy as np

from gradgps._data.datasets import load_dataset
from gradgps._data.inject import inject_grad
from gradgps._eval.robustness import _variant_columns, decimate
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import to_fixes

DATASETS = ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None)
    parser.add_argument(
        "--injected",
        action="store_true",
        help="inject protocol grad (seed 0) and count the normal fixes only",
    )
    args = parser.parse_args()
    params = PipelineParams()
    names = pipeline_feature_names(params)
    run_k, offset_k = names.index("motion_run_s"), names.index("offset_norm")
    threshold = 8.0  # m: an offset held above this on a clean fix is a phantom
    print("| data set | rate | fixes | motion model dead-reckons | phantom offset |")
    print("|---|---|---|---|---|")
    for name in DATASETS:
        table = load_dataset(name, "validation", data_dir=args.data_dir)
        picked = _variant_columns(table, to_fixes(table).attrs["columns"], "positions")
        assert picked is not None  # every data set has positions
        cols, cmap = picked
        for label, period in (("native", None), ("0.5 Hz", 2.0)):
            data = table[cols] if period is None else decimate(table[cols], cmap, period)
            normal = np.ones(len(data), bool)
            if args.injected:
                data = inject_grad(data, seed=0, columns=cmap)
                normal = data["label_anomaly"].to_numpy() == 0
            fixes = to_fixes(data[cols], cmap)  # one row per input row, in order
            # The fixes and segments the Detector uses: usable rows, then GRAD's preprocessing.
            usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
            prepared = grad_points(fixes.iloc[usable], params.max_gap_s)
            pts = prepared.points
            # A point is normal when every row it stands for is.
            normal_pts = np.ones(len(pts), bool)
            rows = prepared.row_point >= 0
            np.logical_and.at(normal_pts, prepared.row_point[rows], normal[usable][rows])
            t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
            nan = np.full(len(pts), np.nan)
            n = run = phantom = 0
            for k, sl in prepared.segment_slices():
                frame = prepared.segment_frames[k]
                f = grad_features(params, frame, t[sl], lat[sl], lon[sl], nan[sl], nan[sl]).features
                use = normal_pts[sl]
                # Features are compressed with a signed log1p; both are >= 0.
                run += int((np.expm1(f[use, run_k]) > 0).sum())
                phantom += int((np.expm1(f[use, offset_k]) > threshold).sum())
                n += int(use.sum())
            print(
                f"| {name} | {label} | {n:,} | {100 * run / n:.2f} % | {100 * phantom / n:.2f} % |"
            )


if __name__ == "__main__":
    main()
