"""The positions-only motion model: kernel equals reference; it never stays diverged."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps._exceptions import ConfigError
from gradgps._grad.motion import MOTION_FEATURES, MotionParams, motion_batch, motion_reference
from gradgps._grad.vehicle import CAR_MAX_SPEED

RUN_S = MOTION_FEATURES.index("motion_run_s")
NIS = MOTION_FEATURES.index("motion_nis")


def _curve(n: int, period: float, speed: float, radius: float, noise: float, seed: int):
    """A car at ``speed`` m/s on a circle of ``radius`` m, fixes every ``period`` s."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * period
    angle = speed * t / radius
    east = radius * np.sin(angle) + rng.normal(0, noise, n)
    north = radius * (1 - np.cos(angle)) + rng.normal(0, noise, n)
    return t, east, north


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    n=st.integers(0, 200),
    jumps=st.integers(0, 6),
)
def test_kernel_equals_reference(seed: int, n: int, jumps: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.choice([0.1, 0.5, 1.0, 1.0, 2.0], n))
    heading = np.cumsum(rng.normal(0, 0.05, n))
    speed = np.clip(15 + np.cumsum(rng.normal(0, 0.3, n)), 0, 40)
    step = np.r_[0.0, np.diff(t)] if n else np.zeros(0)
    east = np.cumsum(speed * np.sin(heading) * step) + rng.normal(0, 2, n)
    north = np.cumsum(speed * np.cos(heading) * step) + rng.normal(0, 2, n)
    if n and jumps:
        k = rng.integers(0, n, jumps)
        east[k] += rng.normal(0, 80, jumps)
    fast = motion_batch(t, east, north, 1.0)
    slow = motion_reference(t, east, north, 1.0)
    assert fast.shape == slow.shape == (n, len(MOTION_FEATURES))
    np.testing.assert_allclose(fast, slow, rtol=1e-9, atol=1e-7)


@pytest.mark.parametrize(
    ("period", "speed", "radius"),
    [(1.0, 30.0, 600.0), (2.0, 30.0, 600.0), (1.0, 10.0, 25.0), (0.1, 15.0, 100.0)],
)
def test_clean_curves_are_not_surprising(period: float, speed: float, radius: float) -> None:
    """A motorway curve at 1 Hz and 0.5 Hz, a roundabout, a 10 Hz bend: positions only."""
    t, east, north = _curve(400, period, speed, radius, noise=1.0, seed=1)
    feats = motion_batch(t, east, north, period)
    nis = feats[20:, NIS]
    assert np.mean(nis > MotionParams().gate) < 0.01
    assert np.all(feats[20:, RUN_S] <= MotionParams().max_run_s)


@pytest.mark.parametrize("period", [0.1, 1.0, 2.0])
def test_reacquires_after_a_long_jump(period: float) -> None:
    """A 100-fix offset of 150 m, then clean driving: followed again within max_run_s."""
    t, east, north = _curve(600, period, 25.0, 800.0, noise=1.5, seed=2)
    east = east.copy()
    east[200:300] += 150.0
    feats = motion_batch(t, east, north, period)
    params = MotionParams()
    # The onset and the return are surprises ...
    assert feats[200, NIS] > params.gate
    assert feats[300, NIS] > params.gate
    # ... and within max_run_s (plus one step) after each, the model follows again.
    settle = math.ceil(params.max_run_s / period) + 2
    for start in (200, 300):
        after = feats[start + settle : start + settle + 50]
        assert np.all(after[:, RUN_S] == 0.0)
        assert np.mean(after[:, NIS] > params.gate) < 0.05


def test_dropped_fix_is_not_a_fault() -> None:
    """A fix missing from a 1 Hz drive: the next one is 2 s later, as the model predicts."""
    t, east, north = _curve(300, 1.0, 30.0, 2000.0, noise=0.5, seed=3)
    keep = np.ones(300, bool)
    keep[150] = False
    feats = motion_batch(t[keep], east[keep], north[keep], 1.0)
    assert feats[150, MOTION_FEATURES.index("dt_ratio")] == pytest.approx(2.0)
    assert feats[150, NIS] < MotionParams().gate


