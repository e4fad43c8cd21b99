"""The offset tracker's beam, hypothesis by hypothesis, around fixes of a simulated drive.

For reading why the tracker holds an offset (docs/deviations.md, "offset tracker: the
previous fix revised", the stop after a noise episode at 5 Hz): runs the readable
reference (:func:`gradgps._grad.offset._reference_channel`, its ``trace``) on one
channel of the segment holding ``ROW`` of the simulated drives ``hangover_check.py``
draws (6 x 15 min at ``--hz``, simulator seed ``--sim-seed``, protocol ``grad`` seed
``--inject-seed``, positions only), and prints at the rows asked for whether the fix
repeats the previous one exactly, the step, and the best five hypotheses as (mode
0/1/2 = clean/jump/outlier, offset m, track - fix m, velocity m/s, log-weight). Never
the test splits. Run:

    python benchmarks/tried/beam_trace_sim.py --hz 5 --sim-seed 555 --inject-seed 0 \\
        --row 17107 --channel north --show 17099,17100,17102,17110
"""

from __future__ import annotations

import argparse

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.defaults import MIN_STEP_S, grad_points
from gradgps._grad.offset import _reference_channel
from gradgps._grad.pipeline import PipelineParams
from gradgps._tracks.preprocess import stream_reasons
from gradgps._tracks.track import ColumnMap, to_fixes

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, default=5.0)
    parser.add_argument("--sim-seed", type=int, default=555)
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument("--row", type=int, required=True)
    parser.add_argument("--channel", choices=("east", "north"), default="north")
    parser.add_argument("--show", required=True, help="rows, comma-separated")
    args = parser.parse_args()
    params = PipelineParams()
    drives = simulate_fleet(6, 15.0, args.hz, args.sim_seed, imu=False)
    labelled = inject_grad(
        drives[["track", "t", "lat", "lon"]], seed=args.inject_seed, columns=POSITIONS
    )
    fixes = to_fixes(labelled, POSITIONS)
    usable = np.flatnonzero(stream_reasons(fixes, min_step_s=MIN_STEP_S) == "")
    prepared = grad_points(fixes.iloc[usable], params.max_gap_s)
    at = int(np.searchsorted(usable, args.row))
    sl = next(s for _, s in prepared.segment_slices() if s.start <= at < s.stop)
    pts = prepared.points.iloc[sl]
    t = pts["t"].to_numpy(np.float64)
    z = pts[args.channel].to_numpy(np.float64)
    other = pts["north" if args.channel == "east" else "east"].to_numpy(np.float64)
    repeated = np.r_[False, (np.diff(z) == 0) & (np.diff(other) == 0)]
    trace: list = []
    _reference_channel(
        params.offset, np.diff(t, prepend=t[0]), z, np.full(len(z), np.nan), repeated, trace
    )
    show = {int(r) for r in args.show.split(",")}
    for i, beam in trace:
        row = int(usable[sl.start + i])
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
