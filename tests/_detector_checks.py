"""The detector contract, after river's ``river/checks``: one ``check_detector`` for every detector.

``check_detector(make, fixes)`` runs every check on detectors made by
``make`` (a fresh one per check, so no check sees another's state) over
``fixes``, canonical fixes of one time-ordered track (with the sensor
channels ``speed``, ``accel_x_mps2``, ``gyro_z_dps`` for sensor detectors).
Batch checks run for every detector; streaming checks for those with
``update``. Each check is also a plain function, so a test can run one alone.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import pytest

from gradgps import ConfigError, PointResult
from gradgps._result import RESULT_COLUMNS, RESULT_DTYPES

Make = Callable[[], Any]
_CHANNELS = ("accel_x_mps2", "gyro_z_dps")


def _with_invalid_rows(fixes: pd.DataFrame) -> pd.DataFrame:
    """``fixes`` with unusable rows between them, under an index that is not 0..n-1."""
    bad = fixes.iloc[:4].copy()
    bad["t"] = [np.nan, fixes["t"].iloc[3] + 0.5, fixes["t"].iloc[5] + 0.5, np.inf]
    bad["lat"] = [fixes["lat"].iloc[0], np.nan, 91.0, fixes["lat"].iloc[3]]
    bad["lon"] = [fixes["lon"].iloc[0], fixes["lon"].iloc[1], fixes["lon"].iloc[2], 200.0]
    # The usable fixes stay in time order (every mode reads a track in row order,
    # so a shuffled track would be flagged out of order); the bad rows go between.
    out = fixes.copy()
    for k, at in enumerate((2, 7, 12, 20)):
        out = pd.concat([out.iloc[:at], bad.iloc[[k]], out.iloc[at:]], ignore_index=True)
    out.index = pd.Index(np.arange(len(out)) * 2 + 10)
    return out


def check_batch_schema_index_and_invalid_rows(make: Make, fixes: pd.DataFrame) -> None:
    """The caller's index and row order kept; the result schema; the invalid-row policy."""
    data = _with_invalid_rows(fixes)
    result = make().detect(data)
    assert list(result.columns) == list(RESULT_COLUMNS)
    assert {c: str(result[c].dtype) for c in result.columns} == RESULT_DTYPES
    assert result.index.equals(data.index)
    reason = result["invalid_reason"].to_numpy(dtype=object)
    invalid = reason != ""
    assert invalid.sum() == 4
    t, lat, lon = (data[c].to_numpy(np.float64) for c in ("t", "lat", "lon"))
    usable = np.isfinite(t) & np.isfinite(lat) & np.isfinite(lon)
    usable &= (np.abs(lat) <= 90) & (np.abs(lon) <= 180)
    np.testing.assert_array_equal(invalid, ~usable)
    bad = result[invalid]
    assert (bad["anomaly"] == 1).all()
    assert (bad["alert"] == 0).all()
    assert bad["score"].isna().all()
    assert bad["lat_clean"].isna().all()
    assert bad["lon_clean"].isna().all()
    good = result[~invalid]
    assert good["anomaly"].isin([0, 1]).all()
    assert good["alert"].isin([0, 1]).all()
    scores = good["score"].to_numpy(np.float64)
    assert np.all((scores >= 0.0) & (scores <= 1.0)), scores[~((scores >= 0) & (scores <= 1))]


def check_batch_empty(make: Make, fixes: pd.DataFrame) -> None:
    result = make().detect(fixes.iloc[:0])
    assert len(result) == 0
    assert list(result.columns) == list(RESULT_COLUMNS)


def _feed(det: Any, row: Any) -> PointResult:
    channels = {c: getattr(row, c) for c in _CHANNELS if hasattr(row, c)}
    speed = getattr(row, "speed", None)
    return det.update(row.t, row.lat, row.lon, speed, None, **channels)  # type: ignore[no-any-return]


def _assert_point(r: PointResult) -> None:
    assert isinstance(r, PointResult)
    assert r.anomaly in (0, 1)
    assert r.alert in (0, 1)
    if r.invalid_reason:
        assert r.anomaly == 1
        assert r.alert == 0
        assert math.isnan(r.score)
        assert math.isnan(r.lat_clean)
        assert math.isnan(r.lon_clean)
    else:
        assert 0.0 <= r.score <= 1.0, r


def check_stream_bad_values(make: Make, fixes: pd.DataFrame) -> None:
    """None, NaN, out-of-order and duplicate times in ``update``: verdicts, never exceptions."""
    det = make()
    rows = list(fixes.itertuples(index=False))
    for row in rows[:5]:
        _assert_point(_feed(det, row))
    last = rows[4]
    before = json.dumps(det.get_state(), allow_nan=False)
    for args in (
        (None, last.lat, last.lon),
        (last.t + 1, None, last.lon),
        (math.nan, last.lat, last.lon),
        (last.t + 1, math.nan, last.lon),
        ("not a time", last.lat, last.lon),
        (last.t + 1, 95.0, last.lon),
        (last.t - 3.0, last.lat, last.lon),  # out of order: before the previous fix
    ):
        r = det.update(*args)
        _assert_point(r)
        assert r.anomaly == 1, (args, r)
        assert r.invalid_reason, (args, r)
    # Unusable fixes never touch the state.
    assert json.dumps(det.get_state(), allow_nan=False) == before
    # A bad optional reading is absent, not an error.
    _assert_point(det.update(last.t + 1.0, last.lat, last.lon, speed=None, heading="north"))
    # A repeated time: a verdict (invalid for GRAD, a dt = 0 reading for baselines).
    _assert_point(det.update(last.t + 1.0, last.lat, last.lon))
    for row in rows[6:10]:
        _assert_point(_feed(det, row))


