"""benchmarks/tried/simulated_misses.py: recall per bias and time type counts faulty rows
only, and a run's first row restarts with every track."""

from __future__ import annotations

import numpy as np
import pandas as pd

from _script_support import load_script

sm = load_script("benchmarks/tried/simulated_misses.py")


def test_recall_by_kind_counts_faulty_rows_and_first_rows_per_track() -> None:
    labelled = pd.DataFrame(
        {
            "track": ["a", "a", "a", "b", "b", "b"],
            "label_anomaly": [1, 1, 0, 1, 1, 0],
            "label_bias": ["jump", "jump", "none", "jump", "noise", "none"],
            "label_time": ["permanent"] * 2 + ["none"] + ["permanent", "transient", "none"],
        }
    )
    flagged = np.array([False, True, True, True, True, True])
    out = sm.recall_by_kind(labelled, flagged)
    jump = out.loc[("jump", "permanent")]
    assert jump["faulty"] == 3
    assert jump["recall"] == 2 / 3
    assert jump["first_recall"] == 0.5  # rows 0 (missed) and 3 (a new track) start runs
    noise = out.loc[("noise", "transient")]
    assert noise["faulty"] == 1
    assert noise["recall"] == 1.0
    assert np.isnan(noise["first_recall"])  # row 4 continues row 3's run
    assert ("none", "none") not in out.index
