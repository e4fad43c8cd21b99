"""The offset tracker's beam, fix by fix, on one of the recipe's validation drives with the
calibration's faults: why it holds an offset there.

Per channel (east, north) and fix of points ``FIRST..LAST-1`` (counted over the track's
prepared points; the segment holding ``FIRST`` is traced from its start) of
track ``TRACK`` (a recipe validation track name, as
``calibration_false_positives.py`` lists them), injected as ``gradgps calibrate``
injects (protocol ``grad`` at the recipe's validation seed, frozen fixes, stale
starts): the fix, whether it repeats the previous one exactly, and the five best
hypotheses after it (mode C clean / J jump / N outlier, track, velocity, offset,
log-weight against the best), from the tracker's readable reference, with the model's
tracker settings and ``--set`` overrides. Never a test split. Run with the sources to
judge on ``PYTHONPATH``:

    python benchmarks/tried/recipe_beam_trace.py nl_motorway-trip02_phone_samsung_s9_01 427 437
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes
from gradgps._train.calibrate import inject_validation_faults
from gradgps._train.recipe import recipe_faults, recipe_tables

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for tracker_accuracy
from tracker_accuracy import beam_trace, tracker_settings


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("track")
    parser.add_argument("first", type=int)
    parser.add_argument("last", type=int)
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--set", default="", help="tracker settings k=v,... over the model's")
    args = parser.parse_args()
    det = Detector(args.model)
    spec = recipe_faults()
    table = next(
        t for t in recipe_tables("validation") if (t["track"].astype(str) == args.track).any()
    )
    cmap = to_fixes(table).attrs["columns"]
    labelled = inject_validation_faults(table, spec)
    labelled = labelled[labelled["track"].astype(str) == args.track].reset_index(drop=True)
    _, _, prepared, _ = det._point_outputs(to_fixes(labelled, cmap))
    sl = next(s for _, s in prepared.segment_slices() if s.start <= args.first < s.stop)
    first, last = args.first - sl.start, args.last - sl.start
    tracker = tracker_settings(det.model_.params.offset, args.set)
    pts = prepared.points.iloc[sl]
    east, north = pts["east"].to_numpy(np.float64), pts["north"].to_numpy(np.float64)
    repeated = np.r_[False, (np.diff(east) == 0) & (np.diff(north) == 0)]  # shown per fix
    for name, z in (("east", east), ("north", north)):
        trace = beam_trace(tracker, pts, name)
        print(f"channel {name}")
        for i, beam in trace:  # from the segment's second fix on
            if not first <= i < last:
                continue
            best = " | ".join(
                f"{'CJN'[int(h.mode)]} p={h.track:.1f} v={h.velocity:.1f} o={h.offset:.1f} "
                f"w={h.weight:.1f}"
                for h in beam[:5]
            )
            print(f"{i + sl.start} z={z[i]:.1f} repeated={int(repeated[i])} {best}")


if __name__ == "__main__":
    main()
