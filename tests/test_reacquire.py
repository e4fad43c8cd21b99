"""No state stays diverged (issue 13): after a fault ends, the pipeline's REMA, offset
tracker and motion model follow the fixes again within a bounded time, from
positions alone, at 10, 1 and 0.5 Hz, on straight roads, motorway curves and
roundabouts."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps._grad.motion import MotionParams
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.geo import LocalFrame

PARAMS = PipelineParams()
NAMES = pipeline_feature_names(PARAMS)
FRAME = LocalFrame(48.1, 11.5)
#: m: an offset the tracker holds above this on a clean fix is a phantom.
THRESHOLD_M = 8.0
#: s: a bound on how long the tracker holds a shift that never ends before a restart
#: explains the fixes better: about 75 s from the default priors (the restart's and a
#: jump's start odds, 3.9 nats, over what holding a jump costs a second beyond a clean
#: track, 0.05 nats), less where the clean track fits the fixes worse.
HOLD_BOUND_S = 100.0


def _uncompress(v: np.ndarray) -> np.ndarray:
    return np.sign(v) * np.expm1(np.abs(v))


def _features(t: np.ndarray, east: np.ndarray, north: np.ndarray) -> dict[str, np.ndarray]:
    lat, lon = FRAME.to_geodetic(east, north)
    nan = np.full(t.size, np.nan)
    feats = grad_features(PARAMS, FRAME, t, lat, lon, nan, nan).features
    return {name: _uncompress(feats[:, k]) for k, name in enumerate(NAMES)}


def _drive(n: int, period: float, speed: float, radius: float, seed: int):
    """A car on a circle (radius = inf: a straight road), with a slowly wandering
    receiver error (Gauss-Markov, as real receivers have) and 0.3 m of white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * period
    angle = speed * t / radius
    east = radius * np.sin(angle) if np.isfinite(radius) else speed * t
    north = radius * (1 - np.cos(angle)) if np.isfinite(radius) else np.zeros(n)
    drift = np.cumsum(rng.normal(0, 0.1 * np.sqrt(period), (2, n)), axis=1)
    return (
        t,
        east + drift[0] + rng.normal(0, 0.3, n),
        north + drift[1] + rng.normal(0, 0.3, n),
    )


def _last_true(x: np.ndarray) -> int:
    idx = np.flatnonzero(x)
    return int(idx.max()) + 1 if idx.size else 0


CASES = [
    (1.0, 30.0, np.inf),  # motorway, straight
    (1.0, 30.0, 600.0),  # motorway curve at 1 Hz, positions only
    (2.0, 30.0, 600.0),  # the same at 0.5 Hz
    (1.0, 8.0, 25.0),  # roundabout
    (0.1, 15.0, 200.0),  # 10 Hz bend
    (0.1, 25.0, 150.0),  # 10 Hz motorway ramp, 4 m/s² to the side
    (0.2, 10.0, 30.0),  # 5 Hz tight turn
]


@pytest.mark.parametrize(("period", "speed", "radius"), CASES)
def test_a_100_fix_jump_then_clean_driving(period: float, speed: float, radius: float) -> None:
    t, east, north = _drive(600, period, speed, radius, seed=1)
    shifted = east.copy()
    shifted[200:300] += 150.0
    f = _features(t, shifted, north)
    rema = (f["east_rema_flag"] > 0) | (f["north_rema_flag"] > 0)
    after = slice(300, 600)
    rema_max_run = PARAMS.rema.max_run
    # REMA: no run of flags after the end outlasts max_run (+ the end's own flag).
    assert _last_true(rema[after][: rema_max_run + 5]) <= rema_max_run + 1
    assert rema[320:].mean() < 0.05
    # The offset tracker lets go of the offset at the end, and holds none later: at
    # once where it held the jump to its end; where it let the jump go before (200 s
    # at 0.5 Hz is beyond its hold; a roundabout at 1 Hz turns 18 degrees a fix, and a
    # restart there soon explains the fixes as well), the jump's end reads as a new
    # jump, released within the hold.
    held_to_end = (f["offset_norm"][200:300] > THRESHOLD_M).mean() > 0.8
    bound = 3 if held_to_end else int(np.ceil(HOLD_BOUND_S / period)) + 3
    assert _last_true(f["offset_norm"][after] > THRESHOLD_M) <= bound
    if (period == 1.0 and radius >= 600.0) or period <= 0.2:
        # At 5-10 Hz the clean track follows the turn (an acceleration that lasts,
        # Singer's model): a constant-velocity track lagged it, the jump was let go
        # after 2-3 s, and its end read as a new jump for 2-8 s more (18-83 fixes).
        assert held_to_end
    # The motion model follows the fixes again within max_run_s.
    settle = int(np.ceil(MotionParams().max_run_s / period)) + 2
    assert np.all(f["motion_run_s"][300 + settle :] == 0.0)


