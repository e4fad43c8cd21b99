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
import sys
from pathlib import Path

import numpy as np

from gradgps._grad.detector import Detector
from gradgps._grad.gru import _reference_cell, diagonal_blocks, scale_features
from gradgps._grad.model_io import gru_model
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
sys.path.insert(0, str(Path(__file__).resolve().parent))  # for simulated_trace
from _segment_features import segment_features
from simulated_trace import drive_arguments, drives


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    drive_arguments(parser, simulated_only=True)  # simulated drives, as simulated_trace.py
    parser.add_argument("--row", type=int, required=True)
    parser.add_argument("--before", type=int, default=150)
    parser.add_argument("--after", type=int, default=48)
    parser.add_argument("--every", type=int, default=3)
    args = parser.parse_args()

    labelled, cmap = drives(args)
    fixes = to_fixes(labelled, cmap)
    truth = labelled["label_anomaly"].to_numpy()
    det = Detector(args.model)
    track = fixes["track"].to_numpy()
    rows = np.flatnonzero(track == track[args.row])
    for seg, _, raw in segment_features(det, fixes.iloc[rows], decompress=False):
        if args.row not in rows[seg]:
            continue
        folder = Path(det.model_.path)  # loaded by segment_features
        config = json.loads((folder / "config.json").read_text())
        with np.load(folder / config["weights_file"]) as archive:
            gru = gru_model({name: archive[name] for name in archive.files}, config)
        w = gru.weights
        members = diagonal_blocks(w)
        scaled = scale_features(raw, gru.mean, gru.std)
        h1 = np.zeros(w["gru1.weight_hh"].shape[1], np.float32)
        h2 = np.zeros(w["gru2.weight_hh"].shape[1], np.float32)
        margin = w["anomaly_head.weight"][1] - w["anomaly_head.weight"][0]
        bias = float(w["anomaly_head.bias"][1] - w["anomaly_head.bias"][0])
        size = h2.size // members
        head = [f"member {m + 1}" for m in range(members)]
        print("| fix | faulty | " + " | ".join(head) + " | bias | sum |")
        print("|" + "---|" * (members + 4))
        at = int(np.flatnonzero(rows[seg] == args.row)[0])
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
