"""Hostile messages and states never stop a Redis worker (issue 18, items 1-3).

On main: a field named ``self`` raised TypeError (extra fields went to
``update()`` as keyword arguments), a non-UTF-8 byte raised
UnicodeDecodeError in redis-py, a ``vehicle_id`` given twice was routed by
its first value and processed under its last (earlier well-formed messages
were acknowledged without output), and a hand-written ``state:`` key was
restored into a detector that then read out of bounds. Each worker that
took the page over crashed too. Here each of those messages gets its own
result and every well-formed message its normal one.
"""

from __future__ import annotations

import json
from typing import Any

import pandas as pd
import pytest

from gradgps._grad.detector import Detector
from gradgps._run.fleet_redis import OUTPUT_FIELDS, RedisStreamWorker, parse_output

fakeredis = pytest.importorskip("fakeredis")
pytest.importorskip("lupa", reason="fakeredis runs the routing Lua script with lupa")

IN, OUT, GROUP = "fixes", "results", "grad"


@pytest.fixture
def server() -> Any:
    return fakeredis.FakeServer()


def _client(server: Any) -> Any:
    return fakeredis.FakeRedis(server=server, decode_responses=True)


def _raw(server: Any) -> Any:
    return fakeredis.FakeRedis(server=server)


def _worker(server: Any, name: str = "w1") -> RedisStreamWorker:
    worker = RedisStreamWorker(_client(server), IN, OUT, GROUP, name, batch_size=8)
    worker.ensure_group()
    return worker


def _drain(*workers: RedisStreamWorker) -> None:
    for _ in range(100):
        reports = [w.step() for w in workers]
        if not any(r.routed_here or r.processed or r.taken_over for r in reports):
            return
    pytest.fail("workers still busy")


def _results(server: Any) -> pd.DataFrame:
    rows = [parse_output(f) for _, f in _client(server).xrange(OUT)]
    return pd.DataFrame(rows, columns=list(OUTPUT_FIELDS)).set_index("source_id")


def _fix(vehicle: str, i: int) -> dict[str, str]:
    return {"vehicle_id": vehicle, "t": str(1000 + i), "lat": "48.1", "lon": repr(11.5 + i * 1e-4)}


def test_a_field_named_self_is_just_an_ignored_channel(server: Any) -> None:
    client = _client(server)
    ids = [client.xadd(IN, {**_fix("a", i), "self": "1", "t_": "x"}) for i in range(3)]
    _drain(_worker(server))
    out = _results(server)
    assert list(out.index) == ids
    assert (out["invalid_reason"] == "").all()


@pytest.mark.parametrize(
    ("fields", "reason"),
    [
        ({b"vehicle_id": b"a", b"t": b"\xff1", b"lat": b"48", b"lon": b"11"}, "'t' is not UTF-8"),
        (
            {b"vehicle_id": b"a", b"t": b"5", b"lat": b"48", b"\xfe": b"1", b"lon": b"11"},
            "not UTF-8",
        ),
        (
            {b"vehicle_id": b"\xc3(", b"t": b"5", b"lat": b"48", b"lon": b"11"},
            "'vehicle_id' is not UTF-8",
        ),
    ],
)
def test_non_utf8_bytes_give_a_flagged_result_and_the_worker_goes_on(
    server: Any, fields: dict[bytes, bytes], reason: str
) -> None:
    client = _client(server)
    before = [client.xadd(IN, _fix("a", i)) for i in range(3)]
    bad = _raw(server).xadd(IN, fields).decode()
    after = [client.xadd(IN, _fix("a", i)) for i in range(3, 6)]
    worker = _worker(server)
    _drain(worker)
    out = _results(server)
    assert list(out.index) == [*before, bad, *after]
    assert reason in out.loc[bad, "invalid_reason"]
    assert out.loc[bad, "anomaly"] == 1
    assert (out.drop(index=bad)["invalid_reason"] == "").all()
    assert _client(server).xpending(IN, GROUP)["pending"] == 0
    # the good messages are exactly what one uninterrupted detector gives
    det = Detector()
    expected = [det.update(1000 + i, 48.1, 11.5 + i * 1e-4).score for i in range(6)]
    assert out.drop(index=bad)["score"].tolist() == expected


