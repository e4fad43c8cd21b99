"""What the features say at the first normal fix after each injected fault (validation splits).

For tuning, never the test splits. Protocol ``grad`` (seed 0) on each real data
set's validation split, positions only (t, lat, lon), at the native rate (or
``--rate 0.5``). At every fault's end, the first normal fix (``--lag K``: the
K-th after it, when the fault has not restarted) is put in one of four groups
by two states the network reads there: does the offset tracker still hold an
offset above its threshold (``hold``/``ok``), and does the motion model reject
the fix (``gated``/``fits``)? Per group: the fault ends flagged by the
detector, of all, split by the ended fault's bias (noise, jump). Run:

    python benchmarks/fault_end_states.py [--model DIR] [--rate native|0.5] [--lag K]
"""

from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

from gradgps._data.datasets import load_dataset
from gradgps._data.inject import inject_grad
from gradgps._eval.robustness import _variant_columns, decimate
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.detector import Detector
from gradgps._grad.motion import MotionParams
from gradgps._grad.pipeline import grad_features, pipeline_feature_names
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import to_fixes

DATASETS = ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--rate", choices=("native", "0.5"), default="native")
    parser.add_argument("--lag", type=int, default=0)
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    det = Detector(args.model)
    params = det.model_.params
    names = pipeline_feature_names(params)
    offset_k, nis_k = names.index("offset_norm"), names.index("motion_nis")
    hold_m = 8.0  # an offset held above this counts as held (m)
    gate = (params.motion or MotionParams()).gate
    flagged: Counter[str] = Counter()
    total: Counter[str] = Counter()
    for name in DATASETS:
        table = load_dataset(name, "validation", data_dir=args.data_dir)
        picked = _variant_columns(table, to_fixes(table).attrs["columns"], "positions")
        assert picked is not None  # every data set has positions
        cols, cmap = picked
        data = table[cols] if args.rate == "native" else decimate(table[cols], cmap, 2.0)
        if args.rate != "native" and len(data) == len(table):
            continue  # natively 0.5 Hz
        labelled = inject_grad(data, seed=0, columns=cmap)
        faulty = labelled["label_anomaly"].to_numpy() == 1
        bias = labelled["label_bias"].to_numpy()
        fixes = to_fixes(labelled[cols], cmap)
        hit = det.detect(fixes)["anomaly"].to_numpy() == 1
        # The fixes and segments the Detector uses, and each point's first row.
        usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
        prepared = grad_points(fixes.iloc[usable], params.max_gap_s)
        pts = prepared.points
        first_row = np.full(len(pts), -1)
        for j, p in enumerate(prepared.row_point):
            if p >= 0 and first_row[p] < 0:
                first_row[p] = usable[j]
        t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
        nan = np.full(len(pts), np.nan)
        for k, sl in prepared.segment_slices():
            f = grad_features(
                params, prepared.segment_frames[k], t[sl], lat[sl], lon[sl], nan[sl], nan[sl]
            ).features
            f = np.sign(f) * np.expm1(np.abs(f))  # undo the signed log1p
            rows = first_row[sl]
            for i in range(1, len(rows) - args.lag):
                if not faulty[rows[i - 1]] or faulty[rows[i : i + args.lag + 1]].any():
                    continue
                j = i + args.lag
                group = (
                    ("hold" if f[j, offset_k] > hold_m else "ok")
                    + "/"
                    + ("gated" if f[j, nis_k] > gate else "fits")
                )
                for key in (group, f"{group}/{bias[rows[i - 1]]}"):
                    total[key] += 1
                    flagged[key] += int(hit[rows[j]])
    print(f"rate {args.rate}, lag {args.lag}: fault ends flagged / all, by state")
    print("| offset tracker / motion model / ended fault | flagged | fault ends |")
    print("|---|---|---|")
    for key in sorted(total):
        print(f"| {key} | {flagged[key]} | {total[key]} |")


if __name__ == "__main__":
    main()
