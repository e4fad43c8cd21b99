"""``gradgps serve-redis`` against a real redis-server: SIGKILL mid-run, restart, exactly once.

20 vehicles x 500 fixes are pushed, interleaved in time as a live fleet
would send them. A worker process is killed with SIGKILL while it works;
then it is restarted under its name next to a second worker. At the end the
output stream must hold exactly one result per input message, each
vehicle's results in time order, and the same numbers as one uninterrupted
``Detector`` per vehicle (so the checkpointed states were restored exactly).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._run.fleet_redis import parse_output
from redis_server import redis_server

redis = pytest.importorskip("redis")

VEHICLES, POINTS = 20, 500
WAIT_S = 60.0
SRC = Path(__file__).resolve().parents[1] / "src"


@pytest.fixture
def redis_url(tmp_path: Path) -> Iterator[str]:
    with redis_server(tmp_path) as url:
        yield url


def _worker(url: str, consumer: str, log: Path) -> subprocess.Popen[bytes]:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
        "NUMBA_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
    }
    with log.open("ab") as sink:  # the child keeps its own descriptor
        return subprocess.Popen(
            [
                sys.executable,
                "-m",
                "gradgps",
                "serve-redis",
                "--url",
                url,
                "--input-stream",
                "fixes",
                "--output-stream",
                "results",
                "--group",
                "grad",
                "--consumer",
                consumer,
                "--batch-size",
                "50",
                "--lease-ms",
                "2000",
                "--block-ms",
                "100",
            ],
            env=env,
            stdout=sink,
            stderr=subprocess.STDOUT,
        )


def _wait_until(
    condition: object, what: str, procs: list[subprocess.Popen[bytes]], logs: list[Path]
) -> None:
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        if condition():  # type: ignore[operator]
            return
        for proc, log in zip(procs, logs, strict=True):
            if proc.poll() is not None:
                pytest.fail(
                    f"worker exited with {proc.returncode} while waiting for {what}:\n"
                    + log.read_text()
                )
        time.sleep(0.02)
    pytest.fail(f"timed out after {WAIT_S:.0f} s waiting for {what}")


def test_sigkill_mid_run_then_restart_gives_exactly_one_result_per_message(
    redis_url: str, tmp_path: Path
) -> None:
    client = redis.Redis.from_url(redis_url, decode_responses=True)
    fleet = simulate_fleet(VEHICLES, POINTS / 60, 1.0, seed=7).sort_values(
        ["t", "track"], kind="stable"
    )
    assert len(fleet) == VEHICLES * POINTS
    pipe = client.pipeline(transaction=False)
    for row in fleet.itertuples():
        pipe.xadd(
            "fixes",
            {
                "vehicle_id": row.track,
                "t": repr(row.t),
                "lat": repr(row.lat),
                "lon": repr(row.lon),
                "speed": repr(row.speed),
                "heading": repr(row.heading),
                "yaw_rate": repr(row.yaw_rate),
            },
        )
    input_ids = pipe.execute()

    logs = [tmp_path / "w1-first.log", tmp_path / "w1-again.log", tmp_path / "w2.log"]
    first = _worker(redis_url, "w1", logs[0])
    try:
        _wait_until(lambda: client.xlen("results") >= 1000, "1,000 results", [first], logs[:1])
        first.send_signal(signal.SIGKILL)
        first.wait(timeout=10)
    finally:
        first.kill()
    done_at_kill = client.xlen("results")
    assert done_at_kill < VEHICLES * POINTS, "the worker finished before it could be killed"

    again, second = _worker(redis_url, "w1", logs[1]), _worker(redis_url, "w2", logs[2])
    try:
        _wait_until(
            lambda: (
                client.xlen("results") >= VEHICLES * POINTS
                and client.xpending("fixes", "grad")["pending"] == 0
            ),
            "all results",
            [again, second],
            logs[1:],
        )
        time.sleep(0.5)  # anything still in flight would show up as an extra result
        for proc in (again, second):
            proc.send_signal(signal.SIGTERM)
        for proc in (again, second):
            assert proc.wait(timeout=20) == 0
    finally:
        again.kill()
        second.kill()

    out = pd.DataFrame([parse_output(f) for _, f in client.xrange("results")])
    assert len(out) == VEHICLES * POINTS
    assert out["source_id"].is_unique
    assert set(out["source_id"]) == set(input_ids)
    assert (out["invalid_reason"] == "").all()
    for vehicle, rows in out.groupby("vehicle_id", sort=False):
        assert np.all(np.diff(rows["t"].to_numpy()) > 0), f"vehicle {vehicle} out of order"
        track = fleet[fleet["track"] == vehicle]
        detector = Detector()
        expected = [
            detector.update(r.t, r.lat, r.lon, r.speed, r.heading) for r in track.itertuples()
        ]
        assert rows["anomaly"].tolist() == [e.anomaly for e in expected]
        np.testing.assert_array_equal(rows["score"].to_numpy(), [e.score for e in expected])
        np.testing.assert_array_equal(rows["lat_clean"].to_numpy(), [e.lat_clean for e in expected])
        assert rows["bias_type"].tolist() == [e.bias_type for e in expected]
