"""Speed of torch-free GRU inference (streaming step, batch, window mode, fleet step).

Usage: ``PYTHONPATH=src python benchmarks/gru_speed.py --json out/gru_speed.json``

Pinned to one CPU and one thread (OMP/numba/BLAS), weights random but seeded
(speed does not depend on the values). Kernels are compiled before timing.
Each single-step time is one Python call (what a streaming detector pays per
point, dispatch included), timed individually to report p50/p99.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from gradgps._grad.gru import GRUModel, weight_shapes  # noqa: E402

# GRUStream and GRUFleet are not part of the product: they live with the GRU tests.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from _gru_support import GRUFleet, GRUStream, stream_step_kernel  # noqa: E402


def _model(n_features: int, n_bias: int, mode: str, window: int) -> GRUModel:
    rng = np.random.default_rng(0)
    weights = {
        name: (rng.normal(size=shape) * 0.3).astype(np.float32)
        for name, shape in weight_shapes(n_features, 32, 16, n_bias).items()
    }
    return GRUModel(weights, np.zeros(n_features), np.ones(n_features), mode=mode, window=window)


def _percentiles(ns: np.ndarray) -> dict[str, float]:
    us = ns / 1e3
    return {
        "p50_us": float(np.percentile(us, 50)),
        "p99_us": float(np.percentile(us, 99)),
        "mean_us": float(us.mean()),
    }


def _time_calls(call: object, inputs: np.ndarray) -> np.ndarray:
    clock = time.perf_counter_ns
    spent = np.empty(len(inputs), np.int64)
    for i, x in enumerate(inputs):
        start = clock()
        call(x)  # type: ignore[operator]
        spent[i] = clock() - start
    return spent


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--features", type=int, default=24, help="number of input features F")
    parser.add_argument("--bias-classes", type=int, default=5)
    parser.add_argument("--steps", type=int, default=100_000, help="single steps timed")
    parser.add_argument("--cpu", type=int, default=0, help="CPU to pin to (-1: no pinning)")
    args = parser.parse_args()
    if args.cpu >= 0 and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {args.cpu})

    n_features = args.features
    rng = np.random.default_rng(1)
    inputs = rng.normal(size=(args.steps, n_features)).astype(np.float32)
    results: dict[str, object] = {
        "cpu": _cpu_name(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "features": n_features,
        "bias_classes": args.bias_classes,
        "hidden": [32, 16],
    }

    stream_model = _model(n_features, args.bias_classes, "stream", 10)
    stream = GRUStream(stream_model)
    stream.update(inputs[0])
    results["stream_step_GRUStream_update"] = _percentiles(_time_calls(stream.update, inputs))

    state = np.zeros(stream_model.state_size, np.float32)
    scratch = np.empty(n_features + 6 * 32, np.float32)
    out = np.empty(1 + args.bias_classes, np.float32)
    params, dims = stream_model.params, stream_model.dims

    def raw(x: np.ndarray) -> None:
        stream_step_kernel(params, dims, x, state, scratch, out)

    raw(inputs[0])
    results["stream_step_kernel_call"] = _percentiles(_time_calls(raw, inputs))

    for window in (10, 50):
        window_model = _model(n_features, args.bias_classes, "window", window)
        online = GRUStream(window_model)
        online.update(inputs[0])
        results[f"window{window}_step_GRUStream_update"] = _percentiles(
            _time_calls(online.update, inputs[: max(1000, args.steps // window)])
        )

    batch = np.tile(inputs, (max(1, 200_000 // len(inputs)), 1))
    stream_model.predict_stream(batch[:100])
    start = time.perf_counter()
    stream_model.predict_stream(batch)
    results["stream_batch_points_per_s"] = len(batch) / (time.perf_counter() - start)
    for window in (10, 50):
        part = batch[: max(2000, len(batch) // window)]
        stream_model.predict_windows(part[:100], window)
        start = time.perf_counter()
        stream_model.predict_windows(part, window)
        results[f"window{window}_batch_points_per_s"] = len(part) / (time.perf_counter() - start)

    n_tracks = 1000
    fleet = GRUFleet(stream_model, n_tracks)
    rows = np.arange(n_tracks, dtype=np.int64)
    fleet.step(rows, inputs[:n_tracks])
    per_vehicle = []
    for repeat in range(200):
        x = inputs[(repeat * n_tracks) % (len(inputs) - n_tracks) :][:n_tracks]
        start = time.perf_counter_ns()
        fleet.step(rows, x)
        per_vehicle.append((time.perf_counter_ns() - start) / n_tracks)
    results["fleet_1000_step_per_vehicle"] = _percentiles(np.array(per_vehicle))

    text = json.dumps(results, indent=2)
    print(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
