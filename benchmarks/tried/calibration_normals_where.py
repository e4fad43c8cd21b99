"""Where the normal points a calibration group flags sit: one group of validation drives,
one rate band, every scored normal point at or above a threshold, read-only.

Why: :mod:`calibration_groups_at` says which group holds a rate band's threshold up;
this says what that group's flagged normal points are, so that a change of training
can answer the cause rather than the number. Per point: its track and index, the
confirm head's probability, the bias type the network gives it, the step speeds into
and out of it (m/s, from positions), and how many fixes after the last injected
faulty fix of its track it sits with that fault's bias (``-`` when none within 50).
The same validation faults and points as the calibration (stale starts' held fixes
and points without a score left out), the model calibrated as trained
(:func:`calibration_groups_at.as_trained`), read by the calibration's own
:func:`gradgps._train.calibrate.table_points`. Never a test split. Run:

    python benchmarks/tried/calibration_normals_where.py MODEL_DIR 0.936 driveplotr
        [--band slow|fast]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._grad.pipeline import O_BIAS, O_CONFIRM
from gradgps._train.calibrate import SLOW_FROM_PERIOD_S, recipe_group, table_points
from gradgps._train.recipe import recipe_faults, recipe_tables

sys.path.insert(0, str(Path(__file__).resolve().parent))
from calibration_groups_at import as_trained
from clean_flag_runs import step_speeds
from hangover_check import since_last_fault

_LOOK_BACK = 50


def after_fault(truth: np.ndarray, bias: np.ndarray, track: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per row: how many rows after its track's last faulty row it sits (1 = the next
    row; 0 on a faulty row; ``_LOOK_BACK + 1`` when there is none within
    ``_LOOK_BACK`` rows) and that row's bias (``-`` when none): hangover_check's
    :func:`since_last_fault` with a look-back."""
    since, last = since_last_fault(truth, track)
    none = (last < 0) | (since > _LOOK_BACK)
    last_bias = np.where(none, "-", np.asarray(bias, dtype=object)[np.maximum(last, 0)])
    return np.where(none, _LOOK_BACK + 1, since), last_bias.astype(object)


def group_normals(model: str, group: str, band: str) -> pd.DataFrame:
    """Every scored normal point of ``group`` in ``band`` (``slow``: periods >= 1.5 s)."""
    spec = recipe_faults()
    parts = []
    with tempfile.TemporaryDirectory() as scratch:
        det = as_trained(model, scratch)
        classes = np.array([*det.model_.output_bias_classes, "-"], dtype=object)
        for table in recipe_tables("validation"):
            if not any(recipe_group(x) == group for x in pd.unique(table["track"].astype(str))):
                continue
            tp = table_points(det, table, spec)
            labelled, out, row, period = tp.labelled, tp.out, tp.row, tp.period
            pts = tp.points.reset_index(drop=True)
            track = pts["track"].astype(str).to_numpy()
            truth = labelled["label_anomaly"].to_numpy() == 1
            since, last_bias = after_fault(
                truth,
                labelled["label_bias"].astype(str).to_numpy(),
                labelled["track"].astype(str).to_numpy(),
            )
            speed = step_speeds(pts.assign(track=track))
            slow = period >= SLOW_FROM_PERIOD_S
            keep = (
                tp.counted
                & np.isfinite(out[:, O_CONFIRM])
                & (slow if band == "slow" else ~slow)
                & np.array([recipe_group(x) == group for x in track])
            )
            keep &= ~truth[np.maximum(row, 0)]
            idx = np.flatnonzero(keep)
            code = out[idx, O_BIAS]
            parts.append(
                pd.DataFrame(
                    {
                        "track": track[idx],
                        "point": idx,
                        "confirm": out[idx, O_CONFIRM],
                        "bias": classes[np.where(np.isfinite(code), code, -1).astype(np.int64)],
                        "speed_in": speed[idx],
                        "speed_out": np.r_[speed[1:], np.nan][idx],
                        "after_fault": since[row[idx]],
                        "fault_bias": last_bias[row[idx]],
                    }
                )
            )
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model")
    parser.add_argument("threshold", type=float)
    parser.add_argument("group")
    parser.add_argument("--band", choices=("slow", "fast"), default="slow")
    args = parser.parse_args()
    normals = group_normals(args.model, args.group, args.band)
    high = normals[normals["confirm"] >= args.threshold]
    print(
        f"{args.model}: {args.group}, {args.band} band: {len(normals):,} scored normal points, "
        f"{len(high)} at or above {args.threshold:g} (normal recall {1 - len(high) / max(len(normals), 1):.4f})"
    )
    print()
    print(
        "| track | point | confirm | bias | step speed in m/s | out m/s | fixes after a fault | its bias |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in high.itertuples():
        after = r.after_fault if r.after_fault <= _LOOK_BACK else "-"
        print(
            f"| {r.track} | {r.point} | {r.confirm:.3f} | {r.bias} | {r.speed_in:.1f} "
            f"| {r.speed_out:.1f} | {after} | {r.fault_bias} |"
        )


if __name__ == "__main__":
    main()
