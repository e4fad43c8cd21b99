"""Peak memory and throughput of ``gradgps detect`` on a 10,000,000-point CSV.

    python benchmarks/memory_10m.py --json benchmarks/results/memory_10m.json
        [--rows 10000000] [--tracks 1000] [--chunk-size 200000] [--keep DIR]

The input is built from simulated drives (``gradgps.simulate_fleet``):
``--tracks / 100`` blocks of 100 tracks, each block a copy of the same 100
simulated drives under new track ids, shifted in time and position, its rows
interleaved by time as in a fleet log. It goes to a temporary folder (never
the repository) and is deleted afterwards unless ``--keep`` names a folder.

``gradgps detect INPUT -o OUT.csv --chunk-size N`` then runs in a child
process with one thread for BLAS and numba. Peak memory is the child's own
peak resident set size (``VmHWM`` in ``/proc/self/status``, read by the
child as ``benchmarks/memory_modes.py`` reads it: the kernel's high-water
mark, nothing sampled; not ``ru_maxrss``, which Linux carries over from this
parent, holding the simulated drives, across fork and exec), wall time is
measured around the child, and throughput is rows / wall time, start-up, the
file structure
pass, reading and writing included; rows per CPU second (the child's user +
system time) says the same without the effect of other load on a shared
machine, whose 1-minute load average before and after is recorded too.
Machine, date and command go into the JSON.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from memory_hostile import VMHWM_CHILD, run_child

from gradgps import simulate_fleet

_BLOCK = 100  # tracks simulated once and repeated


def write_input(path: Path, rows: int, tracks: int) -> int:
    """Write about ``rows`` fixes of ``tracks`` tracks to ``path``; returns the exact row count."""
    if tracks % _BLOCK:
        raise SystemExit(f"--tracks must be a multiple of {_BLOCK}")
    per_track = rows // tracks
    base = simulate_fleet(_BLOCK, per_track / 60.0, 1.0, seed=7, imu=False)
    base = base.groupby("track", sort=False).head(per_track)
    base = base.sort_values("t", kind="stable").reset_index(drop=True)
    track_number = base["track"].astype(int).to_numpy()
    written = 0
    for block in range(tracks // _BLOCK):
        copy = base.copy()
        copy["track"] = (track_number + block * _BLOCK).astype(str)
        copy["t"] = copy["t"] + 3600.0 * block
        copy["lat"] = copy["lat"] + 0.01 * block
        copy.to_csv(path, mode="a", header=block == 0, index=False)
        written += len(copy)
    return written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", type=Path, required=True)
    parser.add_argument("--rows", type=int, default=10_000_000)
    parser.add_argument("--tracks", type=int, default=1000)
    parser.add_argument("--chunk-size", type=int, default=200_000)
    parser.add_argument("--keep", type=Path, default=None, help="keep input and output here")
    args = parser.parse_args()

    folder = Path(tempfile.mkdtemp(prefix="gradgps-mem-")) if args.keep is None else args.keep
    folder.mkdir(parents=True, exist_ok=True)
    try:
        source, output = folder / "fleet.csv", folder / "detected.csv"
        source.unlink(missing_ok=True)
        started = time.perf_counter()
        rows = write_input(source, args.rows, args.tracks)
        print(
            f"wrote {rows:,} rows ({source.stat().st_size / 1e9:.2f} GB) in "
            f"{time.perf_counter() - started:.0f} s",
            file=sys.stderr,
        )
        command = ["detect", str(source), "-o", str(output), "--chunk-size", str(args.chunk_size)]
        # One thread for BLAS too (run_child sets numba's and OpenMP's).
        os.environ.update(OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        load_before = os.getloadavg()[0]
        child = run_child(command, VMHWM_CHILD)
        if child.get("exit_code") != 0:
            raise SystemExit(f"gradgps detect failed: {child}")
        wall = float(str(child["wall_s"]))
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)  # the child's CPU time
        cpu = usage.ru_utime + usage.ru_stime
        out_rows = sum(
            len(c) for c in pd.read_csv(output, usecols=["anomaly"], chunksize=1_000_000)
        )
        result = {
            "rows_in": rows,
            "rows_out": out_rows,
            "tracks": args.tracks,
            "chunk_size": args.chunk_size,
            "input_bytes": source.stat().st_size,
            "output_bytes": output.stat().st_size,
            "peak_rss_mib": child["peak_rss_mb"],
            "peak_measure": "VmHWM of the child (/proc/self/status)",
            "wall_s": round(wall, 1),
            "rows_per_s": round(rows / wall),
            "cpu_s": round(cpu, 1),
            "rows_per_cpu_s": round(rows / cpu),
            "load_average_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],
            "command": f"gradgps detect fleet.csv -o detected.csv --chunk-size {args.chunk_size}",
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"{platform.system()} {platform.release()}",
            "python": platform.python_version(),
            "numpy": np.__version__,
            "pandas": pd.__version__,
            "date": datetime.date.today().isoformat(),
        }
    finally:
        if args.keep is None:
            shutil.rmtree(folder, ignore_errors=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
