"""Offset tracker: kernel == reference, and it holds a jump's offset until the jump ends.

The scenarios below were found with the rule-based tracker this model replaced (each
says what went wrong then); they hold for the switching Kalman model as they did for it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps import ConfigError
from gradgps._grad.offset import (
    N_STEP,
    OFFSET_FEATURES,
    OffsetParams,
    offset_features,
    offset_features_reference,
    singer_step,
)


def _drive(n: int = 300, seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    dt = np.r_[0.0, np.full(n - 1, 1.0)]
    speed = 12.0 + 3.0 * np.sin(np.arange(n) / 30.0)
    heading = np.mod(40.0 + 0.3 * np.arange(n), 360.0)
    ve, vn = speed * np.sin(np.radians(heading)), speed * np.cos(np.radians(heading))
    east = np.cumsum(ve * dt) + rng.normal(0, 0.5, n)
    north = np.cumsum(vn * dt) + rng.normal(0, 0.5, n)
    return dt, east, north, speed, heading


@pytest.mark.parametrize("with_velocity", [True, False])
def test_jump_offset_is_held_for_its_whole_length_and_released(with_velocity: bool) -> None:
    dt, east, north, speed, heading = _drive()
    east = east.copy()
    east[100:130] += 40.0
    sp, hd = (speed, heading) if with_velocity else (None, None)
    out = offset_features(dt, east, north, sp, hd)
    norm = out[:, 2]
    assert (norm[:100] < 3.0).all()
    assert (norm[100:130] > 30.0).all()  # held through 30 points
    assert (norm[130:] < 6.0).all()  # and released when the jump ends


def test_random_sign_noise_run_leaves_no_residue() -> None:
    """A run of noise points can make one step look like the fault's end; the
    distance to the dead-reckoned clean track must still end it where it ends."""
    dt, east, north, speed, heading = _drive(seed=1)
    east = east.copy()
    east[100:106] += [29.0, 34.0, -22.0, 43.0, -32.0, 18.0]
    out = offset_features(dt, east, north, speed, heading)
    assert (out[100:106, 2] > 6.0).all()
    assert (out[106:, 2] < 6.0).all()
    assert (out[106:, 7] == 0.0).all()  # no fault age left either


def test_steady_velocity_disagreement_is_learnt_not_accumulated() -> None:
    """Reported speed 30 % low (a scale error): the bias estimate absorbs it."""
    dt, east, north, speed, heading = _drive(seed=2)
    out = offset_features(dt, east, north, 0.7 * speed, heading)
    assert out[30:, 2].max() < 6.0


def test_fault_held_too_long_is_released() -> None:
    """A shift that never ends is, in the end, the track (a re-anchored receiver): the
    jump's hazard (``fault_s``) makes holding it ever less likely than a restart."""
    dt, east, north, speed, heading = _drive(n=600)
    east = east.copy()
    east[50:] += 40.0  # never ends
    out = offset_features(dt, east, north, speed, heading, OffsetParams(fault_s=10.0))
    assert (out[50:70, 2] > 30.0).all()
    released = int(np.flatnonzero(out[50:, 2] < 6.0)[0]) + 50
    assert (out[released:, 2] < 6.0).all()
    assert released < 400


@pytest.mark.parametrize("with_velocity", [True, False])
def test_a_released_faults_end_leaves_the_other_channels_fault_held(with_velocity: bool) -> None:
    """A north fault outlives what the tracker holds and is released (a restart wins); an
    east jump starts; then the north fault ends with a step back. That step ends the
    released north fault only: the east offset is still held, and its own end (the step
    back to the track) leaves no offset behind. The rule-based tracker once zeroed both channels at
    the north return and re-anchored the clean track on the east-shifted fix, so
    the east jump's end read as a new 50 m jump, held on clean fixes."""
    dt, east, north, speed, heading = _drive()
    east, north = east.copy(), north.copy()
    north[50:100] += 100.0  # released before it returns at 100 (fault_s = 10 s below)
    east[90:115] -= 50.0
    sp, hd = (speed, heading) if with_velocity else (None, None)
    prm = OffsetParams(fault_s=10.0)
    for out in (
        offset_features(dt, east, north, sp, hd, prm),
        offset_features_reference(
            dt, east, north, *((sp, hd) if sp is not None else _nans(len(dt))), prm
        ),
    ):
        assert (out[90:100, 0] < -40.0).all()  # the east jump, held before the return
        assert (out[100:115, 0] < -40.0).all()  # ... and after it
        # the north fault has ended (its return may read as a fault for one fix:
        # the released fault's hypothesis takes one more fix to win back)
        assert (np.abs(out[101:, 1]) < 6.0).all()
        assert (out[115:, 2] < 6.0).all()  # nothing left once the east jump ends


