"""Speed of the statistical core: REMA + MS-SW features + time classifier + recovery.

Measures, on one core (NUMBA_NUM_THREADS=1, OMP_NUM_THREADS=1 are set before
numba loads):

* first-call compile/load time of the batch kernel (from the numba cache when
  it is warm; the first run on a fresh checkout compiles);
* batch throughput of :func:`gradgps._grad.core.core_batch` in points/s on
  a synthetic 1 Hz drive (best of ``--repeat`` runs, 30 s / 5 s windows) and
  on a 5 Hz one (windows are in seconds, so 5 Hz means 5x longer windows),
  twice: as one ``--points`` array, and cut into segments of
  ``--segment-points`` (default 3,600 = one hour at 1 Hz; the longest
  DrivePlotR drive is 2.3 h), which is how ``RemaDetector`` calls it. The
  gap between the two is mostly fresh memory: one big result array is
  page-faulted in on every call, segment-sized ones are reused by malloc;
* the median and 99th percentile of one streaming ``CorePipeline.update``
  call, in microseconds.

Usage: ``python benchmarks/core_speed.py [--points N] [--repeat R] [--json OUT]``.
Targets (issue C): batch >= 2,000,000 points/s, streaming median <= 5 us.
The JSON also records the 1-minute load average before and after, because a
shared machine's other jobs show up directly in these numbers.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
# The streaming CorePipeline is not part of the product: it lives with the tests.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _core_support import CorePipeline
from gradgps._baselines.rema_detector import RemaDetector
from gradgps._grad.core import CoreParams, core_batch


def synthetic_drive(n: int, period: float, seed: int = 0) -> tuple[np.ndarray, ...]:
    """A car at 0-20 m/s with gentle turns, 1 m GPS noise and a few injected jumps."""
    rng = np.random.default_rng(seed)
    speed = np.clip(10 + np.cumsum(rng.normal(0, 0.3 * period, n)), 0, 20)
    heading = np.cumsum(rng.normal(0, 2 * period, n)) % 360
    h = np.radians(heading)
    east = np.cumsum(speed * np.sin(h) * period) + rng.normal(0, 1, n)
    north = np.cumsum(speed * np.cos(h) * period) + rng.normal(0, 1, n)
    for start in rng.integers(0, n - 10, n // 500):
        east[start : start + 3] += 30.0
    return east, north, speed, heading


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--stream-points", type=int, default=20_000)
    ap.add_argument("--repeat", type=int, default=5, help="best of this many runs")
    ap.add_argument("--segment-points", type=int, default=3600)
    ap.add_argument("--json", type=Path, default=None, help="write the numbers here")
    args = ap.parse_args()

    rema = RemaDetector().rema  # the tuned defaults the benchmark detector uses
    results: dict[str, object] = {
        "threads": os.environ["NUMBA_NUM_THREADS"],
        "load_average_before": round(os.getloadavg()[0], 2),
        "cpu_count": os.cpu_count(),
    }

    east, north, speed, heading = synthetic_drive(1000, 1.0)
    t0 = time.perf_counter()
    core_batch(east, north, CoreParams(period=1.0, rema=rema), speed=speed, heading=heading)
    results["first_call_s"] = round(time.perf_counter() - t0, 3)

    for hz in (1, 5):
        period = 1.0 / hz
        params = CoreParams(period=period, rema=rema)
        east, north, speed, heading = synthetic_drive(args.points, period)
        best = np.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            core_batch(east, north, params, speed=speed, heading=heading)
            best = min(best, time.perf_counter() - t0)
        results[f"batch_points_per_s_{hz}hz"] = round(args.points / best)
        seg = args.segment_points * hz
        best = np.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            for i in range(0, args.points, seg):
                core_batch(
                    east[i : i + seg],
                    north[i : i + seg],
                    params,
                    speed=speed[i : i + seg],
                    heading=heading[i : i + seg],
                )
            best = min(best, time.perf_counter() - t0)
        results[f"batch_points_per_s_{hz}hz_segments"] = round(args.points / best)

    params = CoreParams(period=1.0, rema=rema)
    east, north, speed, heading = synthetic_drive(args.stream_points, 1.0)
    pipe = CorePipeline(params)
    times = np.empty(args.stream_points)
    clock = time.perf_counter_ns
    update = pipe.update
    for i in range(args.stream_points):
        e, n, s, h = float(east[i]), float(north[i]), float(speed[i]), float(heading[i])
        t0 = clock()
        update(e, n, s, h)
        times[i] = clock() - t0
    results["stream_median_us"] = round(float(np.median(times)) / 1000, 3)
    results["stream_p99_us"] = round(float(np.percentile(times, 99)) / 1000, 3)
    results["load_average_after"] = round(os.getloadavg()[0], 2)

    text = json.dumps(results, indent=2)
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
