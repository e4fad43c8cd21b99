"""benchmarks/tried/calibration_groups_at.py: each group's normal recall counts only its
normal points, below the threshold, a group without normal points and points
without a score are left out."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

cg = load_script("benchmarks/tried/calibration_groups_at.py")


def test_normal_recall_per_group() -> None:
    truth = np.array([0, 0, 1, 0, 0, 1, 1])
    score = np.array([0.1, 0.9, 0.99, 0.5, 0.95, 0.2, 0.3])
    group = np.array(["a", "a", "a", "b", "b", "b", "c"], dtype=object)
    out = cg.group_normal_recall(truth, score, group, 0.9)
    assert list(out) == ["a", "b"]  # "c" has no normal point
    assert out["a"] == 0.5  # 0.9 is not below 0.9
    assert out["b"] == 0.5
    assert cg.group_normal_recall(truth, score, group, 0.96)["b"] == 1.0


def test_points_without_a_score_are_left_out() -> None:
    truth = np.array([0, 0, 0])
    score = np.array([0.1, np.nan, 0.95])
    group = np.array(["a", "a", "a"], dtype=object)
    assert cg.group_normal_recall(truth, score, group, 0.9)["a"] == 0.5
