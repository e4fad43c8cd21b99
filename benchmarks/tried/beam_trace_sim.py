"""The offset tracker's beam, hypothesis by hypothesis, around fixes of a drive.

For reading why the tracker holds an offset (docs/deviations.md, "offset tracker: the
previous fix revised", the stop after a noise episode at 5 Hz): draws the drives and
faults as ``simulated_trace.py`` does (simulated at ``--hz``, or ``--dataset``'s
validation split), runs the readable reference
(:func:`gradgps._grad.offset._reference_channel`, its ``trace``) on one channel of the
detector's segment holding ``--row``, and prints at the rows asked for whether the fix
repeats the previous one exactly, the step, and the best five hypotheses as (mode 0/1/2
= clean/jump/outlier, offset m, track - fix m, velocity m/s, log-weight). Never the test
splits. Run:

    python benchmarks/tried/beam_trace_sim.py --hz 5 --sim-seed 555 --inject-seed 0 \\
        --row 17107 --channel north --show 17099,17100,17102,17110
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helpers
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for simulated_trace
from _segment_features import segment_features
from simulated_trace import drive_arguments, drives
from tracker_accuracy import beam_trace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    drive_arguments(parser)
    parser.add_argument("--row", type=int, required=True)
    parser.add_argument("--channel", choices=("east", "north"), default="north")
    parser.add_argument("--show", required=True, help="rows, comma-separated")
    args = parser.parse_args()
    det = Detector(args.model)
    labelled, cmap = drives(args)
    fixes = to_fixes(labelled, cmap)
    track = fixes["track"].to_numpy()
    rows = np.flatnonzero(track == track[args.row])
    segment = next(
        (seg, pts)
        for seg, pts, _ in segment_features(det, fixes.iloc[rows])
        if seg[0] <= args.row - rows[0] <= seg[-1]
    )
    seg, pts = segment
    z = pts[args.channel].to_numpy(np.float64)
    other = pts["north" if args.channel == "east" else "east"].to_numpy(np.float64)
    repeated = np.r_[False, (np.diff(z) == 0) & (np.diff(other) == 0)]  # shown per fix
    trace = beam_trace(det.model_.params.offset, pts, args.channel)
    show = {int(r) for r in args.show.split(",")}
    for i, beam in trace:
        row = int(rows[seg[i]])
        if row in show:
            best = [
                (
                    h.mode,
                    round(h.offset, 1),
                    round(float(h.track - z[i]), 1),
                    round(h.velocity, 1),
                    round(h.weight, 2),
                )
                for h in beam[:5]
            ]
            print(row, "repeated" if repeated[i] else "moved", f"step {z[i] - z[i - 1]:.2f}", best)


if __name__ == "__main__":
    main()
