"""The offset tracker's beam, fix by fix, on a validation drive with protocol ``grad`` faults.

For reading why the tracker lets an injected fault go (issue 13), never the test
splits: the data set's validation split, positions only, decimated to one fix per
``--period`` seconds (0: native), protocol ``grad`` with ``--inject-seed``; the
readable tracker (:func:`gradgps._grad.offset._reference_channel`, tested equal to
the kernel) runs on the segment holding ``--rows``' first row in one ``--channel``
with the shipped model's settings (or ``--model``'s), and prints, per row of
``--rows``, the fix and the ``--show`` best hypotheses: mode (0 clean, 1 jump, 2
outlier), log-weight against the best, track, velocity, offset and fault age. Run:

    python benchmarks/tried/injected_beam_trace.py --dataset austin2006 --period 2 \\
        --inject-seed 4 --channel north --rows 763:768 [--show 6] [--model DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for tracker_accuracy
from tracker_accuracy import beam_trace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--period", type=float, default=0.0)
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument("--channel", choices=("east", "north"), default="north")
    parser.add_argument("--rows", required=True, help="FIRST:LAST (LAST excluded)")
    parser.add_argument("--show", type=int, default=6)
    parser.add_argument("--model", default=None)
    args = parser.parse_args()
    first, last = (int(v) for v in args.rows.split(":"))
    det = Detector(args.model)
    period = args.period if args.period > 0 else None
    for name, data, _, cmap, _ in validation_positions(period, None, keep_native=True):
        if name != args.dataset:
            continue
        fixes = to_fixes(inject_grad(data, seed=args.inject_seed, columns=cmap), cmap)
        _, _, prepared, _ = det._point_outputs(fixes)
        if len(prepared.points) != len(fixes):
            raise SystemExit("rows were merged or unusable here: point and row numbers differ")
        k, sl = next((k, sl) for k, sl in prepared.segment_slices() if sl.start <= first < sl.stop)
        pts = prepared.points.iloc[sl]
        z = pts[args.channel].to_numpy(np.float64)
        trace = beam_trace(det.model_.params.offset, pts, args.channel)
        print(f"{name}, segment {k} (rows {sl.start}-{sl.stop - 1}), {args.channel}")
        for i, beam in trace:
            row = i + sl.start
            if first <= row < last:
                print(f"row {row}: fix {z[i]:.1f} m")
                for h in beam[: args.show]:
                    print(
                        f"    mode {h.mode:.0f}  w {h.weight:7.2f}  track {h.track:8.1f}  "
                        f"v {h.velocity:6.2f}  offset {h.offset:7.1f}  age {h.age:5.1f} s"
                    )


if __name__ == "__main__":
    main()
