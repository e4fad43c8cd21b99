"""How right the positions-only motion model is, against the injected truth, without the network.

The motion model (``src/gradgps/_grad/motion.py``) says how surprising each step
is; the network reads it, and where no speed or heading is reported its velocity
stands in for them in REMA. A change to it changes the network's inputs, so
judging it by the detector's F1 needs a retrain. This judges the model's own
output instead, against what protocol ``grad`` (seed 0) wrote, positions only:

* **clean gated**: the share of normal fixes (no injected fault) the model
  rejects (dead-reckons through), on the injected drives and on the same drives
  untouched: a clean fix the model calls surprising;
* **clean after a fault**: the same share over the 1-10 normal fixes right after
  an episode ends, and the 95th percentile of their innovation (m): how far the
  model has strayed when the truth comes back;
* **noise accepted**: the share of fixes inside injected *noise* faults the
  model follows (not gated): an outlier taken for the track.

On fresh simulated drives at 10, 1 and 0.5 Hz (as ``tracker_accuracy.py`` draws
them) and the real validation drives (``--period 0``: native rate; ``--period 2``:
0.5 Hz), never the test splits. ``--set`` overrides settings (``--set gate=5``).
Run with the sources to judge on ``PYTHONPATH``:

    python benchmarks/tried/motion_accuracy.py [--period 0|2] [--set K=V,...]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_grad
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.motion import MOTION_FEATURES, MotionParams, motion_batch
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parent))
from error_places import episode_distances
from tracker_accuracy import drives

RUN = MOTION_FEATURES.index("motion_run_s")
INNOV = MOTION_FEATURES.index("motion_innovation")
REVISED = (
    MOTION_FEATURES.index("motion_previous_outlier")
    if "motion_previous_outlier" in MOTION_FEATURES
    else None
)
BINS = [1, 2, 4, 11, 31, 101, np.iinfo(np.int64).max]


def motion_outputs(params: MotionParams, max_gap_s: float, fixes: pd.DataFrame) -> np.ndarray:
    """Per fix of ``fixes``: the motion model's features on the detector's segments
    (NaN where a fix is dropped or opens a segment's first two fixes)."""
    out = np.full((len(fixes), len(MOTION_FEATURES)), np.nan)
    usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
    prepared = grad_points(fixes.iloc[usable], max_gap_s)
    values = np.full((len(prepared.points), len(MOTION_FEATURES)), np.nan)
    for _, sl in prepared.segment_slices():
        pts = prepared.points.iloc[sl]
        t = pts["t"].to_numpy(np.float64)
        east, north = (pts[c].to_numpy(np.float64) for c in ("east", "north"))
        period = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        seg = motion_batch(t, east, north, period, params)
        seg[:2] = np.nan
        values[sl] = seg
    out[usable] = prepared.to_rows(values, fill=np.nan)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--period", type=float, default=0.0, help="seconds; 0 = native")
    parser.add_argument("--set", default="", help="motion settings k=v,... over the defaults")
    args = parser.parse_args()
    params = PipelineParams()
    overrides = {k: float(v) for k, v in (kv.split("=") for kv in args.set.split(",") if kv)}
    motion = replace(params.motion or MotionParams(), **overrides)
    print(motion)
    print(
        "| drives | clean gated (untouched) | clean gated 1-10 after a fault |"
        " their innovation p95 m | noise accepted | clean gated 1 / 2-3 / 4-10 / 11-30 / 31-100 /"
        " more fixes after an episode |"
    )
    print("|---|---|---|---|---|---|")
    for name, table, cmap in drives(None if args.period == 0 else args.period):
        labelled = inject_grad(table, seed=0, columns=cmap)
        fixes = to_fixes(labelled, cmap)
        out = motion_outputs(motion, params.max_gap_s, fixes)
        clean_out = motion_outputs(motion, params.max_gap_s, to_fixes(table, cmap))
        faulty = labelled["label_anomaly"].to_numpy() == 1
        noise = (labelled["label_bias"].to_numpy() == "noise") & faulty
        _, after, _ = episode_distances(faulty, fixes["track"].to_numpy())
        seen = np.isfinite(out[:, RUN])
        normal = seen & ~faulty
        near = normal & (after >= 1) & (after <= 10)
        gated = out[:, RUN] > 0
        if REVISED is not None:  # a fix revised one fix later counts as rejected
            gated[:-1] |= np.nan_to_num(out[1:, REVISED]) > 0
        clean_gated = np.isfinite(clean_out[:, RUN])
        if REVISED is not None:
            clean_out[:-1, RUN] += np.nan_to_num(clean_out[1:, REVISED])
        print(
            f"| {name} | {100 * gated[normal].mean():.2f} % "
            f"({100 * (clean_out[clean_gated, RUN] > 0).mean():.2f} %) "
            f"| {100 * gated[near].mean():.1f} % ({near.sum():,}) "
            f"| {np.percentile(out[near, INNOV], 95):.1f} "
            f"| {100 * (~gated[noise & seen]).mean():.1f} % ({(noise & seen).sum():,}) "
            f"| {' / '.join(str(int(n)) for n in np.histogram(after[normal & gated], bins=BINS)[0])} |"
        )


if __name__ == "__main__":
    main()