@pytest.mark.parametrize("with_velocity", [True, False])
def test_a_noise_run_is_not_remembered_as_a_released_fault(with_velocity: bool) -> None:
    """Three noise fixes 48, 15 and 37 m north, then the track: the tracker's last
    offset (the third fix's step, 22 m) is ended by the clean-track gate, not by a
    step that undoes it. An offset the last step set is one noise fix's, not a held
    fault: remembered as released, a jump starting 30 s later with a step of -34 m
    (which "undoes" 22 m within its slack) read as that old fault's end, and the
    whole jump went unseen (its true end then read as a new jump)."""
    dt, east, north, speed, heading = _drive()
    north = north.copy()
    north[100:103] += [48.0, 15.0, 37.0]
    north[130:170] -= 34.0
    sp, hd = (speed, heading) if with_velocity else (None, None)
    for out in (
        offset_features(dt, east, north, sp, hd),
        offset_features_reference(
            dt, east, north, *((sp, hd) if sp is not None else _nans(len(dt)))
        ),
    ):
        assert (out[103:130, 2] < 6.0).all()  # the noise run has ended
        assert (out[130:170, 2] > 25.0).all()  # the jump is held
        assert (out[172:, 2] < 6.0).all()  # and ends where it ends


@pytest.mark.parametrize("with_velocity", [True, False])
def test_a_first_step_no_car_drives_starts_the_segment_afresh(with_velocity: bool) -> None:
    """At 10 Hz the second fix of a segment 36 m off: its step (360 m/s) is no car's, so
    the tracker starts afresh there and again at the next such step, and follows the
    clean fixes from the third on. It took the step as the velocity (which at a car's
    acceleration took a minute to come down) and the noisy fix as its clean-track
    anchor, and held a 36 m offset on the clean fixes after it."""
    n = 600
    dt = np.r_[0.0, np.full(n - 1, 0.1)]
    rng = np.random.default_rng(4)
    east = 12.0 * np.cumsum(dt) + rng.normal(0, 0.3, n)
    north = rng.normal(0, 0.3, n)
    north[1] += 36.0
    speed, heading = np.full(n, 12.0), np.full(n, 90.0)
    sp, hd = (speed, heading) if with_velocity else (None, None)
    for out in (
        offset_features(dt, east, north, sp, hd),
        offset_features_reference(
            dt, east, north, *((sp, hd) if sp is not None else _nans(len(dt)))
        ),
    ):
        assert (out[10:, 2] < 6.0).all()


