"""benchmarks/tried/drift_mode_reference.py: without its drift mode it is the shipped
tracker's readable reference, offset for offset."""

from __future__ import annotations

import numpy as np

from _script_support import load_script
from gradgps._grad.offset import OFFSET_FEATURES, offset_features_reference

dm = load_script("benchmarks/tried/drift_mode_reference.py")


def test_no_drift_mode_is_the_shipped_reference() -> None:
    t, east, north = dm.synthetic_pull_off()
    east[20:23] += 60.0  # an outlier run and a jump besides the pull-off
    north[90:100] += 40.0
    ours = dm.tracker_offsets(east, north, t, dm.DriftSettings(drift_per_s=0.0))
    nan = np.full(t.size, np.nan)
    ref = offset_features_reference(np.r_[0.0, np.diff(t)], east, north, nan, nan)
    norm = OFFSET_FEATURES.index("offset_norm")
    previous = OFFSET_FEATURES.index("previous_offset_revised")
    np.testing.assert_allclose(ours[:, 0], ref[:, norm], atol=1e-9)
    np.testing.assert_allclose(ours[:, 3], ref[:, previous], atol=1e-9)
    assert ours[66:80, 0].max() > 8.0  # the snap-back read as a fault: what the mode is for


def test_the_drift_mode_changes_the_reading_of_a_pull_off() -> None:
    t, east, north = dm.synthetic_pull_off()
    stiff = dm.tracker_offsets(east, north, t, dm.DriftSettings(drift_track_q=0.05))
    assert (stiff[:, 2] == dm.DRIFT).any()
