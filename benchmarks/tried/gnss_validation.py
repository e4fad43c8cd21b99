"""Protocol ``gnss`` on the real *validation* drives, positions only: a tuning view.

``gradgps bench --protocol gnss`` scores the test splits, which tuning must not
read. Its long episodes (frozen fixes up to 60 s, multipath bursts, drifts up to
300 s) end with clean driving, the case where a detector that learnt "a long
fault never ends" keeps flagging: the normal recall shows it. This runs the same
cell (:func:`gradgps._eval.gnss.gnss_cell`, protocol ``gnss`` seed ``--seed``)
on every data set's validation split, positions only, with the shipped model or
``--model``. ``--after`` says where the false positives sit instead: per bias
type of the episode before them (same track), how many, and how many fixes after
its end (1-5, 6-30, later). ``--draws N`` gives each data set's normal recall
under seeds 0..N-1 and their mean, for every ``--model`` (repeatable; ``default``
is the shipped model): one fault draw can hide or invent a change. Run:

    python benchmarks/tried/gnss_validation.py [--model DIR] [--seed 0] [--after]
    python benchmarks/tried/gnss_validation.py --draws 5 --model default --model DIR
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.inject import inject_gnss
from gradgps._eval.gnss import gnss_cell
from gradgps._grad.detector import Detector
from gradgps._tracks.track import to_fixes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/, for the helper
from _validation_drives import validation_positions

sys.path.insert(0, str(Path(__file__).resolve().parent))  # benchmarks/tried, for the helper
from hangover_check import since_last_fault


def after_faults(det: Detector, labelled: pd.DataFrame, cols: list[str], cmap) -> pd.DataFrame:
    """One row per false positive: the bias type of the last episode that ended before it
    on its track (``none`` if none) and the fixes since that episode's last fix."""
    fixes = to_fixes(labelled[cols], cmap)
    hit = det.detect(fixes)["anomaly"].to_numpy(dtype=np.int64) == 1
    bias = labelled["label_bias"].to_numpy(dtype=object)
    normal = bias == "none"
    since, last = since_last_fault(~normal, fixes["track"].to_numpy())
    before = np.where(last >= 0, bias[last], "none")
    false = hit & normal
    return pd.DataFrame({"before": before[false], "since": since[false]})


def draws_table(recall: dict[str, dict[str, list[float]]]) -> list[str]:
    """Markdown rows: per data set and model (``recall[model][data set]``, one normal
    recall per fault draw), the draws' values and their mean."""
    rows = ["| data set | model | normal recall per draw | mean |", "|---|---|---|---|"]
    names = list(dict.fromkeys(n for per_set in recall.values() for n in per_set))
    for name in names:
        for model, per_set in recall.items():
            values = per_set[name]
            shown = " ".join(f"{v:.3f}" for v in values)
            rows.append(f"| {name} | {model} | {shown} | {np.mean(values):.4f} |")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", action="append", default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--after", action="store_true", help="where the false positives sit")
    parser.add_argument("--draws", type=int, default=0, help="normal recall over seeds 0..N-1")
    args = parser.parse_args()
    models = args.model or ["default"]
    if args.draws:
        recall: dict[str, dict[str, list[float]]] = {}
        for model in models:
            det = Detector(None if model == "default" else model)
            per_set = recall.setdefault(model, {})
            for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
                for seed in range(args.draws):
                    cell = gnss_cell(det, inject_gnss(table, seed=seed), cols, cmap)
                    per_set.setdefault(name, []).append(cell["normal"]["recall"])
        print("\n".join(draws_table(recall)))
        return
    if len(models) > 1:
        parser.error("one --model without --draws")
    det = Detector(None if models[0] == "default" else models[0])
    if args.after:
        print("| data set | episode before | false positives | 1-5 fixes after | 6-30 | later |")
        print("|---|---|---|---|---|---|")
        for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
            fp = after_faults(det, inject_gnss(table, seed=args.seed), cols, cmap)
            for kind, g in fp.groupby("before"):
                s = g["since"].to_numpy()
                near, mid = ((s >= 1) & (s <= 5)).sum(), ((s > 5) & (s <= 30)).sum()
                print(f"| {name} | {kind} | {len(g)} | {near} | {mid} | {len(g) - near - mid} |")
        return
    kinds = ("noise", "jump", "freeze", "multipath", "outage")
    print("| data set | rows | anomaly F1 | normal recall | " + " | ".join(kinds) + " |")
    print("|---|---|---|---|" + "---|" * len(kinds))
    for name, table, cols, cmap, _ in validation_positions(None, keep_native=True):
        labelled = inject_gnss(table, seed=args.seed)
        cell = gnss_cell(det, labelled, cols, cmap)
        recalls = [cell["types"][k]["recall"] for k in kinds]
        shown = " | ".join("-" if r is None else f"{r:.2f}" for r in recalls)
        print(
            f"| {name} | {cell['rows']:,} | {cell['anomaly']['f1']:.3f} | {cell['normal']['recall']:.3f} | "
            f"{shown} |"
        )


if __name__ == "__main__":
    main()
