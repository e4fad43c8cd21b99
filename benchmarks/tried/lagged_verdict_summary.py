"""Five-draw means of ``lagged_verdict_check.py`` outputs, lag against lag (issue 13 experiment).

Reads ``TAG_seed{0..4}.txt`` (one ``lagged_verdict_check.py --inject-seed S`` output each)
for every ``--pair BASE:CAND`` of tags in ``--dir``, and prints per cell the mean
anomaly F1 and normal recall over the draws and the clean false alarms (the same
in every draw), then each pair's mean F1 difference over all cells and over the
0.5 Hz cells, and, over all pairs, the per-cell clean false alarms averaged per
side. Run (``benchmarks/tried/results/lag2/README.md``):

    python benchmarks/tried/lagged_verdict_summary.py --dir benchmarks/tried/results/lag2 \\
        --pair lag1_s0:lag2_s0 --pair lag1_s1:lag2_s1
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

_ROW = re.compile(r"\| (\S+) \| (native|[\d.]+ Hz) \| ([\d.]+) % \| ([\d.]+) \| ([\d.]+) \|")


def read_draws(folder: Path, tag: str, draws: int = 5) -> dict[tuple[str, str], np.ndarray]:
    """Per cell ``(data set, rate)``: rows ``(clean FA %, F1, normal recall)``, one per draw."""
    cells: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    for seed in range(draws):
        for line in (folder / f"{tag}_seed{seed}.txt").read_text().splitlines():
            m = _ROW.match(line)
            if m:
                cells.setdefault((m[1], m[2]), []).append((float(m[3]), float(m[4]), float(m[5])))
    return {cell: np.array(rows) for cell, rows in cells.items()}


def mean_difference(base: dict, cand: dict, rate: str | None = None) -> float:
    """Mean over cells (of ``rate``, or all) of the candidate's mean F1 less the base's."""
    cells = [c for c in base if rate is None or c[1] == rate]
    return float(np.mean([cand[c][:, 1].mean() - base[c][:, 1].mean() for c in cells]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, required=True)
    parser.add_argument("--pair", action="append", required=True, help="BASE:CAND tags")
    args = parser.parse_args()
    pairs = [tuple(p.split(":")) for p in args.pair]
    runs = {tag: read_draws(args.dir, tag) for pair in pairs for tag in pair}
    for base, cand in pairs:
        print(f"\n{base} -> {cand}: five-draw mean F1 and normal recall, clean false alarms")
        print("| data set | rate | F1 | normal recall | clean FA % |")
        print("|---|---|---|---|---|")
        for cell in runs[base]:
            b, c = runs[base][cell], runs[cand][cell]
            print(
                f"| {cell[0]} | {cell[1]} | {b[:, 1].mean():.3f} -> {c[:, 1].mean():.3f}"
                f" | {b[:, 2].mean():.3f} -> {c[:, 2].mean():.3f}"
                f" | {b[0, 0]:.2f} -> {c[0, 0]:.2f} |"
            )
        print(
            f"mean F1 difference: all cells {mean_difference(runs[base], runs[cand]):+.4f},"
            f" 0.5 Hz cells {mean_difference(runs[base], runs[cand], '0.5 Hz'):+.4f}"
        )
    diffs = [mean_difference(runs[b], runs[c]) for b, c in pairs]
    slow = [mean_difference(runs[b], runs[c], "0.5 Hz") for b, c in pairs]
    print(f"\nover the pairs: all cells {np.mean(diffs):+.4f}, 0.5 Hz cells {np.mean(slow):+.4f}")
    print("clean false alarms per cell, averaged over the pairs' bases -> candidates:")
    for cell in runs[pairs[0][0]]:
        b = np.mean([runs[base][cell][0, 0] for base, _ in pairs])
        c = np.mean([runs[cand][cell][0, 0] for _, cand in pairs])
        print(f"  {cell[0]} {cell[1]}: {b:.3f} -> {c:.3f} %")


if __name__ == "__main__":
    main()
