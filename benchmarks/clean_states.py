"""How often the positions-only states misfire on clean real drives (validation splits).

For each real data set with a validation split, positions only (t, lat, lon),
at the native rate and decimated to 0.5 Hz: the share of fixes the motion
model dead-reckons through (``motion_run_s > 0``: it did not trust the fix)
and the share where the offset tracker holds a phantom offset above its
threshold. Neither state should fire on a clean drive; the GRU sees both.
Validation splits only: these numbers are for tuning. Run:

    python benchmarks/clean_states.py [--data-dir DIR]
"""

from __future__ import annotations

import argparse

import numpy as np

from gradgps._data.datasets import load_dataset
from gradgps._grad.offset import OffsetParams
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.geo import LocalFrame
from gradgps._tracks.thin import thin_mask

DATASETS = ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada")
TRACK = {"driveplotr": "drive", "tuc": "trace"}
TIME = {"tuc": "t_rel"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    params = PipelineParams()
    names = pipeline_feature_names(params)
    run_k, offset_k = names.index("motion_run_s"), names.index("offset_norm")
    threshold = OffsetParams().threshold_m
    print("| data set | rate | fixes | motion model dead-reckons | phantom offset |")
    print("|---|---|---|---|---|")
    for name in DATASETS:
        table = load_dataset(name, "validation", data_dir=args.data_dir)
        tracks = table[TRACK.get(name, "track")].astype(str).to_numpy(object)
        t_all = table[TIME.get(name, "t")].to_numpy(np.float64)
        for label, period in (("native", None), ("0.5 Hz", 2.0)):
            keep = np.ones(len(table), bool) if period is None else thin_mask(tracks, t_all, period)
            n = run = phantom = 0
            for track in np.unique(tracks[keep]):
                rows = keep & (tracks == track)
                t = t_all[rows]
                lat = table["lat"].to_numpy(np.float64)[rows]
                lon = table["lon"].to_numpy(np.float64)[rows]
                nan = np.full(t.size, np.nan)
                f = grad_features(
                    params, LocalFrame(lat[0], lon[0]), t, lat, lon, nan, nan
                ).features
                # Features are compressed with a signed log1p; both are >= 0.
                run += int((np.expm1(f[:, run_k]) > 0).sum())
                phantom += int((np.expm1(f[:, offset_k]) > threshold).sum())
                n += t.size
            print(
                f"| {name} | {label} | {n:,} | {100 * run / n:.2f} % | {100 * phantom / n:.2f} % |"
            )


if __name__ == "__main__":
    main()
