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
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._data.inject import inject_grad
from gradgps._eval.robustness import _variant_columns, decimate
from gradgps._grad.offset import OffsetParams
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.geo import LocalFrame
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
    threshold = OffsetParams().threshold_m
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
            tracks = fixes["track"].to_numpy(object)
            n = run = phantom = 0
            for track in pd.unique(tracks):
                rows = tracks == track
                t = fixes["t"].to_numpy(np.float64)[rows]
                lat = fixes["lat"].to_numpy(np.float64)[rows]
                lon = fixes["lon"].to_numpy(np.float64)[rows]
                nan = np.full(t.size, np.nan)
                f = grad_features(
                    params, LocalFrame(lat[0], lon[0]), t, lat, lon, nan, nan
                ).features
                use = normal[rows]
                # Features are compressed with a signed log1p; both are >= 0.
                run += int((np.expm1(f[use, run_k]) > 0).sum())
                phantom += int((np.expm1(f[use, offset_k]) > threshold).sum())
                n += int(use.sum())
            print(
                f"| {name} | {label} | {n:,} | {100 * run / n:.2f} % | {100 * phantom / n:.2f} % |"
            )


if __name__ == "__main__":
    main()
