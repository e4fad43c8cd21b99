"""Means over the cells of ``fault_age_recall.py`` outputs, per model and column variant,
and the paired differences a decision rule reads.

Why: a training change is judged by the mean anomaly F1 over the validation cells
(every data set and rate) of a column variant, five fault draws pooled per cell, in
pairs of trainings (docs/deviations.md: one training's spread is as wide as the
changes tried). This reads the tables ``fault_age_recall.py`` printed (several files,
several models each) and prints each model's mean per variant, and for each
``--pair BASE:CANDIDATE`` (the last path component of the model directories; the
shipped model is ``default``) the mean of the differences per variant and the worst
positions cell. Run:

    python benchmarks/tried/draws_means.py OUT1.txt [OUT2.txt ...] [--pair default:ten_s0 ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))  # for eval_summary
from eval_summary import table_rows


def read_cells(text: str) -> pd.DataFrame:
    """The rows of one ``fault_age_recall.py`` table: data set, columns, rate, model (the
    directory's last component), anomaly F1, normal recall."""
    rows = [
        {
            "data_set": cells[0],
            "columns": cells[1],
            "rate": cells[2],
            "model": Path(cells[3]).name,
            "f1": float(cells[4]),
            "normal_recall": float(cells[5]),
        }
        for cells in table_rows(text)
        if cells[0] != "data set"
    ]
    return pd.DataFrame(rows)


def _f1_by_cell(cells: pd.DataFrame) -> pd.DataFrame:
    """Anomaly F1 with one row per (columns, data set, rate) and one column per model."""
    wide: pd.DataFrame = cells.pivot_table(
        index=["columns", "data_set", "rate"], columns="model", values="f1"
    )
    return wide


def variant_means(cells: pd.DataFrame) -> pd.DataFrame:
    """Mean anomaly F1 per column variant (rows) and model (columns)."""
    means: pd.DataFrame = _f1_by_cell(cells).groupby(level="columns").mean()
    return means


def paired(cells: pd.DataFrame, base: str, candidate: str) -> tuple[pd.Series, float]:
    """Mean of the cell-by-cell differences candidate - base per column variant (over the
    cells both have), and the lowest such difference among the positions cells."""
    wide = _f1_by_cell(cells)
    diff = (wide[candidate] - wide[base]).dropna()
    by_variant: pd.Series = diff.groupby(level="columns").mean()
    worst = float(diff.loc["positions"].min()) if "positions" in diff.index else float("nan")
    return by_variant, worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="fault_age_recall.py outputs")
    parser.add_argument("--pair", action="append", default=[], help="BASE:CANDIDATE")
    args = parser.parse_args()
    cells = pd.concat([read_cells(Path(f).read_text()) for f in args.files], ignore_index=True)
    cells = cells.drop_duplicates(subset=["data_set", "columns", "rate", "model"])
    print("Mean anomaly F1 over the cells, per column variant (rows) and model (columns):")
    print()
    print(variant_means(cells).round(4).to_string())
    for pair in args.pair:
        base, candidate = pair.split(":")
        by_variant, worst = paired(cells, base, candidate)
        shown = ", ".join(f"{k} {v:+.4f}" for k, v in by_variant.items())
        print()
        print(f"{candidate} - {base}: mean difference {shown}; worst positions cell {worst:+.3f}")


if __name__ == "__main__":
    main()
