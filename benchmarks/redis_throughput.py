"""Throughput and latency of ``gradgps serve-redis`` on a loopback redis-server it starts itself.

    python benchmarks/redis_throughput.py --json benchmarks/results/redis_throughput.json \
        [--vehicles 200] [--fixes 200] [--batch-size 1000] [--rate 2000] [--seconds 10]

* throughput: ``--vehicles`` x ``--fixes`` simulated fixes (interleaved in
  time, as a live fleet sends them) are queued first; then 1, and separately
  2, worker processes drain them. Reported: fixes/s from the first result to
  the last (``steady``) and from the workers' start (``with_start``: process
  start, imports, model load included);
* latency: one worker, already warm; a producer offers ``--rate`` fixes/s
  (``--vehicles`` vehicles in turn, in bursts every 10 ms) for ``--seconds``;
  end-to-end latency per fix = the time its result is read from the output
  stream minus the time its ``XADD`` returned (p50, p99, max, ms).

The redis-server runs on 127.0.0.1 with no persistence; the machine, its
load average and the command go into the JSON. Needs ``redis-server`` on the
PATH and the ``redis`` client.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import redis

from gradgps import simulate_fleet, to_fixes

IN, OUT, GROUP = "fixes", "results", "grad"
SRC = Path(__file__).resolve().parents[1] / "src"


@contextmanager
def redis_server() -> Iterator[str]:
    """A throwaway redis-server on a free loopback port (as tests/redis_server.py)."""
    binary = shutil.which("redis-server")
    if binary is None:
        sys.exit("redis-server not found on the PATH")
    with tempfile.TemporaryDirectory() as workdir, socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        s.close()
        proc = subprocess.Popen(
            [
                *(binary, "--bind", "127.0.0.1", "--port", str(port), "--dir", workdir),
                *("--save", "", "--appendonly", "no"),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        url = f"redis://127.0.0.1:{port}/0"
        try:
            client = redis.Redis.from_url(url)
            for _ in range(200):
                try:
                    client.ping()
                    break
                except redis.ConnectionError:
                    time.sleep(0.05)
            yield url
        finally:
            proc.terminate()
            proc.wait(timeout=10)


def _workers(url: str, n: int, batch_size: int, idle_s: float | None) -> list[Any]:
    env = {**os.environ, "PYTHONPATH": str(SRC), "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", "gradgps", "serve-redis", "--url", url]
    cmd += ["--input-stream", IN, "--output-stream", OUT, "--group", GROUP]
    cmd += ["--batch-size", str(batch_size), "--block-ms", "100"]
    if idle_s is not None:
        cmd += ["--exit-when-idle", str(idle_s)]
    return [
        subprocess.Popen(
            [*cmd, "--consumer", f"w{k}"],
            env=env,
            stderr=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
        )
        for k in range(n)
    ]


def _fleet(vehicles: int, fixes: int) -> list[dict[str, str]]:
    data = to_fixes(simulate_fleet(vehicles, fixes / 60.0, 1.0, seed=21))
    data = data.sort_values(["t", "track"], kind="stable")
    return [
        {
            "vehicle_id": str(r.track),
            "t": repr(r.t),
            "lat": repr(r.lat),
            "lon": repr(r.lon),
            "speed": repr(r.speed),
            "heading": repr(r.heading),
        }
        for r in data.itertuples()
    ]


def _push(client: redis.Redis, messages: list[dict[str, str]]) -> list[str]:
    ids: list[str] = []
    for k in range(0, len(messages), 1000):
        pipe = client.pipeline(transaction=False)
        for m in messages[k : k + 1000]:
            pipe.xadd(IN, m)  # type: ignore[arg-type]
        ids += [i.decode() if isinstance(i, bytes) else i for i in pipe.execute()]
    return ids


def throughput(messages: list[dict[str, str]], workers: int, batch_size: int) -> dict[str, float]:
    with redis_server() as url:
        client = redis.Redis.from_url(url)
        _push(client, messages)
        n = len(messages)
        start = time.perf_counter()
        procs = _workers(url, workers, batch_size, idle_s=2.0)
        first = None
        while True:
            done = client.xlen(OUT)
            if done and first is None:
                first = (time.perf_counter(), done)
            if done >= n:
                break
            if all(p.poll() is not None for p in procs):
                raise RuntimeError(f"workers exited with {done} of {n} results")
            time.sleep(0.01)
        end = time.perf_counter()
        for p in procs:
            p.wait(timeout=60)
        assert first is not None
        return {
            "fixes": n,
            "fixes_per_s_steady": (n - first[1]) / (end - first[0]),
            "fixes_per_s_with_start": n / (end - start),
        }


def latency(
    messages: list[dict[str, str]], rate: float, seconds: float, batch_size: int
) -> dict[str, float]:
    with redis_server() as url:
        client = redis.Redis.from_url(url, decode_responses=True)
        procs = _workers(url, 1, batch_size, idle_s=None)
        try:
            # Warm up: one fix per vehicle, wait for all their results.
            vehicles = list(dict.fromkeys(m["vehicle_id"] for m in messages))
            warm = [m for m in messages if m["vehicle_id"] in vehicles][: len(vehicles)]
            _push(client, warm)
            while client.xlen(OUT) < len(warm):
                time.sleep(0.05)
            last_seen = client.xrevrange(OUT, count=1)[0][0]
            sent: dict[str, float] = {}
            seen: dict[str, float] = {}
            total = int(rate * seconds)
            rest = messages[len(warm) : len(warm) + total]

            def collect() -> None:
                reader = redis.Redis.from_url(url, decode_responses=True)
                cursor = last_seen
                while len(seen) < len(rest):
                    reply = reader.xread({OUT: cursor}, count=10_000, block=1000)
                    now = time.perf_counter()
                    for _, entries in reply or []:
                        for entry_id, fields in entries:
                            seen[fields["source_id"]] = now
                            cursor = entry_id

            collector = threading.Thread(target=collect, daemon=True)
            collector.start()
            tick = 0.01
            per_tick = max(1, round(rate * tick))
            t0 = time.perf_counter()
            for k in range(0, len(rest), per_tick):
                target = t0 + (k // per_tick) * tick
                delay = target - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                pipe = client.pipeline(transaction=False)
                for m in rest[k : k + per_tick]:
                    pipe.xadd(IN, m)  # type: ignore[arg-type]
                ids = pipe.execute()
                now = time.perf_counter()
                for i in ids:
                    sent[i] = now
            offered = len(rest) / (time.perf_counter() - t0)
            collector.join(timeout=120)
        finally:
            for p in procs:
                p.terminate()
                p.wait(timeout=30)
        ms = np.array([(seen[i] - sent[i]) * 1e3 for i in sent if i in seen])
        return {
            "offered_fixes_per_s": offered,
            "latency_fixes": len(ms),
            "latency_lost": len(sent) - len(ms),
            "latency_p50_ms": float(np.percentile(ms, 50)),
            "latency_p99_ms": float(np.percentile(ms, 99)),
            "latency_max_ms": float(ms.max()),
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, required=True)
    parser.add_argument("--vehicles", type=int, default=200)
    parser.add_argument("--fixes", type=int, default=200, help="fixes per vehicle (throughput)")
    parser.add_argument("--batch-size", type=int, default=1000)
    parser.add_argument("--rate", type=float, default=2000.0, help="offered fixes/s (latency)")
    parser.add_argument("--seconds", type=float, default=10.0, help="latency run length")
    parser.add_argument("--note", default="", help="free text: the load on the machine, etc.")
    args = parser.parse_args()
    result: dict[str, Any] = {
        "command": " ".join(["python", *sys.argv]),
        "machine": f"{platform.machine()} {platform.processor() or ''} {os.cpu_count()} cores".strip(),
        "python": platform.python_version(),
        "date": datetime.date.today().isoformat(),
        "load_average_before": os.getloadavg()[0],
        "note": args.note,
        "vehicles": args.vehicles,
        "batch_size": args.batch_size,
    }
    messages = _fleet(args.vehicles, args.fixes)
    for workers in (1, 2):
        for key, value in throughput(messages, workers, args.batch_size).items():
            result[f"throughput_{workers}_worker_{key}"] = value
        print(json.dumps(result, indent=2), flush=True)
    need = int(args.rate * args.seconds) + args.vehicles
    stream = _fleet(args.vehicles, -(-need // args.vehicles) + 1)
    result.update(latency(stream, args.rate, args.seconds, args.batch_size))
    result["load_average_after"] = os.getloadavg()[0]
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
