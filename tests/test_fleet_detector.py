"""FleetDetector: one compiled call per batch, the verdicts and states of one Detector per vehicle.

The property test draws fleets whose vehicles interleave at random and whose
fixes hold every rule of ``Detector.update``: repeated and backward times,
steps under 1 ms, gaps over ``max_gap_s`` (new segments), far jumps (new
frames), warm-ups with changing provisional periods, invalid values, (0, 0),
the receiver's no-fix fields; they are fed in batches of random sizes, and
states are moved between the two classes on the way. Every verdict and
every state must equal the reference's (a Detector per vehicle) exactly.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gradgps import ConfigError, Detector, FleetDetector
from gradgps._grad import detector
from gradgps._grad.detector import REASONS, FleetResult, ReferenceFleet
from gradgps._result import fix_reason

NAN, INF = math.nan, math.inf

# Unusual steps: repeated, backward, under 1 ms, odd periods, at and over max_gap_s (5 s).
_ODD_STEPS = st.sampled_from(
    [0.5, 0.2, 2.0, 0.0, -1.0, 0.0004, 0.001, 4.9, 5.0, 5.05, 5.5, 30.0, 0.1]
)
# Unusual moves (metres): standing still, a jump, past the 100 km frame radius, across a continent.
_ODD_MOVES = st.sampled_from([0.0, 300.0, 150_000.0, 3_000_000.0])
_READING = st.sampled_from([NAN, INF, 5.0, 12.5, -3.0, 270.0])


@st.composite
def fleets(draw: st.DrawFn, max_rows: int = 120) -> dict[str, Any]:
    """Columns of a mixed batch stream: vehicle, t, lat, lon, speed, heading, receiver fields."""
    n = draw(st.integers(0, max_rows))
    n_vehicles = draw(st.integers(1, 4))
    origin = [(draw(st.floats(-60, 60)), draw(st.floats(-170, 170))) for _ in range(n_vehicles)]
    clocks = [draw(st.sampled_from([0.0, 1_700_000_000.0, -20.0])) for _ in range(n_vehicles)]
    rows: dict[str, list[Any]] = {k: [] for k in ("v", "t", "lat", "lon", "speed", "heading")}
    rows["quality"], rows["sats"] = [], []
    # Calm fleets reach the compiled common case (a final period, the segment going on);
    # wild ones start new segments and warm-ups all the time.
    odd_percent = draw(st.sampled_from([2, 10, 40]))
    periods = [draw(st.sampled_from([1.0, 1.0, 0.5, 0.2, 2.0])) for _ in range(n_vehicles)]
    for _ in range(n):
        k = draw(st.integers(0, n_vehicles - 1))
        odd = draw(st.integers(0, 99)) < odd_percent
        clocks[k] += draw(_ODD_STEPS) if odd else periods[k]
        move = draw(_ODD_MOVES) if draw(st.integers(0, 99)) < odd_percent else 10.0
        lat0, lon0 = origin[k]
        lat0 = float(np.clip(lat0 + move * draw(st.floats(-1, 1)) / 111_000.0, -89.0, 89.0))
        lon0 = float((lon0 + move * draw(st.floats(-1, 1)) / 80_000.0 + 180.0) % 360.0 - 180.0)
        origin[k] = (lat0, lon0)
        t, lat, lon = clocks[k], lat0, lon0
        damage = "none"
        if draw(st.integers(0, 99)) < odd_percent:
            damage = draw(st.sampled_from(["t", "lat", "lon", "zero", "rx"]))
        quality: Any = None
        sats: Any = None
        if damage == "t":
            t = draw(st.sampled_from([NAN, INF, -INF]))
        elif damage == "lat":
            lat = draw(st.sampled_from([NAN, 91.0, -INF]))
        elif damage == "lon":
            lon = draw(st.sampled_from([NAN, 180.5, INF]))
        elif damage == "zero":
            lat = lon = 0.0
        elif damage == "rx":
            quality, sats = draw(st.sampled_from([(0, None), ("V", 7), (None, 0), ("3d", 0)]))
        rows["v"].append(f"car{k}")
        rows["t"].append(t)
        rows["lat"].append(lat)
        rows["lon"].append(lon)
        rows["speed"].append(draw(_READING))
        rows["heading"].append(draw(_READING))
        rows["quality"].append(quality)
        rows["sats"].append(sats)
    rows["with_rx"] = draw(st.booleans())
    rows["with_readings"] = draw(st.booleans())
    rows["cuts"] = sorted(draw(st.lists(st.integers(0, n), max_size=6)))
    rows["moves"] = draw(st.lists(st.integers(0, n_vehicles - 1), max_size=6))
    return rows


def assert_same(a: FleetResult, b: FleetResult) -> None:
    """Every verdict equal, bit for bit (NaN where the other has NaN)."""
    for name in ("score", "lat_clean", "lon_clean"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.view(np.int64).tolist() == y.view(np.int64).tolist(), name
    for name in ("anomaly", "alert", "bias_type", "time_type", "invalid_reason"):
        assert getattr(a, name).tolist() == getattr(b, name).tolist(), name


def _run(fleet: Any, rows: dict[str, Any], a: int, b: int) -> FleetResult:
    readings = rows["with_readings"]
    rx = rows["with_rx"]
    return fleet.update_many(
        rows["v"][a:b],
        np.array(rows["t"][a:b], np.float64),
        rows["lat"][a:b],
        rows["lon"][a:b],
        rows["speed"][a:b] if readings else None,
        np.array(rows["heading"][a:b]) if readings else None,
        fix_quality=rows["quality"][a:b] if rx else None,
        satellites=rows["sats"][a:b] if rx else None,
    )


def _move_a_state(fast: FleetDetector, ref: ReferenceFleet, moves: list[int]) -> None:
    """Move the next listed vehicle's state across, if it has one: reference -> fleet and
    fleet -> reference."""
    if moves:
        vehicle = f"car{moves.pop()}"
        if vehicle in ref.detectors:
            fast.drop(vehicle)
            fast.set_state(vehicle, ref.get_state(vehicle))
            ref.set_state(vehicle, fast.get_state(vehicle))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fleets())
def test_fleet_equals_a_detector_per_vehicle_bit_for_bit(rows: dict[str, Any]) -> None:
    fast, ref = FleetDetector(capacity=1), ReferenceFleet()
    bounds = [0, *rows["cuts"], len(rows["t"])]
    moves = list(rows["moves"])
    for a, b in itertools.pairwise(bounds):
        assert_same(_run(fast, rows, a, b), _run(ref, rows, a, b))
        for vehicle in list(ref.detectors):
            state = ref.get_state(vehicle)
            assert fast.get_state(vehicle) == state
            json.dumps(state, allow_nan=False)
        _move_a_state(fast, ref, moves)


@pytest.fixture(scope="module")
def confirm_model(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from _gru_support import random_detector_model

    return random_detector_model(tmp_path_factory.mktemp("confirm"), confirm_head=True)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(fleets())
def test_a_settling_fleet_equals_a_detector_per_vehicle(
    confirm_model: Path, rows: dict[str, Any]
) -> None:
    """A model whose verdicts settle one fix late (a confirm head): the verdicts at once
    and the settled ones (``Detector.settled`` after each fix) equal one Detector's per
    vehicle, bit for bit, through the kernel and the per-fix path and moved states."""
    fast, ref = FleetDetector(confirm_model, capacity=1), ReferenceFleet(confirm_model)
    bounds = [0, *rows["cuts"], len(rows["t"])]
    moves = list(rows["moves"])
    for a, b in itertools.pairwise(bounds):
        got, want = _run(fast, rows, a, b), _run(ref, rows, a, b)
        assert_same(got, want)
        assert [got.settled_point(i) for i in range(len(got))] == [
            want.settled_point(i) for i in range(len(want))
        ]
        _move_a_state(fast, ref, moves)


def test_rare_cases_and_the_kernel_share_the_work() -> None:
    """A vehicle's warm-up goes through the per-fix path, the rest through the kernel: both
    in one batch, several vehicles interleaved, equal to the reference."""
    n_v, steps = 5, 40
    vehicles = [f"v{k}" for k in range(n_v)] * steps
    t = np.repeat(np.arange(steps, dtype=float), n_v)
    lat = 45.0 + np.arange(n_v * steps) * 1e-5
    lon = np.full(n_v * steps, 7.0)
    speed = np.full(n_v * steps, 10.0)
    fast, ref = FleetDetector(), ReferenceFleet()
    assert_same(
        fast.update_many(vehicles, t, lat, lon, speed),
        ref.update_many(vehicles, t, lat, lon, speed),
    )
    assert fast.update_many(vehicles[:n_v], t[:n_v], lat[:n_v], lon[:n_v]).anomaly.tolist()
    # times not after the previous fix: invalid, from the kernel, with the Detector's reason
    res = fast.update_many(vehicles[:n_v], t[:n_v], lat[:n_v], lon[:n_v])
    assert set(res.invalid_reason.tolist()) == {"time not after the previous fix"}


def test_reason_codes_are_the_detectors_reasons() -> None:
    assert REASONS[0] == ""
    assert len(set(REASONS)) == len(REASONS)
    cases = [
        (NAN, 1.0, 1.0, None, 0),
        (1.0, 1.0, 1.0, None, 1),
        (1.0, 1.0, 1.0, None, 2),
        (1.0, NAN, 1.0, None, 0),
        (1.0, -90.5, 1.0, None, 0),
        (1.0, 1.0, INF, None, 0),
        (1.0, 1.0, -181.0, None, 0),
        (1.0, 0.0, 0.0, None, 0),
        (1.0, 1.0, 1.0, 1.0, 0),
        (1.0, 1.0, 1.0, 1.5, 0),
        (1.0005, 1.0, 1.0, 1.0, 0),
        (1.001, 1.0, 1.0, 1.0, 0),
        (2.0, 1.0, 1.0, 1.0, 0),
    ]
    for t, lat, lon, last, rx in cases:
        quality = 0 if rx == 1 else None
        sats = 0 if rx == 2 else None
        expected = fix_reason(t, lat, lon, last, 0.001, fix_quality=quality, satellites=sats)
        fresh = last is None
        code = detector._reason_code(t, lat, lon, fresh, NAN if fresh else last, rx)
        assert REASONS[code] == expected


def test_states_move_between_detector_and_fleet() -> None:
    det = Detector()
    fixes = [(float(i), 45.0 + i * 1e-4, 7.0, 8.0, 0.0) for i in range(12)]
    for f in fixes[:8]:
        det.update(*f)
    fleet = FleetDetector()
    fleet.set_state("a", json.loads(json.dumps(det.get_state())))
    assert fleet.get_state("a") == det.get_state()
    for f in fixes[8:]:
        expected = det.update(*f)
        got = fleet.update("a", *f)
        assert got == expected or (math.isnan(got.score) and math.isnan(expected.score))
    assert Detector().set_state(fleet.get_state("a")).get_state() == det.get_state()


def test_a_refused_state_leaves_the_vehicle_as_it_was() -> None:
    fleet = FleetDetector()
    fleet.update_many(["a"] * 8, np.arange(8.0), np.full(8, 45.0) + np.arange(8) * 1e-4, [7.0] * 8)
    before = fleet.get_state("a")
    bad = dict(before, S=before["S"][:-1])
    with pytest.raises(ConfigError):
        fleet.set_state("a", bad)
    with pytest.raises(ConfigError):
        fleet.set_state("b", {"format": 1})
    assert fleet.get_state("a") == before
    assert "b" not in fleet
    assert fleet.get_state("b") == Detector().get_state()


def test_drop_and_many_vehicles_reuse_and_compact_the_state_buffer() -> None:
    """Slots freed by drop are reused, and the S buffer is compacted as periods change."""
    fast, ref = FleetDetector(capacity=2), ReferenceFleet()
    rng = np.random.default_rng(5)
    for round_ in range(6):
        n = 300
        vehicles = [f"v{k}" for k in rng.integers(0, 40, n)]
        clock = {v: 0.0 for v in vehicles}
        t = []
        for v in vehicles:
            clock[v] += [1.0, 0.1, 0.5][round_ % 3] * (1 + rng.integers(0, 2))
            t.append(clock[v] + 10_000.0 * round_)
        lat = 45.0 + rng.normal(0, 1e-4, n)
        lon = 7.0 + rng.normal(0, 1e-4, n)
        assert_same(fast.update_many(vehicles, t, lat, lon), ref.update_many(vehicles, t, lat, lon))
        for v in sorted(set(vehicles))[::3]:
            fast.drop(v)
            ref.drop(v)
        assert sorted(map(str, fast.vehicles)) == sorted(map(str, ref.detectors))
        for v in ref.detectors:
            assert fast.get_state(v) == ref.get_state(v)


def test_times_as_datetimes_and_text_are_read_as_the_detector_reads_them() -> None:
    import pandas as pd

    times = pd.date_range("2024-05-01", periods=10, freq="1s").to_numpy()
    lat = [45.0 + i * 1e-4 for i in range(10)]
    lon = ["7.0"] * 9 + ["east"]
    fast, ref = FleetDetector(), ReferenceFleet()
    assert_same(
        fast.update_many(["x"] * 10, times, lat, lon), ref.update_many(["x"] * 10, times, lat, lon)
    )
    frame = fast.update_many(["x"], [times[-1] + np.timedelta64(1, "s")], [45.0], [7.0]).to_frame()
    assert list(frame.columns)[:2] == ["anomaly", "score"]


def test_times_nanoseconds_cannot_hold_are_still_times() -> None:
    """Datetimes before 1677 or after 2262 (a logger's placeholder year, a corrupt field) fit no
    nanosecond count: the fleet wrapped them around into other years (3000 read as 1831,
    1500 as 2084) and ``Detector.update`` raised OverflowError. Both now read each in its own
    unit, as batch detection reads a column of them."""
    from gradgps._tracks.track import datetime_seconds

    times = np.array(["1500-01-01T00:00:00", "3000-01-01T00:00:00"], "datetime64[s]")
    for base in times:
        t = base + np.arange(8).astype("timedelta64[s]")
        lat = [45.0 + i * 1e-4 for i in range(8)]
        fast, ref = FleetDetector(), ReferenceFleet()
        got = fast.update_many(["x"] * 8, t, lat, [7.0] * 8)
        assert_same(got, ref.update_many(["x"] * 8, t, lat, [7.0] * 8))
        assert (got.invalid_reason == "").all()
        seconds = datetime_seconds(pd.Series(t).dt.tz_localize("UTC"))
        assert fast.get_state("x")["last_t"] == seconds[-1]
    for text in ("3000-01-01T00:00:00", "1500-01-01T00:00:00+01:00"):
        assert Detector().update(text, 45.0, 7.0).invalid_reason == ""


def test_receiver_fields_are_read_by_position_whatever_the_index() -> None:
    """A pandas Series with its own index is one value per fix in order, as every other
    argument: the per-fix path once looked values up by label (KeyError on index 10-12)."""
    fleet, reference = FleetDetector(), Detector()
    quality = pd.Series(["V", "A", "V", "A"], index=[10, 11, 12, 13])
    t = [1.7e9, 1.7e9 + 1, 1.7e9 + 2, 1.7e9 + 3]
    got = fleet.update_many(
        ["a"] * 4, t, [48.1] * 4, [11.5, 11.5001, 11.5002, 11.5003], fix_quality=quality
    ).to_frame()
    want = [
        reference.update(t[i], 48.1, 11.5 + 1e-4 * i, fix_quality=quality.iloc[i]) for i in range(4)
    ]
    assert list(got["invalid_reason"]) == [w.invalid_reason for w in want]
    assert list(got["anomaly"]) == [w.anomaly for w in want]
