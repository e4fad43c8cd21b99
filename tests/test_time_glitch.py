"""A time column coarser than the fixes: a fix set aside for its time at a new position
begins a new segment at the next usable fix, in every mode (time_glitch_breaks)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from gradgps._data.simulator import simulate_fleet
from gradgps._grad.detector import Detector, FleetDetector, MultiTrackDetector
from gradgps._tracks.preprocess import NOT_AFTER, stream_reasons, time_glitch_breaks
from gradgps._tracks.track import to_fixes

pytestmark = pytest.mark.filterwarnings("ignore::gradgps.InputWarning")


def test_a_repeat_at_a_new_position_breaks_the_next_usable_fix_only() -> None:
    """Per track in row order: a moved repeat breaks the next usable fix of its own track;
    an exact repeat breaks nothing; a track's first fixes have nothing to repeat."""
    fixes = pd.DataFrame(
        {
            "track": ["a", "a", "b", "a", "b", "b", "a", "b"],
            "t": [0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 2.0, 2.0],
            "lat": [1.0, 1.1, 5.0, 1.2, 5.0, 5.1, 1.3, 5.2],
            "lon": [1.0, 1.0, 5.0, 1.0, 5.0, 5.0, 1.0, 5.0],
        }
    )
    reason = stream_reasons(fixes)
    assert reason.tolist() == ["", NOT_AFTER, "", "", NOT_AFTER, "", "", ""]
    # a's repeat moved (row 1): its next usable fix (row 3) breaks; b's is exact (row 4).
    assert time_glitch_breaks(fixes, reason).tolist() == [0, 0, 0, 1, 0, 0, 0, 0]


def _coarse_clock_drive(minutes: float = 20.0, seed: int = 31) -> pd.DataFrame:
    """A clean simulated 1 Hz drive whose fixes come 0.995 s apart on a clock written as
    whole seconds: one second repeated every 200 s, at the next fix's position."""
    drive = simulate_fleet(1, minutes, 1.0, seed=seed, imu=False)
    t = drive["t"].to_numpy()
    coarse = np.floor(t[0] + 0.995 * (t - t[0]))
    return drive[["lat", "lon"]].assign(t=coarse, track="a")[["track", "t", "lat", "lon"]]


def test_a_coarse_clock_leaves_the_clean_fixes_unflagged_in_every_mode() -> None:
    """Before the rule, the fix after each repeated second was read as a jump and held
    (the NL motorway drives so written: 47 % flagged); now no clean usable fix is
    flagged, and batch, the stream and the fleet agree."""
    fixes = to_fixes(_coarse_clock_drive())
    batch = Detector().detect(fixes)
    repeats = batch["invalid_reason"] != ""
    assert 4 <= int(repeats.sum()) <= 8
    # (the sources before the rule flagged 7 of this drive's 1,194 usable fixes)
    assert int(batch.loc[~repeats, "anomaly"].sum()) == 0
    streamed = MultiTrackDetector().update_fixes(fixes)
    for col in ("anomaly", "invalid_reason", "bias_type"):
        assert streamed[col].tolist() == batch[col].tolist(), col
    np.testing.assert_array_equal(streamed["score"].to_numpy(), batch["score"].to_numpy())
    fleet = FleetDetector()
    got = fleet.update_many(
        fixes["track"].to_numpy(), fixes["t"].to_numpy(), fixes["lat"], fixes["lon"]
    )
    assert got.invalid_reason.tolist() == batch["invalid_reason"].tolist()


def test_a_state_saved_after_a_moved_repeat_begins_the_segment_when_restored() -> None:
    """The pending break travels in the state (format 4): a Detector and a FleetDetector
    restored right after the repeat give the uninterrupted stream's verdicts and states."""
    fixes = to_fixes(_coarse_clock_drive(minutes=6.0))
    rows = list(fixes[["t", "lat", "lon"]].itertuples(index=False, name=None))
    times, lat = fixes["t"].to_numpy(), fixes["lat"].to_numpy()
    moved = (np.diff(times) == 0) & (np.diff(lat) != 0)
    k = int(np.flatnonzero(moved)[0]) + 1  # the first second repeated at a new position
    whole = Detector()
    want = [whole.update(*r) for r in rows]
    first = Detector()
    for r in rows[: k + 1]:
        first.update(*r)
    state = json.loads(json.dumps(first.get_state(), allow_nan=False))
    assert state["glitch"] is True
    again = Detector().set_state(state)
    assert [again.update(*r) for r in rows[k + 1 :]] == want[k + 1 :]
    fleet = FleetDetector()
    fleet.set_state("a", state)
    assert fleet.get_state("a") == state
    got = fleet.update_many(["a"] * (len(rows) - k - 1), *np.array(rows[k + 1 :]).T)
    assert got.anomaly.tolist() == [w.anomaly for w in want[k + 1 :]]
    assert fleet.get_state("a") == whole.get_state()
