"""Where a model errs on one validation drive set in one column variant (with speed, heading...).

``simulated_trace.py`` reads positions only; a change can help there and hurt where
the file reports a velocity (docs/deviations.md, "offset tracker: outliers mostly
near the track": DrivePlotR with speed and heading 0.997 -> 0.976). This injects
protocol ``grad`` (seed ``--inject-seed``) into a data set's *validation* split in
``--variant``'s columns, runs the shipped model (or ``--model``) and prints the
missed faulty fixes and false positives by bias and time type, every run of five
or more missed fixes, and with ``--rows A:B`` those rows: the verdict, the score,
the label and the injected offsets north and east (m). Run with the sources to
judge on ``PYTHONPATH``:

    python benchmarks/tried/variant_errors.py --dataset driveplotr --variant +speed+heading
        [--model DIR] [--rows 2738:2764]
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset
from gradgps._data.inject import inject_grad
from gradgps._eval.robustness import _variant_columns, decimate
from gradgps._grad.detector import Detector
from gradgps._tracks.geo import LocalFrame
from gradgps._tracks.track import to_fixes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="driveplotr")
    parser.add_argument("--variant", default="+speed+heading")
    parser.add_argument("--model", default=None)
    parser.add_argument("--inject-seed", type=int, default=0)
    parser.add_argument("--rows", default=None, help="A:B, rows to show")
    parser.add_argument(
        "--period", type=float, default=0.0, help="decimate to this (s); 0 = native"
    )
    args = parser.parse_args()
    table = load_dataset(args.dataset, "validation")
    picked = _variant_columns(table, to_fixes(table).attrs["columns"], args.variant)
    if picked is None:
        raise SystemExit(f"{args.dataset} has no {args.variant} columns")
    cols, cmap = picked
    if args.period > 0:
        table = decimate(table, cmap, args.period).reset_index(drop=True)
    labelled = inject_grad(table[cols], seed=args.inject_seed, columns=cmap)
    result = Detector(args.model).detect(to_fixes(labelled[cols], cmap))
    hit = result["anomaly"].to_numpy() == 1
    truth = labelled["label_anomaly"].to_numpy() == 1
    miss = truth & ~hit
    print(
        f"missed {int(miss.sum())} of {int(truth.sum())} faulty fixes, "
        f"{int((hit & ~truth).sum())} false positives"
    )
    kinds = labelled[["label_bias", "label_time"]]
    print(pd.crosstab(kinds["label_bias"][miss], kinds["label_time"][miss]).to_string())
    edges = np.diff(np.concatenate([[0], miss.astype(np.int8), [0]]))
    for start, stop in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if stop - start >= 5:
            print(
                f"missed run: rows {start}-{stop - 1} ({stop - start} fixes), "
                f"{kinds['label_bias'].iat[start]} {kinds['label_time'].iat[start]}"
            )
    if args.rows:
        a, b = (int(v) for v in args.rows.split(":"))
        frame = LocalFrame(float(labelled["lat_true"].iat[a]), float(labelled["lon_true"].iat[a]))
        east_true, north_true = frame.to_local(
            labelled["lat_true"].to_numpy()[a:b], labelled["lon_true"].to_numpy()[a:b]
        )
        east, north = frame.to_local(
            labelled[cmap.lat].to_numpy()[a:b], labelled[cmap.lon].to_numpy()[a:b]
        )
        shown = pd.DataFrame(
            {
                "flag": hit[a:b].astype(int),
                "score": result["score"].to_numpy()[a:b].round(3),
                "faulty": truth[a:b].astype(int),
                "bias": kinds["label_bias"].to_numpy()[a:b],
                "offset_north_m": (north - north_true).round(1),
                "offset_east_m": (east - east_true).round(1),
            },
            index=range(a, b),
        )
        print(shown.to_string())


if __name__ == "__main__":
    main()
