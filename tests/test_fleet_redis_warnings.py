"""The Redis worker's input checks: each vehicle gets follow mode's warnings, once each,
exactly once, whatever worker restores its state."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd
import pytest

from gradgps._data.simulator import simulate_fleet
from gradgps._run.fleet_redis import RedisStreamWorker
from gradgps._run.follow import follow_lines
from gradgps._tracks.input_checks import CHECK_EVERY, InputChecks

fakeredis = pytest.importorskip("fakeredis")
pytest.importorskip("lupa", reason="fakeredis runs the routing Lua script with lupa")

IN, OUT, GROUP = "fixes", "results", "grad"
# Two looks of the checks: after CHECK_EVERY fixes, then after twice as many more.
FIXES = 3 * CHECK_EVERY


@pytest.fixture(scope="module")
def fleet() -> pd.DataFrame:
    """Vehicle 0 sends one fix every 5 s (slower than any validated rate), vehicle 1 one a
    second; positions only, interleaved in time as a live fleet sends them."""
    slow = simulate_fleet(1, 5 * FIXES / 60 + 1, 1.0, seed=11).iloc[::5].iloc[:FIXES]
    fast = simulate_fleet(1, FIXES / 60 + 1, 1.0, seed=12).iloc[:FIXES]
    assert len(slow) == len(fast) == FIXES
    both = pd.concat([slow.assign(track="0"), fast.assign(track="1")])
    return both[["track", "t", "lat", "lon"]].sort_values(["t", "track"], kind="stable")


def _client(server: Any) -> Any:
    return fakeredis.FakeRedis(server=server, decode_responses=True)


def _push(server: Any, fleet: pd.DataFrame) -> list[str]:
    client = _client(server)
    return [
        client.xadd(
            IN, {"vehicle_id": r.track, "t": repr(r.t), "lat": repr(r.lat), "lon": repr(r.lon)}
        )
        for r in fleet.itertuples()
    ]


def _follow_warnings(track: pd.DataFrame) -> list[str]:
    said: list[str] = []
    lines = ["t,lat,lon", *(f"{r.t!r},{r.lat!r},{r.lon!r}" for r in track.itertuples())]
    follow_lines(lines, lambda _: None, warn=said.append)
    return said


def _drain(worker: RedisStreamWorker) -> None:
    for _ in range(1000):
        report = worker.step()
        if not (report.routed_here or report.processed or report.taken_over):
            return
    pytest.fail("worker still busy")


def test_each_vehicle_gets_follow_modes_warnings_once_at_the_fix_that_showed_them(
    fleet: pd.DataFrame,
) -> None:
    server = fakeredis.FakeServer()
    ids = _push(server, fleet)
    # Pages of 97 messages cut the looks' fix counts anywhere; a fresh worker half way
    # through goes on from the stored checks (its cache is empty).
    first = RedisStreamWorker(_client(server), IN, OUT, GROUP, "w1", batch_size=97)
    first.ensure_group()
    first.heartbeat()
    first.route()
    first.process_pending()
    second = RedisStreamWorker(_client(server), IN, OUT, GROUP, "w2", batch_size=97)
    _client(server).delete(f"gradgps:{IN}:{GROUP}:alive:w1")
    _drain(second)
    assert _client(server).xlen(OUT) == len(ids)

    said = [f for _, f in _client(server).xrange(f"{OUT}:warnings")]
    for vehicle, track in fleet.groupby("track"):
        expected = _follow_warnings(track)
        mine = [f for f in said if f["vehicle_id"] == vehicle]
        assert [f["warning"] for f in mine] == expected
        if vehicle == "0":
            assert any("slower than the slowest" in w for w in expected), expected
            # Found at the first look: the vehicle's CHECK_EVERY-th fix.
            vehicle_ids = [
                i for i, r in zip(ids, fleet.itertuples(), strict=True) if r.track == "0"
            ]
            assert mine[0]["source_id"] == vehicle_ids[CHECK_EVERY - 1]
        else:
            assert expected == []


def test_checks_state_goes_on_as_if_nothing_had_stopped(fleet: pd.DataFrame) -> None:
    """InputChecks.to_state/from_state: stopped and restored half way, the checks find what
    checks fed everything at once find, and the state survives JSON."""
    frame = fleet[fleet["track"] == "0"].assign(speed=12.0, heading=90.0)
    whole = InputChecks().add(frame)
    half = InputChecks().add(frame.iloc[:700])
    restored = InputChecks.from_state(json.loads(json.dumps(half.to_state())))
    restored.add(frame.iloc[700:])
    assert restored.findings() == whole.findings()
    assert json.dumps(restored.to_state()) == json.dumps(whole.to_state())
    np.testing.assert_array_equal(restored.heading_diff_hist, whole.heading_diff_hist)


def test_a_damaged_checks_state_is_reported_and_the_vehicle_starts_afresh(
    fleet: pd.DataFrame,
) -> None:
    server = fakeredis.FakeServer()
    client = _client(server)
    _push(server, fleet.iloc[:10])
    worker = RedisStreamWorker(client, IN, OUT, GROUP, "w1", batch_size=4)
    worker.ensure_group()
    _drain(worker)
    key = f"gradgps:{IN}:{GROUP}:state:0"
    record = json.loads(client.get(key))
    record["checks"]["checks"]["hist"] = [[10**9, 1]]
    client.set(key, json.dumps(record))
    _push(server, fleet.iloc[10:14])
    _drain(RedisStreamWorker(client, IN, OUT, GROUP, "w2", batch_size=4))
    dead = [f for _, f in client.xrange(f"gradgps:{IN}:{GROUP}:dead-letter")]
    assert any("histogram bin" in f["problem"] and f["key"] == key for f in dead), dead
    assert client.xlen(OUT) == 14


def test_a_vehicle_gets_the_warning_for_fixes_it_could_not_use(fleet: pd.DataFrame) -> None:
    """A vehicle whose fixes carry a repeated timestamp at a new position (a time column
    coarser than its fixes): the repeat is unusable, and still goes to the checks, so the
    vehicle gets follow mode's ``repeated timestamps`` warning (before: none)."""
    track = fleet[fleet["track"] == "1"].iloc[: CHECK_EVERY + 10].copy()  # one look
    track.iloc[101:, track.columns.get_loc("t")] -= 1.0
    server = fakeredis.FakeServer()
    _push(server, track)
    worker = RedisStreamWorker(_client(server), IN, OUT, GROUP, "w1", batch_size=64)
    worker.ensure_group()
    _drain(worker)
    said = [f["warning"] for _, f in _client(server).xrange(f"{OUT}:warnings")]
    expected = _follow_warnings(track)
    assert [w for w in expected if w.startswith("repeated timestamps")], expected
    assert said == expected