@pytest.mark.parametrize(
    "bad", [{"gate": 0.0}, {"memory": 1.5}, {"max_run_s": math.inf}, {"turn_tau_s": -0.1}]
)
def test_params_are_checked(bad: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        MotionParams(**bad).checked()


def _braking(period: float, noise: float, seed: int):
    """Straight road: 28 m/s, a hard stop at 5 m/s² to walking pace, 20 s there,
    then 2.5 m/s² back to 28 m/s (a motorway exit queue)."""
    dt = 0.01
    phases = [
        (28.0, 0.0, 60.0),
        (28.0, -5.0, 5.0),
        (3.0, 0.0, 20.0),
        (3.0, 2.5, 10.0),
        (28.0, 0.0, 60.0),
    ]
    speeds = np.concatenate([np.clip(v0 + a * np.arange(0, d, dt), 3, 28) for v0, a, d in phases])
    x = np.cumsum(speeds) * dt
    t = np.arange(0, speeds.size * dt, period)
    idx = np.minimum((t / dt).astype(int), x.size - 1)
    rng = np.random.default_rng(seed)
    return t, x[idx] + rng.normal(0, noise, t.size), rng.normal(0, noise, t.size)


@pytest.mark.parametrize("period", [1.0, 2.0])
def test_hard_braking_is_followed_not_dead_reckoned(period: float) -> None:
    """A real 0.5 Hz drive braking hard must not lock the model out for max_run_s.

    Found on the Nevada drive: a step that the model did not expect was gated,
    the model dead-reckoned at the old speed while the fixes slowed, and no
    later fix agreed with the dead-reckoned motion, so it stayed lost for
    max_run_s, again and again. Fixes that agree among themselves bring it back.
    """
    t, east, north = _braking(period, noise=1.0, seed=4)
    feats = motion_batch(t, east, north, period)
    assert feats[:, RUN_S].max() <= period  # never more than one fix dead-reckoned
    assert np.mean(feats[:, RUN_S] > 0) < 0.03


def test_a_curve_after_a_jump_is_followed_at_once() -> None:
    """0.5 Hz, 30 m/s on a 600 m curve, a 150 m jump of 100 fixes: within two fixes
    of either edge the model follows the fixes again, turning (not in max_run_s)."""
    t, east, north = _curve(600, 2.0, 30.0, 600.0, noise=0.3, seed=1)
    east = east.copy()
    east[200:300] += 150.0
    feats = motion_batch(t, east, north, 2.0)
    for start in (200, 300):
        assert feats[start, NIS] > MotionParams().gate
        assert np.all(feats[start + 3 : start + 100, RUN_S] == 0.0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), jumps=st.integers(0, 8))
def test_turn_rate_never_exceeds_what_a_car_can_pull(seed: int, jumps: int) -> None:
    """Whatever the fixes, |turn rate| x speed stays within max_accel (no circles)."""
    rng = np.random.default_rng(seed)
    n = 200
    t = np.cumsum(rng.choice([0.1, 1.0, 2.0], n))
    east = np.cumsum(rng.normal(10, 8, n))
    north = np.cumsum(rng.normal(0, 8, n))
    if jumps:
        east[rng.integers(0, n, jumps)] += rng.normal(0, 100, jumps)
    feats = motion_batch(t, east, north, 1.0)
    lateral = feats[:, MOTION_FEATURES.index("motion_lateral_accel")]
    assert np.all(lateral <= MotionParams().max_accel + 1e-9)


