"""RedisStreamWorker on fakeredis: exactly one result per message, each vehicle in order.

Workers here are objects sharing one fake server, each with its own client
(as separate processes would be); crashes are simulated by a commit that
raises before its transaction, and death by deleting the alive key (what
the lease expiring does). The real server, a real SIGKILL and a restarted
process are in test_fleet_redis_server.py.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from gradgps import ConfigError
from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector
from gradgps._run.fleet_redis import OUTPUT_FIELDS, RedisStreamWorker, parse_output

fakeredis = pytest.importorskip("fakeredis")
pytest.importorskip("lupa", reason="fakeredis runs the routing Lua script with lupa")

IN, OUT, GROUP = "fixes", "results", "grad"


class Crash(Exception):
    """Stands for the process dying in the middle of a page."""


@pytest.fixture(scope="module")
def fleet() -> pd.DataFrame:
    """4 vehicles x 60 fixes, interleaved in time as a live fleet sends them."""
    return simulate_fleet(4, 1.0, 1.0, seed=3).sort_values(["t", "track"], kind="stable")


@pytest.fixture
def server() -> Any:
    return fakeredis.FakeServer()


def _client(server: Any) -> Any:
    return fakeredis.FakeRedis(server=server, decode_responses=True)


def _worker(server: Any, name: str, batch_size: int = 16) -> RedisStreamWorker:
    worker = RedisStreamWorker(_client(server), IN, OUT, GROUP, name, batch_size=batch_size)
    worker.ensure_group()
    return worker


def _push(server: Any, fleet: pd.DataFrame) -> list[str]:
    client = _client(server)
    return [
        client.xadd(
            IN,
            {
                "vehicle_id": r.track,
                "t": repr(r.t),
                "lat": repr(r.lat),
                "lon": repr(r.lon),
                "speed": repr(r.speed),
                "heading": repr(r.heading),
            },
        )
        for r in fleet.itertuples()
    ]


def _drain(*workers: RedisStreamWorker, rounds: int = 200) -> None:
    """Step the workers in turn until one full round does nothing."""
    for _ in range(rounds):
        reports = [w.step() for w in workers]
        if not any(r.routed_here or r.processed or r.taken_over for r in reports):
            return
    pytest.fail(f"workers still busy after {rounds} rounds")


def _results(server: Any) -> pd.DataFrame:
    return pd.DataFrame([parse_output(f) for _, f in _client(server).xrange(OUT)])


def _check_exactly_once_and_exact(server: Any, fleet: pd.DataFrame, ids: list[str]) -> None:
    """One result per input id, and per vehicle the numbers of one uninterrupted Detector."""
    out = _results(server)
    assert list(out.columns) == list(OUTPUT_FIELDS)
    assert out["source_id"].is_unique
    assert sorted(out["source_id"]) == sorted(ids)
    assert _client(server).xpending(IN, GROUP)["pending"] == 0
    for vehicle, track in fleet.groupby("track"):
        rows = out[out["vehicle_id"] == vehicle]
        detector = Detector()
        expected = [
            detector.update(r.t, r.lat, r.lon, r.speed, r.heading) for r in track.itertuples()
        ]
        assert rows["t"].tolist() == track["t"].tolist()  # every fix, in time order
        np.testing.assert_array_equal(rows["score"].to_numpy(), [e.score for e in expected])
        np.testing.assert_array_equal(rows["lon_clean"].to_numpy(), [e.lon_clean for e in expected])
        assert rows["anomaly"].tolist() == [e.anomaly for e in expected]
        assert rows["time_type"].tolist() == [e.time_type for e in expected]


def _crash_on_commit(worker: RedisStreamWorker, monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Make the worker's next commit die before its transaction; returns the page it held."""
    held: list[Any] = []

    def crash(messages: list[Any]) -> tuple[int, int]:
        held.extend(messages)
        raise Crash

    monkeypatch.setattr(worker, "_commit", crash)
    return held


def test_one_worker_gives_a_streaming_detector_per_vehicle(
    server: Any, fleet: pd.DataFrame
) -> None:
    ids = _push(server, fleet)
    _drain(_worker(server, "w1"))
    _check_exactly_once_and_exact(server, fleet, ids)


def test_two_workers_share_the_group_and_keep_each_vehicle_in_order(
    server: Any, fleet: pd.DataFrame
) -> None:
    ids = _push(server, fleet)
    a, b = _worker(server, "a", batch_size=7), _worker(server, "b", batch_size=5)
    passed = 0
    a.heartbeat()
    for _ in range(200):
        # a reads and routes, b reads and routes before a processes: b must pass on a's vehicles
        ra = a.route()
        rb = b.step()
        passed += int(rb.routed_away)
        ra2 = a.step()
        if not (ra[0] or rb.routed_here or rb.processed or ra2.routed_here or ra2.processed):
            break
    assert passed > 0, "the test never made a worker pass a message to its vehicle's owner"
    _check_exactly_once_and_exact(server, fleet, ids)
    owners = _client(server).hgetall(f"{a.key_prefix}owner")
    assert set(owners.values()) <= {"a", "b"}


def test_restarted_worker_redoes_the_page_it_died_in(
    server: Any, fleet: pd.DataFrame, monkeypatch: pytest.MonkeyPatch
) -> None:
    ids = _push(server, fleet)
    first = _worker(server, "w1")
    first.step()  # a few pages done
    held = _crash_on_commit(first, monkeypatch)
    with pytest.raises(Crash):
        first.step()
    assert held, "the crash hit no page"
    _drain(_worker(server, "w1"))  # same name, fresh process: empty cache
    _check_exactly_once_and_exact(server, fleet, ids)