def check_state_json_round_trip(make: Make, fixes: pd.DataFrame) -> None:
    """Strict JSON state; restored elsewhere, the stream goes on with the same verdicts."""
    rows = list(fixes.itertuples(index=False))
    cut = len(rows) // 2
    a = make()
    for row in rows[:cut]:
        _feed(a, row)
    text = json.dumps(a.get_state(), allow_nan=False)
    b = make()
    assert b.set_state(json.loads(text)) is b
    for row in rows[cut:]:
        ra, rb = _feed(a, row), _feed(b, row)
        assert ra.anomaly == rb.anomaly
        assert ra.score == pytest.approx(rb.score, abs=1e-12, nan_ok=True)
        assert ra.lat_clean == pytest.approx(rb.lat_clean, abs=1e-12, nan_ok=True)


def _truncated(value: Any) -> Any | None:
    """``value`` with its first innermost list of numbers one element short (None if there is none)."""
    if isinstance(value, dict):
        for k, v in value.items():
            t = _truncated(v)
            if t is not None:
                return {**value, k: t}
        return None
    if isinstance(value, list) and value:
        if all(isinstance(v, int | float | str) and not isinstance(v, bool) for v in value):
            return value[:-1]
        for i, v in enumerate(value):
            t = _truncated(v)
            if t is not None:
                return [*value[:i], t, *value[i + 1 :]]
    return None


def check_state_rejected(make: Make, fixes: pd.DataFrame) -> None:
    """A state with a key missing, or with an array cut short, is refused with ConfigError."""
    det = make()
    for row in fixes.iloc[:6].itertuples(index=False):
        _feed(det, row)
    state = json.loads(json.dumps(det.get_state(), allow_nan=False))
    for key in state:
        with pytest.raises(ConfigError):
            make().set_state({k: v for k, v in state.items() if k != key})
        cut = _truncated(state[key])
        if cut is not None:
            with pytest.raises(ConfigError):
                make().set_state({**state, key: cut})
    with pytest.raises(ConfigError):
        make().set_state("not a state")


def check_stream_equals_batch(make: Make, fixes: pd.DataFrame) -> None:
    """Time-ordered fixes of one track: streaming gives the batch's verdicts."""
    batch = make().detect(fixes)
    det = make()
    stream = [_feed(det, row) for row in fixes.itertuples(index=False)]
    np.testing.assert_array_equal([r.anomaly for r in stream], batch["anomaly"].to_numpy())
    np.testing.assert_allclose([r.score for r in stream], batch["score"].to_numpy(), atol=1e-5)
    np.testing.assert_allclose(
        [r.lat_clean for r in stream], batch["lat_clean"].to_numpy(), atol=1e-9
    )
    assert [r.invalid_reason for r in stream] == batch["invalid_reason"].tolist()


BATCH_CHECKS = (check_batch_schema_index_and_invalid_rows, check_batch_empty)
STREAM_CHECKS = (
    check_stream_bad_values,
    check_state_json_round_trip,
    check_state_rejected,
    check_stream_equals_batch,
)


def detector_checks(det: Any) -> tuple[Callable[[Make, pd.DataFrame], None], ...]:
    """The checks that apply to ``det``: batch ones always, streaming ones if it streams."""
    return BATCH_CHECKS + (STREAM_CHECKS if hasattr(det, "update") else ())


def check_detector(make: Make, fixes: pd.DataFrame) -> None:
    """Every check of the contract that applies to the detectors ``make`` builds."""
    for check in detector_checks(make()):
        check(make, fixes)


def final_verdicts(
    det: Any, fixes: Any, finals: list[PointResult] | None = None
) -> list[PointResult]:
    """A stream's final verdicts: each fix's verdict at once (``det.update(*fix)`` for
    each tuple of ``fixes``), replaced by ``det.settled`` when a later fix settles it
    (a model whose verdicts settle one fix late). ``finals``: those of the fixes before,
    read by a stream ``det`` continues (a restored state); extended in place."""
    finals = [] if finals is None else finals
    usable = [k for k, r in enumerate(finals) if r.invalid_reason == ""]
    last = usable[-1] if usable else None  # the fix a settled verdict belongs to
    for fix in fixes:
        result = det.update(*fix)
        settled = det.settled
        if settled is not None:
            assert last is not None
            finals[last] = settled
        finals.append(result)
        if result.invalid_reason == "":
            last = len(finals) - 1
    return finals