def _nans(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.full(n, np.nan), np.full(n, np.nan)


def test_clean_drive_keeps_offset_small() -> None:
    dt, east, north, speed, heading = _drive(seed=3)
    for sp, hd in ((speed, heading), (None, None)):
        assert offset_features(dt, east, north, sp, hd)[:, 2].max() < 3.0


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(
        st.tuples(
            st.floats(-40, 40),
            st.floats(-40, 40),
            st.floats(0.1, 2.0),
            st.one_of(st.just(float("nan")), st.floats(0, 40)),
            st.floats(0, 360),
            st.booleans(),  # the fix repeats the previous one exactly (held)
        ),
        min_size=1,
        max_size=60,
    ),
    sigma_m=st.floats(0.5, 20.0),
    fault_s=st.floats(1.0, 100.0),
    restart_per_s=st.floats(1e-6, 0.1),
)
def test_kernel_matches_reference(
    steps: list[tuple[float, ...]], sigma_m: float, fault_s: float, restart_per_s: float
) -> None:
    arr = np.array(steps)
    dt = arr[:, 2]
    held = arr[:, 5] == 1.0
    east = np.cumsum(np.where(held, 0.0, arr[:, 0]))
    north = np.cumsum(np.where(held, 0.0, arr[:, 1]))
    prm = OffsetParams(sigma_m=sigma_m, fault_s=fault_s, restart_per_s=restart_per_s)
    a = offset_features(dt, east, north, arr[:, 3], arr[:, 4], prm)
    b = offset_features_reference(dt, east, north, arr[:, 3], arr[:, 4], prm)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_bad_parameters() -> None:
    with pytest.raises(ConfigError):
        OffsetParams(sigma_m=0).to_array()
    with pytest.raises(ConfigError):
        OffsetParams(noise_stay=1.5).to_array()
    with pytest.raises(ConfigError):
        OffsetParams(fault_s=float("nan")).to_array()


def test_a_step_that_undoes_the_offset_ends_the_fault_whatever_dead_reckoning_says() -> None:
    """Found on the DrivePlotR validation drive, positions only: three noise fixes
    about 37 m south, then the truth again. The velocity the tracker dead-reckons
    with (here a reported speed 6 m/s too high, like a motion model pulled by the
    fault) put the clean-track estimate 22 m off by the return, and the tracker
    took the distance to it for a new offset, held on clean fixes for 100 s."""
    dt, east, north, speed, heading = _drive(seed=2)
    north = north.copy()
    north[100:103] += [-37.2, -35.8, -37.4]
    fast = speed.copy()
    fast[99:104] += 6.0  # the velocity estimate is wrong around the fault
    for out in (
        offset_features(dt, east, north, fast, heading),
        offset_features_reference(dt, east, north, fast, heading),
    ):
        assert (out[100:103, 2] > 20.0).all()
        assert (out[103:, 2] < 8.0).all()  # the return ends it at once


def test_a_wrong_predicted_velocity_is_learnt_not_accumulated() -> None:
    """Positions only, and the segment's first fix is 30 m off: the first step sets
    the constant-velocity estimate 30 m/s wrong, and every clean step after it
    misses the prediction by the same 30 m. That is one velocity error, not a new
    jump each second: before, the tracker added it to the offset every step and
    held the sum (over 1 km) on clean fixes for 100 s. Now the third miss in a row
    reads as a velocity error: the estimate is corrected and the offset goes back
    to what it was before the run."""
    n = 60
    t = np.arange(n, dtype=float)
    dt = np.r_[np.nan, np.diff(t)]
    east, north = 24.0 * t, np.zeros(n)
    north[0] = 30.0
    nan = np.full(n, np.nan)
    for out in (
        offset_features(dt, east, north),
        offset_features_reference(dt, east, north, nan, nan),
    ):
        assert out[:, 2].max() < 65.0  # two steps' miss at most, then unlearnt
        assert (out[4:, 2] < 1.0).all()
        assert (out[4:, 7] == 0.0).all()


def test_a_noise_run_a_car_cannot_drive_teaches_no_velocity() -> None:
    """A stationary receiver at 5 Hz: noise fixes at +23 and +47 m step away by the
    same 24 m twice, at 120 m/s. Read as a velocity error, that became a 121 m/s
    velocity and a phantom 71 m offset; no car drives it, so it is a fault."""
    n = 80
    t = np.arange(n) * 0.2
    dt = np.r_[np.nan, np.diff(t)]
    east, north = np.zeros(n), np.zeros(n)
    east[40:42] = [22.9, 47.0]
    nan = np.full(n, np.nan)
    for out in (
        offset_features(dt, east, north),
        offset_features_reference(dt, east, north, nan, nan),
    ):
        assert (out[40:42, 2] > 20.0).all()
        assert (out[43:, 2] < 8.0).all()