@pytest.mark.parametrize(("period", "speed", "radius"), CASES)
def test_clean_drives_hold_no_phantom_offset(period: float, speed: float, radius: float) -> None:
    t, east, north = _drive(600, period, speed, radius, seed=2)
    f = _features(t, east, north)
    assert (f["offset_norm"][20:] > THRESHOLD_M).mean() < 0.01
    rema = (f["east_rema_flag"] > 0) | (f["north_rema_flag"] > 0)
    assert rema[20:].mean() < 0.05


@settings(max_examples=15, deadline=None)
@given(
    start=st.integers(30, 250),
    length=st.integers(1, 200),
    shift=st.floats(20.0, 500.0),
    period=st.sampled_from([0.1, 1.0, 2.0]),
)
def test_any_jump_is_let_go_after_it_ends(
    start: int, length: int, shift: float, period: float
) -> None:
    t, east, north = _drive(start + length + 160, period, 25.0, 800.0, seed=start)
    north = north.copy()
    north[start : start + length] += shift
    f = _features(t, east, north)
    end = start + length
    # The guarantee whatever the jump: a suspicion never outlives HOLD_BOUND_S (the
    # fixed cases above show the usual release, within a few fixes).
    settle = int(np.ceil(HOLD_BOUND_S / period)) + 3
    assert _last_true(f["offset_norm"][end:] > THRESHOLD_M) <= settle
    rema = (f["east_rema_flag"] > 0) | (f["north_rema_flag"] > 0)
    assert _last_true(rema[end : end + 60]) <= PARAMS.rema.max_run + 1


def test_a_noise_burst_leaves_no_offset_behind() -> None:
    """The same burst as tests/test_motion.py's noise run, through the whole
    pipeline: before, the motion model's wrong velocity fed the offset tracker,
    which added the same 30-50 m miss to the offset every second and held 330 m
    on clean fixes for 100 s."""
    t, east, north = _drive(120, 1.0, 24.0, np.inf, 3)
    north = north.copy()
    north[60:64] += [-32.4, 35.6, 17.9, -11.3]
    f = _features(t, east, north)
    assert _last_true(f["offset_norm"][64:] > THRESHOLD_M) == 0
    assert np.all(np.abs(f["motion_speed"][64:] - 24.0) < 3.0)


@pytest.mark.parametrize("period", [0.1, 1.0])
def test_a_wrong_velocity_from_the_start_is_unlearnt(period: float) -> None:
    """A segment whose first fix is 30 m off: the first step sets both velocity
    estimates 30 m/s wrong at 1 Hz (300 m/s at 10 Hz), and every clean step after
    it misses by the same amount. The rule-based tracker this model replaced
    added that to the offset each step and held 100-170 m on clean fixes for
    100 s; the switching model restarts the young track on the good fixes."""
    n = int(60 / period)
    t, east, north = _drive(n, period, 24.0, np.inf, 3)
    north = north.copy()
    north[0] += 30.0
    f = _features(t, east, north)
    assert f["offset_norm"][int(10 / period) :].max() < 80.0
    assert np.all(f["offset_norm"][3:] < 100.0)
