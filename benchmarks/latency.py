"""Speed of the full GRAD pipeline (features, REMA, offset tracker, GRU, time type, recovery).

    python benchmarks/latency.py --json OUT.json [--model DIR] [--points 1000000]

* streaming: ``Detector.update`` per fix on one simulated track (p50 / p99
  over all calls after a warm-up, microseconds);
* batch: ``Detector.detect`` on ``--points`` fixes (1,000 simulated tracks),
  fixes per second, preprocessing included;
* fleet: one step for 1,000 tracks at once: one ``update`` per vehicle, one
  Detector per vehicle, microseconds per vehicle.

Threads are pinned to one (BLAS, numba) before anything is imported, so the
numbers are one core's. The machine and the date go into the JSON.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from gradgps import simulate_fleet, to_fixes  # noqa: E402
from gradgps._detector import Detector  # noqa: E402


def _streaming(model: str | None, minutes: float) -> dict[str, float]:
    fixes = to_fixes(simulate_fleet(1, minutes, 1.0, seed=11))
    rows = list(fixes[["t", "lat", "lon", "speed", "heading"]].itertuples(index=False, name=None))
    warm = Detector(model)
    for r in rows[:100]:
        warm.update(*r)
    det = Detector(model)
    times = np.empty(len(rows))
    clock = time.perf_counter_ns
    for i, (t, lat, lon, speed, heading) in enumerate(rows):
        start = clock()
        det.update(t, lat, lon, speed=speed, heading=heading)
        times[i] = clock() - start
    us = times[50:] / 1e3
    return {"streaming_p50_us": float(np.percentile(us, 50)),
            "streaming_p99_us": float(np.percentile(us, 99)), "streaming_calls": len(us)}


def _batch(model: str | None, points: int) -> dict[str, float]:
    tracks = 1000
    minutes = points / tracks / 60.0
    fixes = to_fixes(simulate_fleet(tracks, minutes, 1.0, seed=12))
    det = Detector(model)
    det.detect(fixes.iloc[:200])
    best = np.inf
    for _ in range(2):
        start = time.perf_counter()
        det.detect(fixes)
        best = min(best, time.perf_counter() - start)
    return {"batch_points": len(fixes), "batch_points_per_s": len(fixes) / best}


def _fleet(model: str | None, vehicles: int, steps: int) -> dict[str, float]:
    fixes = to_fixes(simulate_fleet(vehicles, steps / 60.0, 1.0, seed=13))
    per = [g[["t", "lat", "lon", "speed", "heading"]].to_numpy() for _, g in fixes.groupby("track")]
    dets = [Detector(model) for _ in per]
    step_times = []
    for k in range(min(len(p) for p in per)):
        start = time.perf_counter()
        for det, p in zip(dets, per, strict=True):
            t, lat, lon, speed, heading = p[k]
            det.update(t, lat, lon, speed=speed, heading=heading)
        step_times.append(time.perf_counter() - start)
    us = np.array(step_times[5:]) * 1e6 / len(dets)
    return {"fleet_vehicles": len(dets), "fleet_step_us_per_vehicle": float(np.median(us))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True, help="where to write the results")
    parser.add_argument("--model", default=None, help="model directory (default: shipped model)")
    parser.add_argument("--points", type=int, default=1_000_000, help="fixes for the batch run")
    parser.add_argument("--stream-minutes", type=float, default=60.0)
    parser.add_argument("--fleet-steps", type=int, default=60)
    args = parser.parse_args()
    result: dict[str, object] = {
        "command": "python benchmarks/latency.py --json " + str(args.json),
        "machine": f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores".strip(),
        "python": platform.python_version(),
        "date": datetime.date.today().isoformat(),
    }
    result.update(_streaming(args.model, args.stream_minutes))
    result.update(_batch(args.model, args.points))
    result.update(_fleet(args.model, 1000, args.fleet_steps))
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
