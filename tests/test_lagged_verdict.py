"""benchmarks/tried/lagged_verdict_train.py and lagged_verdict_check.py: labels moved
``k`` points later, and verdicts read ``k`` fixes later, never across a track's end."""

from __future__ import annotations

import numpy as np
import pytest

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


def test_flagged_runs_end_at_a_gap_and_at_a_new_track() -> None:
    flag = np.array([1, 1, 0, 1, 1, 1, 0], bool)
    track = np.array(["a", "a", "a", "a", "b", "b", "b"])
    assert check.flagged_runs(flag, track) == [("a", 0, 2), ("a", 3, 1), ("b", 4, 2)]


summary = load_script("benchmarks/tried/lagged_verdict_summary.py")


def test_the_summary_reads_five_draws_and_differences_their_means(tmp_path) -> None:
    def table(f1_native: float, f1_slow: float) -> str:
        return (
            "| data set | rate | clean false alarms | anomaly F1 | normal recall |\n"
            f"| d | native | 0.10 % | {f1_native:.3f} | 0.990 |\n"
            f"| d | 0.5 Hz | 0.20 % | {f1_slow:.3f} | 0.980 |\n"
            "| simulated | 10 Hz | 0.01 % | 0.999 | 1.000 |\n"
        )

    for seed in range(5):
        (tmp_path / f"base_seed{seed}.txt").write_text(table(0.9, 0.8 + 0.01 * seed))
        (tmp_path / f"cand_seed{seed}.txt").write_text(table(0.92, 0.85))
    base, cand = summary.read_draws(tmp_path, "base"), summary.read_draws(tmp_path, "cand")
    assert base[("d", "0.5 Hz")].shape == (5, 3)
    assert base[("simulated", "10 Hz")].shape == (5, 3)  # any rate, as --simulated writes
    assert summary.mean_difference(base, cand, "native") == pytest.approx(0.02)
    assert summary.mean_difference(base, cand, "0.5 Hz") == pytest.approx(0.85 - 0.82)
    assert summary.mean_difference(base, cand) == pytest.approx((0.02 + 0.03 + 0.0) / 3)
