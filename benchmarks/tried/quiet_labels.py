"""How many faulty training points look clean to every feature a latch could learn from.

If protocol ``grad`` labelled many fixes faulty whose features are all quiet (the
offset tracker holds no offset and no evidence, neither channel's REMA flags, the
motion model's normalised innovation is small), a network would learn to keep
flagging clean-looking fixes after a fault: a latch taught by the labels. This
counts them on simulated training-like drives (8 x 10 minutes, simulator seed
30001 as the recipe's are drawn from 30,000 up, protocol ``grad`` seed 101,
positions only) at 0.5, 1 and 10 Hz: their share of the faulty points and their
longest run. Run:

    python benchmarks/tried/quiet_labels.py
"""

from __future__ import annotations

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.pipeline import PipelineParams, pipeline_feature_names
from gradgps._tracks.track import ColumnMap
from gradgps._train.grad import labelled_sequences

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")
#: the motion model's normalised innovation below this is quiet (chi-square, 2 dof, p = 0.01)
QUIET_NIS = 9.0


def main() -> None:
    params = PipelineParams()
    names = pipeline_feature_names(params)
    col = {name: names.index(name) for name in names}
    print("| rate | faulty points | with all features quiet | share | longest run |")
    print("|---|---|---|---|---|")
    for hz in (0.5, 1.0, 10.0):
        sim = simulate_fleet(8, 10.0, hz, 30001, imu=False)[["track", "t", "lat", "lon"]]
        labelled = inject_grad(sim, seed=101, columns=POSITIONS)
        faulty, quiet, longest = 0, 0, 0
        for feats, anomaly, _ in labelled_sequences(labelled, params, POSITIONS):
            f = np.sign(feats) * np.expm1(np.abs(feats))  # the features uncompressed
            calm = (
                (np.abs(f[:, col["offset_norm"]]) < 1e-9)
                & (f[:, col["fault_evidence"]] < 1.0)
                & (f[:, col["east_rema_flag"]] == 0)
                & (f[:, col["north_rema_flag"]] == 0)
                & (f[:, col["motion_nis"]] < QUIET_NIS)
            )
            hit = (anomaly == 1) & calm
            faulty += int((anomaly == 1).sum())
            quiet += int(hit.sum())
            run = 0
            for h in hit:
                run = run + 1 if h else 0
                longest = max(longest, run)
        print(f"| {hz:g} Hz | {faulty:,} | {quiet:,} | {quiet / max(faulty, 1):.1%} | {longest} |")


if __name__ == "__main__":
    main()
