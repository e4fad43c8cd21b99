"""µs per vehicle of one ``FleetDetector.update_many`` step over a large fleet (issue 17).

Every vehicle sends one fix per step (1 Hz, moving, speed and heading
reported or not); after ``--warmup`` steps (segment start-up, the compiled
code's first call) the median and 99th percentile over ``--steps`` steps of
the wall time of one ``update_many`` call, divided by the number of
vehicles. One process, one thread. Writes JSON with the machine and the load
average before and after. Run:

    python benchmarks/fleet_step.py [--vehicles 10000] [--steps 40] [--warmup 10]
        [--positions-only] [--json benchmarks/results/fleet_step.json]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from gradgps import FleetDetector  # noqa: E402
from gradgps._eval.robustness import machine  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--positions-only", action="store_true")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    n = args.vehicles
    load_before = list(os.getloadavg())
    fleet = FleetDetector()
    ids = [f"v{k}" for k in range(n)]
    rng = np.random.default_rng(0)
    lat = 45.0 + rng.normal(0.0, 0.05, n)
    lon = 7.0 + rng.normal(0.0, 0.05, n)
    speed = None if args.positions_only else np.full(n, 11.0)
    heading = None if args.positions_only else np.zeros(n)
    seconds = []
    for k in range(args.warmup + args.steps):
        lat = lat + 1e-4  # about 11 m north a second
        t = np.full(n, 1.7e9 + k)
        began = time.perf_counter()
        fleet.update_many(ids, t, lat, lon, speed, heading)
        seconds.append(time.perf_counter() - began)
    steady = np.array(seconds[args.warmup :]) * 1e6 / n
    report = {
        "vehicles": n,
        "steps": args.steps,
        "warmup": args.warmup,
        "columns": "positions" if args.positions_only else "+speed+heading",
        "us_per_vehicle_median": float(np.median(steady)),
        "us_per_vehicle_p99": float(np.percentile(steady, 99)),
        "machine": machine(),
        "load_before": load_before,
        "load_after": list(os.getloadavg()),
    }
    print(json.dumps(report, indent=1))
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
