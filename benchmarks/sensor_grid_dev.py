"""The sensor-grid table's recipe on the validation split: for developing the channel GRAD.

    python benchmarks/sensor_grid_dev.py [--rows ROW,ROW] [--methods M,M] [--json FILE]

Trains (or takes from ``$GRADGPS_CACHE``) every method of ``--methods`` per
row exactly as ``benchmarks/run_all.py --tables sensor-grid`` does (same
recipe: 3 injection seeds, 15-second budget, speed from the fixes), then
scores it on the *validation* split injected with seed 0 (the thresholds come
from validation seed 7), so features and settings can be compared without
looking at the test split. Prints, per row, point F1 / window F1 / normal
recall of each method and the best baseline's point and window F1.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from run_all import GRID_WINDOW, SENSOR_BASELINES, SENSOR_METHODS, _grid_recipe


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rows", default="", help="comma-separated rows (default: all 20)")
    parser.add_argument("--methods", default=",".join(SENSOR_METHODS))
    parser.add_argument("--json", type=Path, help="also write the report here")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    import torch

    from gradgps._eval.bench import run_bench

    torch.set_num_threads(1)
    methods = [m for m in args.methods.split(",") if m]
    began = time.perf_counter()
    report = run_bench(
        "sensor-grid",
        "driveplotr",
        methods,
        split="validation",
        seed=0,
        data_dir=args.data_dir,
        recipe=_grid_recipe(False),
        per_row=True,
        fix_speed=True,
        window=GRID_WINDOW,
        rows=[r for r in args.rows.split(",") if r] or None,
    )
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    results = report["results"]
    rows = list(results[methods[0]])
    baselines = [m for m in methods if m in SENSOR_BASELINES]
    print(f"{'row':14s} " + " ".join(f"{m:>17s}" for m in methods) + "  best baseline pt/win")
    for row in rows:
        cells = []
        for m in methods:
            b = results[m][row]
            cells.append(
                f"{100 * b['anomaly']['f1']:5.1f}/{100 * b['window']['anomaly']['f1']:5.1f}"
                f"/{b['normal']['recall']:.3f}"
            )
        best = ""
        if baselines:
            point = max(100 * results[m][row]["anomaly"]["f1"] for m in baselines)
            window = max(100 * results[m][row]["window"]["anomaly"]["f1"] for m in baselines)
            best = f"{point:5.1f}/{window:5.1f}"
        print(f"{row:14s} " + " ".join(f"{c:>17s}" for c in cells) + f"  {best}")
    print(f"({time.perf_counter() - began:.0f} s)")


if __name__ == "__main__":
    main()