@pytest.mark.parametrize("period", [0.1, 1.0, 2.0])
def test_a_frozen_fix_stops_harder_than_any_car(period: float) -> None:
    """A car braking to a stop at 3 m/s² and a receiver freezing its fix at 20 m/s
    both stand still afterwards; stop_decel tells them apart at every rate."""
    decel = MOTION_FEATURES.index("stop_decel")
    still = MOTION_FEATURES.index("still_s")
    rng = np.random.default_rng(5)
    t = np.arange(0, 60, period)
    speed = np.clip(20 - 3 * np.clip(t - 20, 0, None), 0, None)  # stops at t = 26.7 s
    x = np.cumsum(speed) * period
    braking = motion_batch(t, x + rng.normal(0, 0.05, t.size), np.zeros(t.size), period)
    assert braking[-1, still] > 20  # stood still since the stop
    assert braking[:, decel].max() < 3.5
    frozen_x = 20.0 * t
    frozen_x[t >= 20] = frozen_x[t >= 20][0]  # the fix freezes at 20 m/s
    frozen = motion_batch(t, frozen_x, np.zeros(t.size), period)
    assert frozen[-1, still] > 20
    assert frozen[-1, decel] > 8  # beyond what a car pulls (about 0.6-0.9 g)


def test_a_growing_offset_is_no_track_to_follow() -> None:
    """Two faulty fixes whose offset grows by the same amount twice must not be followed.

    Found on the TUC validation drive (4-5 Hz, positions only): offsets of
    0, -24, -47 m on two fixes made two observed steps that agreed with each
    other, the model re-acquired on them at 120 m/s, and its speed estimate
    (4.6 m/s before) read 51 m/s when the fixes came back; the offset tracker
    then held a phantom 60 m offset on clean fixes for tens of seconds.
    """
    period, speed = 0.2, 4.6
    n = 60
    t = np.arange(n) * period
    east = speed * t.copy()
    north = np.zeros(n)
    east[30] -= 24.0
    east[31] -= 47.0
    feats = motion_batch(t, east, north, period)
    # The model's speed never leaves what a car could do from 4.6 m/s.
    assert feats[:, MOTION_FEATURES.index("motion_speed")].max() < speed + 6.0 * 3 * period + 1
    assert np.all(feats[34:, NIS] < 1.0)  # and it is on the track again at once


def test_a_noise_run_whose_steps_agree_by_chance_is_no_track() -> None:
    """Found on the NL motorway validation drive (phone, 1 Hz, positions only):
    four noise fixes 32, 36, 18 and 11 m off north of a car at 24 m/s east. Two
    of their steps agreed with each other within the gate, the model re-acquired
    on them, its speed read 37 m/s, and it rejected the real track for seven
    seconds after the noise had ended. Two steps agreeing by chance is no track;
    three fixes moving consistently are."""
    period, speed, n = 1.0, 24.0, 90
    t = np.arange(n) * period
    rng = np.random.default_rng(3)
    east = speed * t + rng.normal(0, 0.3, n)
    north = rng.normal(0, 0.3, n)
    north[60:64] += [-32.4, 35.6, 17.9, -11.3]
    for feats in (motion_batch(t, east, north, period), motion_reference(t, east, north, period)):
        motion_speed = feats[:, MOTION_FEATURES.index("motion_speed")]
        assert np.all(np.abs(motion_speed[64:] - speed) < 3.0)
        assert np.all(feats[66:, RUN_S] == 0.0)  # following the fixes again at once


