"""detect-fleet throughput on a local Dask cluster: 1,000 simulated vehicles, 1 and 2 workers.

Simulates ``--vehicles`` drives of ``--minutes`` at 1 Hz, writes them as one
Parquet file per vehicle, then for each worker count starts a local cluster
(single-thread worker processes, numba at one thread each), loads the model
and the compiled kernels in every worker (so first-call costs are not
timed), and times :func:`gradgps._run.fleet_dask.detect_fleet` end to end: each
task reads its file, detects and writes its output file. Points/s = input
rows / wall seconds of that call. The 1-minute load average before and after
is recorded: on a shared machine other jobs show up directly in the numbers.

Usage::

    PYTHONPATH=src python benchmarks/fleet_dask.py --json benchmarks/results/fleet_dask.json \\
        --markdown BENCHMARKS.md

``--markdown`` rewrites the section between ``<!-- fleet:start -->`` and
``<!-- fleet:end -->`` of that file (appending it when absent).
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from gradgps._data.simulator import simulate_fleet
from gradgps._run.chunked import detect_partition
from gradgps._run.fleet_dask import dask_client, detect_fleet

START, END = "<!-- fleet:start -->", "<!-- fleet:end -->"


def _warm_up() -> None:
    """Runs in each worker: load the model and the numba kernels from their caches."""
    from gradgps._data.simulator import simulate_drive
    from gradgps._grad.detector import Detector

    Detector().detect(simulate_drive(1.0, 1.0, 0))


def write_fleet(root: Path, vehicles: int, minutes: float, seed: int) -> int:
    frame = simulate_fleet(vehicles, minutes, 1.0, seed)
    for vehicle, rows in frame.groupby("track", sort=False):
        rows.drop(columns="track").to_parquet(root / f"{vehicle}.parquet", index=False)
    return len(frame)


def measure(source: Path, scratch: Path, workers: int) -> dict[str, Any]:
    with dask_client(workers=workers) as client:
        client.run(_warm_up)
        load_before = os.getloadavg()[0]
        summary = detect_fleet(source, scratch / f"out-{workers}", client, task=detect_partition)
    return {
        "workers": workers,
        "vehicles": summary.vehicles,
        "points": summary.rows,
        "seconds": round(summary.seconds, 2),
        "points_per_s": round(summary.rows / summary.seconds),
        "load_average_before": round(load_before, 2),
        "load_average_after": round(os.getloadavg()[0], 2),
    }


def markdown(results: dict[str, Any]) -> str:
    runs = results["runs"]
    lines = [
        START,
        "## Fleet batch: detect-fleet on Dask",
        "",
        f"`python benchmarks/fleet_dask.py` ({results['date']}, {results['cpu_count']} CPUs, "
        f"{results['machine']}): {results['vehicles']:,} simulated vehicles x "
        f"{results['minutes']:g} min at 1 Hz ({runs[0]['points']:,} points), one Parquet file "
        "per vehicle, a local cluster of single-thread worker processes; wall time of "
        "`detect_fleet` (read, detect, write every vehicle) after the workers loaded the model.",
        "",
        "| workers | seconds | points/s | speed-up | load avg before -> after |",
        "| ---: | ---: | ---: | ---: | --- |",
    ]
    base = runs[0]["points_per_s"]
    for run in runs:
        lines.append(
            f"| {run['workers']} | {run['seconds']:.1f} | {run['points_per_s']:,} | "
            f"{run['points_per_s'] / base:.2f}x | {run['load_average_before']} -> "
            f"{run['load_average_after']} |"
        )
    lines += ["", results["note"], END]
    return "\n".join(lines)


def update_markdown(path: Path, section: str) -> None:
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    if START in text and END in text:
        head, rest = text.split(START, 1)
        text = head + section + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + section + "\n"
    path.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=1000)
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--markdown", type=Path, help="rewrite the fleet section of this file")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="fleet-bench-") as tmp:
        scratch = Path(tmp)
        source = scratch / "in"
        source.mkdir()
        started = time.perf_counter()
        points = write_fleet(source, args.vehicles, args.minutes, args.seed)
        print(
            f"simulated {args.vehicles} vehicles, {points:,} points in "
            f"{time.perf_counter() - started:.1f} s",
            file=sys.stderr,
        )
        runs = []
        for workers in args.workers:
            runs.append(measure(source, scratch, workers))
            print(json.dumps(runs[-1]), file=sys.stderr)
    results = {
        "command": "python benchmarks/fleet_dask.py " + " ".join(sys.argv[1:]),
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()} {platform.python_implementation()} {platform.python_version()}",
        "cpu_count": os.cpu_count(),
        "vehicles": args.vehicles,
        "minutes": args.minutes,
        "seed": args.seed,
        "runs": runs,
        "note": (
            "A load average near or above the CPU count means other jobs shared the CPUs "
            "during the run; the numbers, the 2-worker speed-up most of all, are then lower "
            "than on an idle machine. Each task pays a Parquet read and write besides "
            "detection."
        ),
    }
    text = json.dumps(results, indent=2)
    print(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    if args.markdown:
        update_markdown(args.markdown, markdown(results))


if __name__ == "__main__":
    main()
