"""Time classifier on the benchmark protocol's episode shapes; kernel == reference; streaming."""

from __future__ import annotations

import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

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
