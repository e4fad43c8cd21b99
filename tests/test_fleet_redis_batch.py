"""The Redis worker scores each page in one FleetDetector.update_many, and a page whose batch
raises is redone message by message from the stored states (only the failing message lost)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from gradgps._grad.detector import Detector
from gradgps._run.fleet_redis import RedisStreamWorker, parse_output

fakeredis = pytest.importorskip("fakeredis")
pytest.importorskip("lupa", reason="fakeredis runs the routing Lua script with lupa")

IN, OUT, GROUP = "fixes", "results", "grad"


def _client(server: Any) -> Any:
    return fakeredis.FakeRedis(server=server, decode_responses=True)


def _push(server: Any, n_vehicles: int, n_fixes: int) -> list[tuple[str, str, float, float]]:
    client = _client(server)
    sent = []
    for i in range(n_fixes):
        for k in range(n_vehicles):
            t, lat, lon = 100.0 + i, 45.0 + k * 0.01 + i * 1e-4, 7.0 + (i % 3) * 1e-6
            fields = {"vehicle_id": f"v{k}", "t": repr(t), "lat": repr(lat), "lon": repr(lon)}
            sent.append((client.xadd(IN, fields), f"v{k}", t, lat))
    return sent


def _results(server: Any) -> pd.DataFrame:
    rows = [parse_output(f) for _, f in _client(server).xrange(OUT)]
    return pd.DataFrame(rows).set_index("source_id")


def _drain(worker: RedisStreamWorker) -> None:
    for _ in range(100):
        report = worker.step()
        if not (report.routed_here or report.processed or report.taken_over):
            return
    pytest.fail("worker still busy")


def test_a_page_is_one_update_many_call(monkeypatch: pytest.MonkeyPatch) -> None:
    server = fakeredis.FakeServer()
    sent = _push(server, 6, 20)
    worker = RedisStreamWorker(_client(server), IN, OUT, GROUP, "w", batch_size=40)
    worker.ensure_group()
    calls: list[int] = []
    update_many = worker._fleet.update_many

    def counted(vehicle_ids: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append(len(vehicle_ids))
        return update_many(vehicle_ids, *args, **kwargs)

    monkeypatch.setattr(worker._fleet, "update_many", counted)
    _drain(worker)
    assert calls == [40, 40, 40]
    out = _results(server)
    assert list(out.index) == [s[0] for s in sent]
    for k in range(6):
        det = Detector()
        rows = [s for s in sent if s[1] == f"v{k}"]
        expected = [
            det.update(t, lat, 7.0 + (i % 3) * 1e-6).score for i, (_, _, t, lat) in enumerate(rows)
        ]
        np.testing.assert_array_equal(out.loc[[r[0] for r in rows], "score"], expected)


def test_a_page_whose_batch_raises_is_redone_message_by_message(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    server = fakeredis.FakeServer()
    sent = _push(server, 3, 12)
    poison = next(s for s in sent if s[1] == "v1" and s[2] == 105.0)
    worker = RedisStreamWorker(_client(server), IN, OUT, GROUP, "w", batch_size=50)
    worker.ensure_group()
    update_many = worker._fleet.update_many

    def fails_on_poison(vehicle_ids: Any, t: Any, lat: Any, *args: Any, **kwargs: Any) -> Any:
        result = update_many(vehicle_ids, t, lat, *args, **kwargs)  # states move on first
        if poison[3] in lat:
            raise RuntimeError("boom")
        return result

    monkeypatch.setattr(worker._fleet, "update_many", fails_on_poison)
    _drain(worker)
    out = _results(server)
    assert list(out.index) == [s[0] for s in sent]
    assert "could not be processed (RuntimeError: boom)" in out.loc[poison[0], "invalid_reason"]
    dead = _client(server).xrange(worker.dead_letter_stream)
    assert [f["source_id"] for _, f in dead] == [poison[0]]
    # v0 and v2 as one uninterrupted Detector; v1 restarts fresh after the poison
    for k in range(3):
        rows = [s for s in sent if s[1] == f"v{k}"]
        det = Detector()
        expected = []
        for i, (sid, _, t, lat) in enumerate(rows):
            if sid == poison[0]:
                det = Detector()
                expected.append(np.nan)
                continue
            expected.append(det.update(t, lat, 7.0 + (i % 3) * 1e-6).score)
        np.testing.assert_array_equal(out.loc[[r[0] for r in rows], "score"], expected)
