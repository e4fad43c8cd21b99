"""Speed of the full GRAD pipeline (features, REMA, offset tracker, GRU, time type, recovery).

    python benchmarks/latency.py --json OUT.json [--model DIR] [--points 1000000]

* streaming: ``Detector.update`` per fix on one simulated track (p50 / p99
  over all calls after a warm-up, microseconds);
* batch: ``Detector.detect`` on ``--points`` fixes (``--tracks`` simulated
  tracks), fixes per second, preprocessing included; with one thread and
  with ``--threads`` numba threads (``batch_points_per_s`` is the latter,
  ``batch_threads`` says how many);
* fleet: one step for 1,000 tracks at once: one ``update`` per vehicle, one
  Detector per vehicle, microseconds per vehicle.

BLAS is pinned to one thread before anything is imported; numba gets
``--threads`` threads for the second batch run only. The machine, the load
average and the date go into the JSON.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from gradgps import simulate_fleet, to_fixes  # noqa: E402
from gradgps._grad.detector import Detector  # noqa: E402


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
    return {
        "streaming_p50_us": float(np.percentile(us, 50)),
        "streaming_p99_us": float(np.percentile(us, 99)),
        "streaming_calls": len(us),
    }


def _batch(model: str | None, points: int, tracks: int, threads: int) -> dict[str, float]:
    minutes = points / tracks / 60.0
    fixes = to_fixes(simulate_fleet(tracks, minutes, 1.0, seed=12))
    det = Detector(model)
    out: dict[str, float] = {"batch_points": len(fixes), "batch_tracks": tracks}
    for n, key in ((1, "batch_points_per_s_1_thread"), (threads, "batch_points_per_s")):
        det.detect(fixes.iloc[:5000], threads=n)  # compile
        best = np.inf
        for _ in range(2):
            start = time.perf_counter()
            det.detect(fixes, threads=n)
            best = min(best, time.perf_counter() - start)
        out[key] = len(fixes) / best
    out["batch_threads"] = threads
    return out


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
    parser.add_argument("--tracks", type=int, default=100, help="tracks in the batch run")
    parser.add_argument(
        "--threads",
        type=int,
        default=os.cpu_count() or 1,
        help="numba threads for the second batch run",
    )
    parser.add_argument("--stream-minutes", type=float, default=60.0)
    parser.add_argument("--fleet-steps", type=int, default=60)
    args = parser.parse_args()
    result: dict[str, object] = {
        "command": "python benchmarks/latency.py --json " + str(args.json),
        "machine": f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores".strip(),
        "python": platform.python_version(),
        "date": datetime.date.today().isoformat(),
        "load_average_before": os.getloadavg()[0],
    }
    result.update(_streaming(args.model, args.stream_minutes))
    result.update(_batch(args.model, args.points, args.tracks, args.threads))
    result.update(_fleet(args.model, 1000, args.fleet_steps))
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