def test_a_repeated_vehicle_id_is_flagged_and_loses_no_other_message(server: Any) -> None:
    """The issue's case: three messages of vehicle b, then one naming a and b (4 in, 1 out)."""
    client = _client(server)
    raw = _raw(server)
    ids = [client.xadd(IN, _fix("b", i)) for i in range(3)]
    # redis-py takes a dict, so a repeated field needs the raw command
    twice = raw.execute_command(
        "XADD",
        IN,
        "*",
        "vehicle_id",
        "a",
        "t",
        "1005",
        "lat",
        "48.1",
        "lon",
        "11.5",
        "vehicle_id",
        "b",
    ).decode()
    ids.append(client.xadd(IN, _fix("b", 3)))
    w1, w2 = _worker(server, "w1"), _worker(server, "w2")
    _drain(w1, w2)
    out = _results(server)
    assert sorted(out.index) == sorted([*ids, twice])  # 5 in, 5 out
    assert "'vehicle_id' appears more than once" in out.loc[twice, "invalid_reason"]
    assert out.loc[twice, "vehicle_id"] == "a"  # the first value, as the router uses
    b = out[out["vehicle_id"] == "b"]
    assert (b["invalid_reason"] == "").all()
    assert b["t"].tolist() == [1000.0, 1001.0, 1002.0, 1003.0]


@pytest.mark.parametrize(
    "stored",
    [
        "not json",
        json.dumps({"last_id": "0-0"}),
        json.dumps({"last_id": "x", "detector": {}}),
        "[" * 100_000,
        "damaged-S",
        "truncated-H",
        "edited-P",
    ],
)
def test_a_damaged_state_key_gives_a_fresh_detector_and_a_dead_letter(
    server: Any, stored: str
) -> None:
    client = _client(server)
    worker = _worker(server)
    first = [client.xadd(IN, _fix("a", i)) for i in range(20)]
    _drain(worker)
    key = f"gradgps:{IN}:{GROUP}:state:a"
    record = json.loads(client.get(key))
    if stored == "damaged-S":
        record["detector"]["S"] = []
        stored = json.dumps(record)
    elif stored == "truncated-H":
        record["detector"]["H"] = record["detector"]["H"][:4]
        stored = json.dumps(record)
    elif stored == "edited-P":
        record["detector"]["period"] = 1e-300
        stored = json.dumps(record)
    client.set(key, stored)
    later = [client.xadd(IN, _fix("a", i)) for i in range(20, 60)]
    for w in (worker, _worker(server, "w2")):  # the cached detector, and a fresh worker
        w._tracks.clear()
    _drain(worker)
    out = _results(server)
    assert list(out.index) == [*first, *later]
    assert (out["invalid_reason"] == "").all()
    dead = client.xrange(worker.dead_letter_stream)
    assert len(dead) == 1
    assert dead[0][1]["key"] == key
    assert "fresh detector" in dead[0][1]["problem"]
    # the restart is a fresh detector from message 20 on
    det = Detector()
    expected = [det.update(1000 + i, 48.1, 11.5 + i * 1e-4).score for i in range(20, 60)]
    assert out.loc[later, "score"].tolist() == expected


@pytest.mark.parametrize("damage", ["prefix", "inside last_id", "inside the state"])
def test_a_state_key_with_non_utf8_bytes_does_not_stop_the_worker(server: Any, damage: str) -> None:
    """A state key holding bytes that are not UTF-8: on main the client's decoding raised
    UnicodeDecodeError for the whole page, the worker stopped with it pending, and so did
    every restart. Now the vehicle restarts with a fresh detector and a dead-letter entry."""
    client = _client(server)
    worker = _worker(server)
    first = [client.xadd(IN, _fix("a", i)) for i in range(10)]
    _drain(worker)
    key = f"gradgps:{IN}:{GROUP}:state:a"
    text = client.get(key).encode()
    stored = {
        "prefix": b"\xff" + text,
        "inside last_id": text.replace(b'"last_id": "', b'"last_id": "\xc3('),
        "inside the state": text.replace(b'"format"', b'"form\xfet"'),
    }[damage]
    assert stored != text
    _raw(server).set(key, stored)
    later = [client.xadd(IN, _fix("a", i)) for i in range(10, 30)]
    worker._tracks.clear()
    _drain(worker)
    out = _results(server)
    assert list(out.index) == [*first, *later]
    assert (out["invalid_reason"] == "").all()
    assert client.xpending(IN, GROUP)["pending"] == 0
    dead = client.xrange(worker.dead_letter_stream)
    assert [d[1]["key"] for d in dead] == [key]
    det = Detector()
    expected = [det.update(1000 + i, 48.1, 11.5 + i * 1e-4).score for i in range(10, 30)]
    assert out.loc[later, "score"].tolist() == expected
