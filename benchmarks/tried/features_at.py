"""The pipeline's features and a model's verdicts, fix by fix, on a stretch of a validation drive.

For looking at one event (issue 13: why a clean fix is flagged), never the test
splits. Positions only (t, lat, lon), the data set's validation split at its
native rate (or ``--period``'s): per fix of ``--rows`` (rows of the drive, within the
segment holding the first),
the step speed from the fixes, the chosen features (decompressed: metres,
seconds), the model's at-once flag and, with ``--confirm``, the confirm head's
verdict read at the next fix (``lagged_verdict_check.py --confirm``). Run:

    python benchmarks/tried/features_at.py --dataset nevada --rows 520:575 \\
        [--model DIR] [--confirm] [--features offset_norm,fault_age_s,...]
        [--period 2] [--inject-seed S]

``--period`` decimates the drive first; ``--inject-seed`` reads it with protocol
``grad`` faults of that seed (positions), to see what the pipeline saw in a missed fault.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._grad.pipeline import grad_features, pipeline_feature_names
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions
from lagged_verdict_check import at_once as at_once_detector
from lagged_verdict_check import confirmed

DEFAULT_FEATURES = "offset_norm,fault_age_s,clean_distance,motion_nis,motion_speed"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--rows", required=True, help="FIRST:LAST (LAST excluded)")
    parser.add_argument("--model", default=None)
    parser.add_argument("--confirm", action="store_true")
    parser.add_argument("--features", default=DEFAULT_FEATURES)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--period", type=float, default=0.0, help="decimate (s); 0 = native")
    parser.add_argument("--inject-seed", type=int, default=None, help="protocol grad seed")
    args = parser.parse_args()
    first, last = (int(v) for v in args.rows.split(":"))
    det = Detector(args.model)
    once = at_once_detector(det)
    names = pipeline_feature_names(det.model_.params)
    wanted = args.features.split(",")
    period = args.period if args.period > 0 else None
    for name, data, _, cmap, _ in validation_positions(period, args.data_dir, keep_native=True):
        if name != args.dataset:
            continue
        if args.inject_seed is not None:
            data = inject_grad(data, seed=args.inject_seed, columns=cmap)
        fixes = to_fixes(data, cmap)
        _, usable, prepared, _ = det._point_outputs(fixes)
        if len(prepared.points) != len(fixes):
            raise SystemExit("rows were merged or unusable here: point and row numbers differ")
        k, sl = next(
            ((k, sl) for k, sl in prepared.segment_slices() if sl.start <= first < sl.stop),
            next(iter(prepared.segment_slices())),
        )
        pts = prepared.points.iloc[sl]
        t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
        nan = np.full(len(t), np.nan)
        raw = grad_features(
            det.model_.params, prepared.segment_frames[k], t, lat, lon, nan, nan
        ).features
        values = np.sign(raw) * np.expm1(np.abs(raw))  # the pipeline's signed log1p undone
        east, north = pts["east"].to_numpy(), pts["north"].to_numpy()
        speed = np.r_[np.nan, np.hypot(np.diff(east), np.diff(north)) / np.diff(t)]
        at_once = once.detect(fixes)["anomaly"].to_numpy() == 1
        late = confirmed(det, fixes) if args.confirm else None
        print(f"{name}, segment {k}, rows {first}..{last - 1} of {len(usable)}")
        head = ["fix", "speed m/s", *wanted, "at once"] + (
            ["confirmed"] if late is not None else []
        )
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for row in range(first, min(last, sl.stop)):
            i = row - sl.start  # the row's place in its segment
            cells = [str(row), f"{speed[i]:.1f}"]
            cells += [f"{values[i, names.index(f)]:.2f}" for f in wanted]
            cells.append(str(int(at_once[row])))
            if late is not None:
                cells.append(str(int(late[row])))
            print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
