"""benchmarks/tried/hangover_check.py: a normal fix counts the fixes since the last faulty
fix of its own track, and carries that fix's bias and time type; a new track starts
afresh."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

hc = load_script("benchmarks/tried/hangover_check.py")


def test_fixes_since_the_last_fault_of_the_same_track() -> None:
    truth = np.array([0, 1, 1, 0, 0, 1, 0, 0, 0, 1], dtype=bool)
    track = np.array(["a"] * 7 + ["b"] * 3)
    bias = np.array(["", "noise", "noise", "", "", "jump", "", "", "", "jump"], dtype=object)
    kind = np.array(
        ["", "permanent", "permanent", "", "", "transient", "", "", "", "transient"],
        dtype=object,
    )
    since, ended = hc.fixes_since_fault(truth, track, bias, kind)
    np.testing.assert_array_equal(since, [-1, 0, 0, 1, 2, 0, 1, -1, -1, 0])
    assert list(ended[:7]) == [
        "",
        "noise permanent",
        "noise permanent",
        "noise permanent",
        "noise permanent",
        "jump transient",
        "jump transient",
    ]
    assert list(ended[7:9]) == ["", ""]  # track b: no fault before