def test_dead_worker_is_taken_over_and_a_late_zombie_commit_adds_nothing(
    server: Any, fleet: pd.DataFrame, monkeypatch: pytest.MonkeyPatch
) -> None:
    ids = _push(server, fleet)
    dead, alive = _worker(server, "dead", batch_size=40), _worker(server, "alive")
    dead.step()
    held = _crash_on_commit(dead, monkeypatch)
    with pytest.raises(Crash):
        dead.step()
    _client(server).delete(f"{dead.key_prefix}alive:dead")  # its lease ran out
    report = alive.step()
    assert report.taken_over > 0
    _drain(alive)
    _check_exactly_once_and_exact(server, fleet, ids)
    # The "dead" one was only stalled: it wakes up and commits the page it held.
    monkeypatch.undo()
    processed, skipped = dead._commit(held)
    assert (processed, skipped) == (0, len(held))
    _check_exactly_once_and_exact(server, fleet, ids)


def test_a_conflicting_commit_is_redone_from_the_stored_state(
    server: Any, fleet: pd.DataFrame, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two workers on the same page (a stalled owner and its replacement): WATCH keeps one result."""
    ids = _push(server, fleet)
    stalled, other = _worker(server, "stalled"), _worker(server, "other")
    stalled.step()
    held = _crash_on_commit(stalled, monkeypatch)
    with pytest.raises(Crash):
        stalled.step()
    monkeypatch.undo()
    run_detectors = stalled._run_detectors
    interfered = []

    def other_commits_first(messages: Any, tracks: Any, *rest: Any) -> Any:
        if not interfered:  # between stalled's WATCH and its MULTI
            interfered.append(other._commit(held))
        return run_detectors(messages, tracks, *rest)

    monkeypatch.setattr(stalled, "_run_detectors", other_commits_first)
    assert stalled._commit(held) == (0, len(held))
    assert interfered == [(len(held), 0)]
    monkeypatch.undo()
    _drain(stalled, other)
    _check_exactly_once_and_exact(server, fleet, ids)


def test_unusable_messages_get_a_result_with_the_reason(server: Any) -> None:
    client = _client(server)
    no_vehicle = client.xadd(IN, {"t": "1", "lat": "45", "lon": "7"})
    bad_lat = client.xadd(IN, {"vehicle_id": "v", "t": "1", "lat": "north", "lon": "7"})
    good = client.xadd(IN, {"vehicle_id": "v", "t": "2", "lat": "45", "lon": "7", "odd": "x"})
    _drain(_worker(server, "w1"))
    out = _results(server).set_index("source_id")
    assert out.loc[no_vehicle, "invalid_reason"] == "message has no vehicle_id"
    assert out.loc[bad_lat, "invalid_reason"] == "latitude missing or not finite"
    assert out.loc[bad_lat, "anomaly"] == 1
    assert out.loc[good, "invalid_reason"] == ""
    assert out.loc[good, "lat_clean"] == pytest.approx(45.0, abs=1e-6)


def test_worker_settings_are_checked(server: Any) -> None:
    with pytest.raises(ConfigError, match="decode_responses"):
        RedisStreamWorker(fakeredis.FakeRedis(server=server), IN, OUT, GROUP, "w")
    with pytest.raises(ConfigError, match="differ"):
        RedisStreamWorker(_client(server), IN, IN, GROUP, "w")
    with pytest.raises(ConfigError, match="consumer"):
        RedisStreamWorker(_client(server), IN, OUT, GROUP, "")


def test_a_settling_model_revises_outputs_into_the_final_verdicts_exactly_once(
    server: Any, fleet: pd.DataFrame, tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A model with a confirm head (verdicts settle one fix late): each message gets its
    verdict at once on the output stream, and the revision stream corrects those a
    vehicle's next fix settles differently, exactly once, through a crash and a restart:
    outputs with the revisions applied are each vehicle's final verdicts."""
    from _detector_checks import final_verdicts
    from _gru_support import random_detector_model

    model = random_detector_model(tmp_path / "confirm", confirm_head=True)
    ids = _push(server, fleet)

    def worker(name: str, batch_size: int) -> RedisStreamWorker:
        w = RedisStreamWorker(
            _client(server), IN, OUT, GROUP, name, batch_size=batch_size, model=model
        )
        w.ensure_group()
        return w

    first = worker("w1", 16)
    assert first.settles
    assert first.revision_stream == f"{OUT}:revisions"
    first.step()
    held = _crash_on_commit(first, monkeypatch)
    with pytest.raises(Crash):
        first.step()
    assert held, "the crash hit no page"
    _drain(worker("w1", 16), worker("w2", 5))
    out = _results(server)
    assert sorted(out["source_id"]) == sorted(ids)
    revisions = pd.DataFrame(
        [parse_output(f) for _, f in _client(server).xrange(first.revision_stream)]
    )
    assert list(revisions.columns) == list(OUTPUT_FIELDS)
    assert revisions["source_id"].is_unique
    assert len(revisions) > 3  # else the test could not tell
    final = out.set_index("source_id")
    final.update(revisions.set_index("source_id"))
    for vehicle, track in fleet.groupby("track"):
        rows = final[final["vehicle_id"] == vehicle]
        columns = track[["t", "lat", "lon", "speed", "heading"]]
        want = final_verdicts(Detector(model), columns.itertuples(index=False))
        assert rows["anomaly"].astype(int).tolist() == [w.anomaly for w in want]
        assert rows["time_type"].tolist() == [w.time_type for w in want]
        np.testing.assert_array_equal(
            rows["lat_clean"].to_numpy(float), [w.lat_clean for w in want]
        )