def test_the_velocity_estimate_changes_no_faster_than_a_car() -> None:
    """Found on the TUC validation drive (5 Hz, parked, positions only): noise fixes
    25, 20, -22, -27 and -48 m east. The 5.5 m step between the first two was
    within threshold_m, so the constant-velocity estimate learnt from it: -14 m/s
    for a parked car, then -19 m/s, and the return to the truth read as a new
    35 m offset held for 100 s. A car's velocity changes by accel_allowance * dt
    a step at most; so does the estimate."""
    n = 120
    t = np.arange(n) * 0.2
    dt = np.r_[np.nan, np.diff(t)]
    east, north = np.zeros(n), np.zeros(n)
    east[40:45] = [25.2, 19.7, -21.7, -26.7, -48.4]
    nan = np.full(n, np.nan)
    for out in (
        offset_features(dt, east, north),
        offset_features_reference(dt, east, north, nan, nan),
    ):
        assert (out[46:, 2] < 8.0).all()


def test_after_a_restart_the_first_drivable_step_teaches_no_velocity() -> None:
    """A parked car at 1 Hz whose segment opens on two noise fixes (77 m east, then 48 m
    west): both first steps are faster than a car drives, so the tracker starts afresh
    twice, and the step back from the second noise fix to the truth (48 m, drivable) must
    not become the velocity (a first version took it, and the network flagged the
    parked fixes after it)."""
    n = 120
    dt = np.r_[0.0, np.ones(n - 1)]
    rng = np.random.default_rng(6)
    east, north = rng.normal(0, 0.3, n), rng.normal(0, 0.3, n)
    east[1] += 77.0
    east[2] -= 48.0
    for out in (
        offset_features(dt, east, north),
        offset_features_reference(dt, east, north, *_nans(n)),
    ):
        assert (out[4:, 2] < 6.0).all()


@pytest.mark.parametrize("with_velocity", [True, False])
def test_a_receiver_holding_its_fix_while_the_car_drives_leaves_no_offset_behind(
    with_velocity: bool,
) -> None:
    """Found on the Austin 2006 logger's validation drive (1 Hz, positions only): the
    receiver wrote the same fix three times while the car drove on at 11 m/s, then
    caught up. A held fix 11-22 m behind reads, to a filter, much like a braking car,
    and a filter that took it so lagged the car when it sped away and read the good
    fixes after it as a jump (16 fixes of phantom). A fix repeated to the last digit is
    as likely held as live (``_HELD``): the held reading is an outlier branch, and it
    is the one the next fixes bear out."""
    dt, east, north, speed, heading = _drive(seed=5)
    east, north = east.copy(), north.copy()
    east[101:104], north[101:104] = east[100], north[100]
    sp, hd = (speed, heading) if with_velocity else (None, None)
    for out in (
        offset_features(dt, east, north, sp, hd),
        offset_features_reference(
            dt, east, north, *((sp, hd) if sp is not None else _nans(len(dt)))
        ),
    ):
        if with_velocity:  # the reported velocity says the car never braked
            assert (out[102:104, 2] > 15.0).all()  # so the held fixes fall behind it
        # the catch-up may read as one outlier; the fixes after it are clean
        assert (out[105:, 2] < 6.0).all()


def test_a_standing_car_whose_receiver_pins_its_fix_holds_no_offset() -> None:
    """Static hold: a parked car whose receiver repeats its fix exactly for a minute,
    then drives off. The clean track explains the repeats (it predicts the fix where
    it is), so nothing is held, before or after."""
    n = 200
    dt = np.r_[0.0, np.ones(n - 1)]
    rng = np.random.default_rng(7)
    t = np.arange(n, dtype=float)
    speed = np.clip(t - 120.0, 0.0, 12.0)  # still until 120 s, then 1 m/s² to 12 m/s
    east = np.cumsum(speed * dt) + rng.normal(0, 0.4, n)
    north = rng.normal(0, 0.4, n)
    east[40:120], north[40:120] = east[40], north[40]  # pinned while standing
    nan = np.full(n, np.nan)
    for out in (
        offset_features(dt, east, north),
        offset_features_reference(dt, east, north, nan, nan),
    ):
        assert (out[:, 2] < 6.0).all()


