"""benchmarks/tried/lagged_verdict_train.py and lagged_verdict_check.py: labels moved
``k`` points later, and verdicts read ``k`` fixes later, never across a track's end."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

train = load_script("benchmarks/tried/lagged_verdict_train.py")
check = load_script("benchmarks/tried/lagged_verdict_check.py")


def test_labels_move_later_and_the_first_points_are_not_scored() -> None:
    labels = np.array([0, 1, 1, 0, 2])
    ignore = train.IGNORE_LABEL
    np.testing.assert_array_equal(train.moved_later(labels, 1), [ignore, 0, 1, 1, 0])
    np.testing.assert_array_equal(train.moved_later(labels, 2), [ignore, ignore, 0, 1, 1])


def test_a_verdict_read_later_stays_in_its_track() -> None:
    flag = np.array([0, 0, 1, 0, 1, 0, 0], bool)
    track = np.array(["a", "a", "a", "a", "b", "b", "b"])
    np.testing.assert_array_equal(check.flags_later(flag, track, 0), flag)
    np.testing.assert_array_equal(check.flags_later(flag, track, 1), [0, 1, 0, 0, 0, 0, 0])
    # two later: row 2 would read row 4, which is track "b": it takes row 3, "a"'s last
    np.testing.assert_array_equal(check.flags_later(flag, track, 2), [1, 0, 0, 0, 0, 0, 0])
