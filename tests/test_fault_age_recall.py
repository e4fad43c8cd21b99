"""benchmarks/fault_age_recall.py: a faulty fix's age is the time since its own
episode's first fix (the older channel where both channels are faulty), and ages fall
into the bins the table prints."""

from __future__ import annotations

import numpy as np

from _script_support import load_script

far = load_script("benchmarks/fault_age_recall.py")


def test_age_is_time_since_the_episode_started_the_older_channel_first() -> None:
    t = np.arange(10) * 2.0
    lat = np.array([-1, 3, 3, 3, -1, -1, 8, 8, 8, -1])
    lon = np.array([-1, -1, 5, 5, 5, -1, -1, -1, 9, 9])
    age = far.episode_age_s(t, lat, lon)
    assert np.isnan(age[[0, 5]]).all()
    np.testing.assert_allclose(age[[1, 2, 3, 4]], [0.0, 2.0, 4.0, 4.0])  # 4: lon's own age
    np.testing.assert_allclose(age[[6, 7, 8, 9]], [0.0, 2.0, 4.0, 2.0])


def test_ages_fall_into_the_printed_bins() -> None:
    age = np.array([np.nan, 0.0, 29.9, 30.0, 59.0, 60.0, 119.0, 120.0, 500.0])
    np.testing.assert_array_equal(far.age_bins(age), [-1, 0, 0, 1, 1, 2, 2, 3, 3])
