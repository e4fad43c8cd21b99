"""benchmarks/receiver_consensus.py: another receiver's position at a fix's time, the
consensus of the others, and runs of far fixes."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

rc = load_script("benchmarks/receiver_consensus.py")


def _receiver(t: list[float], east: list[float], segment: list[str] | None = None) -> object:
    seg = np.array(segment or ["a"] * len(t))
    z = np.asarray(east, float)
    return rc.Receiver("r", seg, np.asarray(t, float), z, -z)


def test_interpolation_between_two_fixes_of_one_segment_only() -> None:
    rx = _receiver([0, 1, 2, 6, 7], [0, 10, 20, 60, 70], ["a", "a", "a", "a", "b"])
    at = rc.interpolate_at(rx, np.array([0.5, 1.0, 4.0, 6.5, -1.0, 9.0]))
    np.testing.assert_allclose(at[:2, 0], [5.0, 10.0])
    np.testing.assert_allclose(at[:2, 1], [-5.0, -10.0])
    # 2 -> 6 is longer than MAX_BRACKET_S; 6 -> 7 crosses segments; outside the fixes
    assert np.isnan(at[2:]).all()


def test_the_consensus_needs_two_others_that_agree() -> None:
    a = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    b = np.array([[2.0, 0.0], [50.0, 0.0], [np.nan, np.nan]])
    c = np.array([[1.0, 0.0], [100.0, 0.0], [1.0, 0.0]])
    ref = rc.consensus([a, b, c])
    np.testing.assert_allclose(ref[0], [1.0, 0.0])
    assert np.isnan(ref[1]).all()  # the median 50 m: nobody else within AGREE_M of it
    np.testing.assert_allclose(ref[2], [0.5, 0.0])  # two left, 1 m apart


def test_far_runs_stop_at_a_gap_and_at_a_new_segment() -> None:
    far = np.array([1, 1, 0, 1, 1, 1], bool)
    segment = np.array(["a", "a", "a", "a", "b", "b"])
    assert rc.runs_of(far, segment) == [(0, 2), (3, 1), (4, 2)]