@pytest.mark.parametrize("dt", [0.1, 1.0, 2.0, 9.0, 40.0])
def test_singer_process_noise_is_singers_closed_form(dt: float) -> None:
    """The numerically integrated process noise equals Singer's (1970) closed form
    where that form is well conditioned (alpha * dt >= 0.025), and the transition is
    the Singer model's."""
    prm = OffsetParams(sigma_a=1.3, tau_a=4.0)
    step = np.zeros(N_STEP)
    singer_step(prm.to_array(), dt, step)
    a, x = 1.0 / prm.tau_a, dt / prm.tau_a
    e1, e2 = np.exp(-x), np.exp(-2 * x)
    qc = 2 * a * prm.sigma_a**2
    closed = [
        qc / (2 * a**5) * (1 - e2 + 2 * x + 2 * x**3 / 3 - 2 * x**2 - 4 * x * e1),
        qc / (2 * a**4) * (e2 + 1 - 2 * e1 + 2 * x * e1 - 2 * x + x**2),
        qc / (2 * a**3) * (1 - e2 - 2 * x * e1),
        qc / (2 * a**3) * (4 * e1 - 3 - e2 + 2 * x),
        qc / (2 * a**2) * (e2 + 1 - 2 * e1),
        qc / (2 * a) * (1 - e2),
    ]
    np.testing.assert_allclose(step[4:], closed, rtol=1e-6)
    np.testing.assert_allclose(step[:4], [dt, (x - 1 + e1) / a**2, (1 - e1) / a, e1], rtol=1e-12)
    # the acceleration's spread is stationary: a long step forgets the start entirely
    assert step[9] == pytest.approx(prm.sigma_a**2 * (1 - e2), rel=1e-6)


def _low_rate_drive(n: int, seed: int, turn_deg_s: float) -> tuple[np.ndarray, ...]:
    """0.5 Hz, 12 m/s, turning at ``turn_deg_s``, 2 m receiver noise."""
    rng = np.random.default_rng(seed)
    dt = np.r_[0.0, np.full(n - 1, 2.0)]
    heading = np.radians(40.0 + turn_deg_s * np.cumsum(dt))
    east = np.cumsum(12.0 * np.sin(heading) * dt) + rng.normal(0, 2, n)
    north = np.cumsum(12.0 * np.cos(heading) * dt) + rng.normal(0, 2, n)
    return dt, east, north


def test_the_previous_fix_is_revised_one_fix_later() -> None:
    """``previous_offset_revised`` at a fix is the offset of the fix before as the best
    hypothesis's history has it now, which one more fix can change either way."""
    column = OFFSET_FEATURES.index("previous_offset_revised")
    # a gross outlier: seen at once, and still an outlier one fix later
    dt, east, north = _low_rate_drive(150, seed=1, turn_deg_s=0.0)
    east[100] += 60.0
    out = offset_features(dt, east, north)
    assert out[100, 2] > 50.0
    assert out[101, column] == pytest.approx(out[100, 2], abs=1e-9)
    assert out[101, 2] == 0.0
    # a 25 m outlier on a straight road: taken for the track at once, revealed at the next
    dt, east, north = _low_rate_drive(150, seed=1, turn_deg_s=0.0)
    east[100] += 25.0
    out = offset_features(dt, east, north)
    assert out[100, 2] == 0.0
    assert out[101, column] > 20.0
    # a 24.5 m outlier in a turn: the clean track follows it, so the good fix after it
    # is read as a fault; one fix later the history that took the outlier for an outlier
    # leads again and says that fix was clean
    dt, east, north = _low_rate_drive(150, seed=21, turn_deg_s=-2.2)
    east[100] += 24.5
    out = offset_features(dt, east, north)
    assert out[101, 2] > 25.0
    assert out[102, column] == 0.0
    assert (out[102:, 2] == 0.0).all()
