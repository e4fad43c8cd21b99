"""Time classifier on the benchmark protocol's episode shapes; kernel == reference; streaming."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps._exceptions import ConfigError
from gradgps._grad.time_classifier import (
    INTERMITTENT,
    NONE,
    PERMANENT,
    TRANSIENT,
    TimeClassifier,
    TimeParams,
    classify_time,
    classify_time_reference,
)


def _flags(n: int, *runs: tuple[int, int]) -> np.ndarray:
    f = np.zeros(n, dtype=np.int8)
    for start, length in runs:
        f[start : start + length] = 1
    return f


def test_transient_fault_of_one_to_five_points() -> None:
    for length in range(1, 6):
        codes = classify_time(_flags(50, (20, length)))
        assert set(codes[20 : 20 + length]) == {TRANSIENT}
        assert codes[:20].max() == NONE
        assert codes[20 + length :].max() == NONE


def test_intermittent_episode_first_burst_transient_then_intermittent() -> None:
    # 4 bursts of 1-3 points separated by 3-15 normal points.
    f = _flags(120, (40, 2), (47, 1), (60, 3), (70, 2))
    codes = classify_time(f)
    assert codes[40:42].tolist() == [TRANSIENT, TRANSIENT]  # causal: not known to recur yet
    assert codes[47] == INTERMITTENT
    assert set(codes[60:63]) == {INTERMITTENT}
    assert set(codes[70:72]) == {INTERMITTENT}
    # A burst more than episode_gap after the last one starts a new episode.
    assert classify_time(_flags(120, (40, 2), (58, 1)))[58] == TRANSIENT


def test_permanent_fault_at_segment_end() -> None:
    codes = classify_time(_flags(400, (340, 60)))
    prm = TimeParams()
    assert set(codes[340 : 340 + prm.permanent_run - 1]) == {TRANSIENT}
    assert set(codes[340 + prm.permanent_run - 1 :]) == {PERMANENT}


@settings(max_examples=60, deadline=None)
@given(
    flags=st.lists(st.booleans(), max_size=200),
    perm=st.integers(1, 12),
    gap=st.integers(1, 20),
    bursts=st.integers(1, 4),
)
def test_kernel_matches_reference(flags: list[bool], perm: int, gap: int, bursts: int) -> None:
    prm = TimeParams(permanent_run=perm, episode_gap=gap, intermittent_bursts=bursts)
    np.testing.assert_array_equal(classify_time(flags, prm), classify_time_reference(flags, prm))


def test_streaming_equals_batch_with_json_state() -> None:
    f = _flags(200, (10, 2), (20, 1), (100, 30), (150, 1))
    clf = TimeClassifier()
    names = []
    for i, v in enumerate(f):
        if i in (0, 15, 120):
            clf = TimeClassifier().set_state(json.loads(json.dumps(clf.get_state())))
        names.append(clf.update(int(v)))
    expected = ["none", "transient", "intermittent", "permanent"]
    assert names == [expected[c] for c in classify_time(f)]


def test_time_spans_count_fixes_up_to_1_hz_and_seconds_above() -> None:
    from gradgps._grad.time_classifier import TimeSpans

    prm = TimeParams(permanent_run=6, episode_gap=15, intermittent_bursts=2)
    spans = TimeSpans()
    for period in (1.0, 2.0, 5.0):
        assert spans.at_period(prm, period) == prm
    assert spans.at_period(prm, 0.1) == TimeParams(
        permanent_run=60, episode_gap=150, intermittent_bursts=2
    )
    assert spans.at_period(prm, 0.25).permanent_run == 24
    with pytest.raises(ConfigError, match="fixes_per_second"):
        TimeSpans(fixes_per_second=0.0).at_period(prm, 1.0)
    with pytest.raises(ConfigError, match="period"):
        spans.at_period(prm, math.nan)


def test_the_pipeline_types_a_10_hz_fault_by_its_duration() -> None:
    """Every fix of a 10 Hz drive flagged: permanent after 6 s (60 fixes), as 6 fixes at
    1 Hz; a model whose settings say ``"verdict_time": null`` counts fixes."""
    import dataclasses

    import pandas as pd

    from gradgps import Detector
    from gradgps._grad.pipeline import PipelineParams

    t = np.arange(100) * 0.1
    lat = 48.1 + 4.0 * t / 111_320.0
    fixes = pd.DataFrame({"t": t, "lat": lat, "lon": np.full(t.size, 11.5)})
    det = Detector(threshold=1e-9)
    run = det.model_.params.time.permanent_run
    kinds = det.detect(fixes)["time_type"].to_numpy()
    assert (kinds[: 10 * run - 1] != "permanent").all()
    assert (kinds[10 * run - 1 :] == "permanent").all()
    saved = det.model_.params.to_dict()
    assert saved["verdict_time"] == {"fixes_per_second": 1.0}
    in_fixes = PipelineParams.from_dict({**saved, "verdict_time": None})
    assert in_fixes.verdict_time is None
    legacy = {k: v for k, v in saved.items() if k != "verdict_time"}
    assert PipelineParams.from_dict(legacy).verdict_time is not None
    det.model_ = dataclasses.replace(det.model_, params=in_fixes)
    kinds = det.detect(fixes)["time_type"].to_numpy()
    assert (kinds[run - 1 :] == "permanent").all()