def test_a_gap_in_the_log_does_not_open_the_gate() -> None:
    """A 60 s gap inside what the model is given as one segment (a logger paused),
    then a 50 m jump half a minute later, at 1 Hz, positions only.

    Across the gap the car's routine acceleration explains hundreds of metres,
    so the gate accepts the fix after it; its innovation says nothing about the
    receiver's noise. Before the running scale was winsorised, that one
    innovation took the scale from a few metres to about 190 m, and the jump,
    30 fixes later, passed the gate (and pulled the velocity after it)."""
    rng = np.random.default_rng(3)
    t = np.r_[np.arange(100.0), 160.0 + np.arange(60.0)]
    heading = np.radians(60.0)
    east = 12.0 * np.sin(heading) * t + rng.normal(0, 1.0, t.size)
    north = 12.0 * np.cos(heading) * t + rng.normal(0, 1.0, t.size)
    east[100] += 300.0  # the car took another road during the gap: it comes back 300 m off
    east[101:] += 300.0
    east[130:133] += 50.0  # three fixes jumped 50 m (the model re-acquires the
    # jumped track on its second fix, which moves like the track: see the module doc)
    for feats in (motion_batch(t, east, north, 1.0), motion_reference(t, east, north, 1.0)):
        assert feats[100, NIS] <= MotionParams().gate  # the fix after the gap is taken
        assert feats[130, NIS] > MotionParams().gate  # the jump is a surprise
        assert feats[133, NIS] > MotionParams().gate  # and so is its end
        assert (feats[140:, NIS] < 2.0).all()  # the track is followed again


def test_the_velocity_is_never_faster_than_a_car() -> None:
    """A minute of 50 m noise on every fix (a receiver in a deep canyon), 1 Hz, a car at
    13 m/s: re-acquired after ``max_run_s`` on the step between two noise fixes, the
    model's velocity read 100 m/s (a simulated drive), and dead-reckoned from there."""
    rng = np.random.default_rng(11)
    t = np.arange(200.0)
    east = 13.0 * t + rng.normal(0, 1.0, t.size)
    north = rng.normal(0, 1.0, t.size)
    east[50:110] += rng.normal(0, 50.0, 60)
    north[50:110] += rng.normal(0, 50.0, 60)
    speed = MOTION_FEATURES.index("motion_speed")
    for feats in (motion_batch(t, east, north, 1.0), motion_reference(t, east, north, 1.0)):
        assert feats[:, speed].max() <= CAR_MAX_SPEED + 1e-9
        assert (feats[130:, RUN_S] == 0).all()  # and the track is followed again


@pytest.mark.parametrize("noisy", [0, 1])
def test_a_first_step_no_car_drives_starts_the_segment_afresh(noisy: int) -> None:
    """At 10 Hz the first or the second fix of a segment 36 m off: the step between them
    (360 m/s) is no car's, so the model starts afresh at the second fix and follows
    the track from the next steps. It started its velocity at 364 m/s and rejected
    the clean fixes after it (kernel and reference alike)."""
    n = 200
    t = np.arange(n) * 0.1
    rng = np.random.default_rng(5)
    east = 12.0 * t + rng.normal(0, 0.3, n)
    north = rng.normal(0, 0.3, n)
    north[noisy] += 36.0
    for feats in (motion_batch(t, east, north, 0.1), motion_reference(t, east, north, 0.1)):
        speed = feats[:, MOTION_FEATURES.index("motion_speed")]
        assert (speed <= 70.0).all()
        assert (feats[8:, NIS] < 3.0).all()  # the clean fixes fit
        assert abs(speed[-1] - 12.0) < 1.0


def test_after_a_restart_the_model_starts_still() -> None:
    """A parked car at 1 Hz whose segment opens on two noise fixes (77 m east, then 48 m
    west): the model starts afresh twice, then still, not at the 48 m/s of the step
    back from the second noise fix."""
    n = 60
    t = np.arange(n, dtype=np.float64)
    rng = np.random.default_rng(6)
    east, north = rng.normal(0, 0.3, n), rng.normal(0, 0.3, n)
    east[1] += 77.0
    east[2] -= 48.0
    for feats in (motion_batch(t, east, north, 1.0), motion_reference(t, east, north, 1.0)):
        assert (feats[4:, MOTION_FEATURES.index("motion_speed")] < 2.0).all()
        assert (feats[4:, NIS] < 3.0).all()
