"""benchmarks/tried/calibration_normals_where.py: a normal row's distance after its
track's last faulty row, and that fault's bias, restart with every track and give up
after the look-back."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

cw = load_script("benchmarks/tried/calibration_normals_where.py")


def test_rows_after_a_fault_count_from_its_last_row() -> None:
    truth = np.array([0, 1, 1, 0, 0, 1, 0])
    bias = np.array(["none", "noise", "noise", "none", "none", "jump", "none"], dtype=object)
    track = np.array(["a"] * 7, dtype=object)
    since, last = cw.after_fault(truth, bias, track)
    none = cw._LOOK_BACK + 1
    np.testing.assert_array_equal(since, [none, 0, 0, 1, 2, 0, 1])
    assert list(last) == ["-", "noise", "noise", "noise", "noise", "jump", "jump"]


def test_a_new_track_starts_without_a_fault_and_the_look_back_ends() -> None:
    n = cw._LOOK_BACK + 3
    truth = np.r_[1, np.zeros(n - 1, int), 0, 0]
    bias = np.array(["noise"] + ["none"] * (n + 1), dtype=object)
    track = np.array(["a"] * n + ["b", "b"], dtype=object)
    since, last = cw.after_fault(truth, bias, track)
    assert since[cw._LOOK_BACK] == cw._LOOK_BACK
    assert last[cw._LOOK_BACK] == "noise"
    assert since[cw._LOOK_BACK + 1] == cw._LOOK_BACK + 1
    assert last[cw._LOOK_BACK + 1] == "-"
    assert since[n] == cw._LOOK_BACK + 1
    assert last[n] == "-"
