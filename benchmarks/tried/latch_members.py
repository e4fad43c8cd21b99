"""Which of the shipped model's networks holds a latch: each member's share of the anomaly logit.

The shipped model is four networks merged into one with block-diagonal weights
(docs/model-card.md); its anomaly head adds up what each member's last hidden
layer contributes, plus one bias. This reruns the model's GRU with the readable
NumPy reference on the segment that holds row ``--row`` of the drives
``simulated_trace.py`` draws (simulator seed ``--sim-seed``, ``--hz``, protocol
``grad`` seed ``--inject-seed``, positions only) and prints, every ``--every``
fixes from ``--before`` before the row to ``--after`` after it, each member's
contribution to the anomaly logit's margin (anomaly minus normal), the bias's,
and their sum (P(anomaly) = sigmoid(sum)). A latch held by one member shows as one
column high and the others at their usual values on clean fixes; one held by all,
as every column raised. Never the test splits. Run:

    python benchmarks/tried/latch_members.py --hz 0.5 --sim-seed 4242 --inject-seed 0 \\
        --row 400 [--before 150] [--after 48] [--every 3] [--model DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from gradgps._data.inject import inject_grad
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._grad.gru import _reference_cell, diagonal_blocks, scale_features
from gradgps._grad.model_io import gru_model
from gradgps._grad.pipeline import grad_features
from gradgps._tracks.track import ColumnMap, to_fixes

POSITIONS = ColumnMap(track="track", time="t", lat="lat", lon="lon", speed="", heading="")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hz", type=float, required=True)
    parser.add_argument("--sim-seed", type=int, default=4242)
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument("--row", type=int, required=True)
    parser.add_argument("--before", type=int, default=150)
    parser.add_argument("--after", type=int, default=48)
    parser.add_argument("--every", type=int, default=3)
    parser.add_argument("--model", default=None)
    args = parser.parse_args()

    sim = simulate_fleet(6, 15.0, args.hz, args.sim_seed, imu=False)
    labelled = inject_grad(
        sim[["track", "t", "lat", "lon"]], seed=args.inject_seed, columns=POSITIONS
    )
    fixes = to_fixes(labelled, POSITIONS)
    truth = labelled["label_anomaly"].to_numpy()
    det = Detector(args.model)
    det.detect(fixes.iloc[:2])  # loads the model
    folder = Path(det.model_.path)
    config = json.loads((folder / "config.json").read_text())
    with np.load(folder / config["weights_file"]) as archive:
        gru = gru_model({name: archive[name] for name in archive.files}, config)
    w = gru.weights
    members = diagonal_blocks(w)
    track = fixes["track"].to_numpy()
    rows = np.flatnonzero(track == track[args.row])
    _, _, prepared, _ = det._point_outputs(fixes.iloc[rows].reset_index(drop=True))
    local = args.row - rows[0]
    for k, sl in prepared.segment_slices():
        seg = np.arange(len(prepared.points))[sl]
        if not seg[0] <= local <= seg[-1]:
            continue
        pts = prepared.points.iloc[sl]
        t, lat, lon = (pts[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
        nan = np.full(len(t), np.nan)
        raw = grad_features(det.model_.params, prepared.segment_frames[k], t, lat, lon, nan, nan)
        scaled = scale_features(raw.features, gru.mean, gru.std)
        h1 = np.zeros(w["gru1.weight_hh"].shape[1], np.float32)
        h2 = np.zeros(w["gru2.weight_hh"].shape[1], np.float32)
        margin = w["anomaly_head.weight"][1] - w["anomaly_head.weight"][0]
        bias = float(w["anomaly_head.bias"][1] - w["anomaly_head.bias"][0])
        size = h2.size // members
        head = [f"member {m + 1}" for m in range(members)]
        print("| fix | faulty | " + " | ".join(head) + " | bias | sum |")
        print("|" + "---|" * (members + 4))
        at = local - seg[0]
        for i in range(len(scaled)):
            h1 = _reference_cell(
                scaled[i], h1, w["gru1.weight_ih"], w["gru1.weight_hh"],
                w["gru1.bias_ih"], w["gru1.bias_hh"],
            )  # fmt: skip
            h2 = _reference_cell(
                h1, h2, w["gru2.weight_ih"], w["gru2.weight_hh"],
                w["gru2.bias_ih"], w["gru2.bias_hh"],
            )  # fmt: skip
            if i < at - args.before or i > at + args.after or (i - at) % args.every:
                continue
            parts = [float(margin[m * size : (m + 1) * size] @ h2[m * size : (m + 1) * size])
                     for m in range(members)]  # fmt: skip
            g = rows[seg[i]]
            cells = [f"{v:.2f}" for v in (*parts, bias, sum(parts) + bias)]
            print(f"| {g} | {int(truth[g])} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
