"""A model on the real validation drives: clean false alarms and injected-fault F1.

For tuning and model choice (never the test splits): per real data set with a
validation split, in each column variant asked for (``--variant``, default
positions only: t, lat, lon; data sets without the variant's columns are
skipped), at the native rate and decimated to 0.5 Hz, the share of the
untouched drive's fixes flagged, and the anomaly F1 and normal recall under
protocol ``grad`` (seed 0), each scored as the robustness suite scores its
cells (:func:`gradgps._eval.robustness._cell`: a file's real glitches are
left out). ``--threshold`` overrides the model's own, to see what a
threshold choice costs. ``--repair`` adds the repair's columns: the RMS distance
of ``lat_clean/lon_clean`` from the untouched drive's fixes, and the repaired and
corrupted RMSE against the truth over the injected faulty fixes;
``--reach-m``/``--reach-accel`` override the recovery's reach
(:func:`gradgps._grad.recovery.within_reach`). Run:

    python benchmarks/validation_check.py [--model DIR] [--threshold P] [--data-dir DIR]
        [--variant positions|+speed|+speed+heading ...] [--repair]
        [--reach-m M] [--reach-accel A]
"""

from __future__ import annotations

import argparse
import dataclasses

import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._eval.robustness import _cell, _variant_columns, decimate
from gradgps._grad.detector import Detector
from gradgps._grad.recovery import RecoveryParams
from gradgps._tracks.track import ColumnMap, to_fixes

DATASETS = ("driveplotr", "tuc", "nl_motorway", "nl_motorway_gopro", "austin2006", "nevada")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--threshold", type=float, default=None)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument(
        "--variant",
        action="append",
        choices=("positions", "+speed", "+speed+heading"),
        help="column variant (repeatable; default positions)",
    )
    parser.add_argument("--repair", action="store_true", help="add the repair's columns")
    parser.add_argument("--reach-m", type=float, default=None)
    parser.add_argument("--reach-accel", type=float, default=None)
    args = parser.parse_args()
    det = Detector(args.model, threshold=args.threshold)
    recovery = with_reach(det, args.reach_m, args.reach_accel)
    print(f"recovery: {recovery}")
    head = "| data set | columns | rate | fixes | clean false alarms | anomaly F1 | normal recall |"
    rule = "|---|---|---|---|---|---|---|"
    if args.repair:
        head += " clean repair RMS m | repaired / corrupted RMSE m |"
        rule += "---|---|"
    print(head)
    print(rule)
    for name in DATASETS:
        table = load_dataset(name, "validation", data_dir=args.data_dir)
        full = to_fixes(table).attrs["columns"]
        for variant in args.variant or ["positions"]:
            picked = _variant_columns(table, full, variant)
            if picked is not None:
                _check(det, name, variant, table, picked, args.repair)


def with_reach(det: Detector, reach_m: float | None, reach_accel: float | None) -> RecoveryParams:
    """Set the recovery's reach of ``det``'s model where given (``None``: the model's
    own); returns the recovery settings it now has."""
    recovery = det.model_.params.recovery
    if reach_m is not None:
        recovery = dataclasses.replace(recovery, reach_m=reach_m)
    if reach_accel is not None:
        recovery = dataclasses.replace(recovery, reach_accel_mps2=reach_accel)
    det.model_ = dataclasses.replace(
        det.model_, params=dataclasses.replace(det.model_.params, recovery=recovery)
    )
    return recovery


def _check(
    det: Detector,
    name: str,
    variant: str,
    table: pd.DataFrame,
    picked: tuple[list[str], ColumnMap],
    repair: bool,
) -> None:
    """Print one data set's rows for one column variant."""
    cols, cmap = picked
    for rate, period in (("native", None), ("0.5 Hz", 2.0)):
        data = table if period is None else decimate(table, cmap, period)
        if period is not None and len(data) == len(table):
            continue  # natively 0.5 Hz
        cell = _cell(det, data, cols, cmap)
        false_alarms = cell["clean"]["false_alarm_rate"]
        f1 = cell["grad"]["anomaly"]["f1"]
        normal_recall = cell["grad"]["normal"]["recall"]
        line = (
            f"| {name} | {variant} | {rate} | {len(data):,} "
            f"| {100 * false_alarms:.2f} % | {f1:.3f} | {normal_recall:.3f} |"
        )
        if repair:
            g = cell["grad"]
            line += (
                f" {cell['clean']['repair_rms_m']:.2f} "
                f"| {g['recovery_rmse_m']:.1f} / {g['corrupted_rmse_m']:.1f} |"
            )
        print(line)


if __name__ == "__main__":
    main()
