"""REMA: paper-mode choices, kernel == reference, streaming == batch, state round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gradgps._exceptions import ConfigError
from gradgps._grad.rema import REMA_MODES, Rema, RemaParams, rema_batch, rema_reference


def _assert_same(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> None:
    for name, x, y in zip(a._fields, a, b, strict=True):  # type: ignore[attr-defined]
        np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-9, err_msg=name)


def _drive(n: int = 300, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = 5000.0 + np.cumsum(rng.normal(8.0, 0.5, n))
    x[120:123] += 40.0
    return x


def test_paper_warm_up_is_plain_ema_without_flags() -> None:
    x = np.array([0.0, 10.0, 0.0, 10.0, 0.0, 500.0, 0.0, 0.0])
    prm = RemaParams(alpha=0.5, alpha_min=0.5, alpha_max=0.5, slide_size=6)
    out = rema_batch(x, prm)
    assert out.flag[:6].tolist() == [0] * 6  # 500 at t=5 is inside the warm-up
    assert np.isnan(out.lower[:6]).all()
    assert out.ema[0] == 0.0
    for t in range(1, 6):
        assert out.ema[t] == pytest.approx(0.5 * x[t - 1] + 0.5 * out.ema[t - 1])
    assert np.isfinite(out.lower[6])


def test_paper_bounds_from_std_of_ss_minus_one_previous_emas() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(0.0, 1.0, 40)
    prm = RemaParams(slide_size=8, sensitivity=2.0)
    out = rema_batch(x, prm)
    t = 30
    ema_before = out.ema[t - 8 : t - 1]
    centre = 0.5 * (out.lower[t] + out.upper[t])
    half = 0.5 * (out.upper[t] - out.lower[t])
    assert half == pytest.approx(2.0 * np.std(ema_before))
    p_value = np.mean([out.ema[t - 8], out.ema[t - 4], out.ema[t - 2]])
    alpha_used = out.alpha[t - 1]
    assert centre == pytest.approx(alpha_used * x[t - 1] + (1 - alpha_used) * p_value)


def test_paper_outlier_resets_ema_punishes_alpha_and_raw_value_feeds_next() -> None:
    x = np.r_[np.zeros(20), 100.0, np.zeros(3)]
    x[:20] += np.tile([0.1, -0.1], 10)
    prm = RemaParams(
        alpha=0.5, alpha_min=0.1, punish=0.2, reward=0.05, slide_size=6, min_margin=0.5
    )
    out = rema_batch(x, prm)
    assert out.flag.tolist().index(1) == 20
    assert out.alpha[19] == pytest.approx(0.9)
    assert out.ema[20] == pytest.approx(np.mean(out.ema[14:19]))
    assert out.alpha[20] == pytest.approx(out.alpha[19] - 0.2)
    # Literal paper: the raw outlier (100) is what the next EMA is built from.
    p_value = np.mean([out.ema[15], out.ema[18], out.ema[19]])
    centre = 0.5 * (out.lower[21] + out.upper[21])
    assert centre == pytest.approx(out.alpha[20] * 100.0 + (1 - out.alpha[20]) * p_value)


def test_min_margin_stops_flagging_a_stopped_car() -> None:
    rng = np.random.default_rng(2)
    x = 100.0 + rng.normal(0.0, 0.01, 200)  # parked: centimetre jitter
    x[150] += 0.05
    assert rema_batch(x, RemaParams()).flag.sum() > 0
    assert rema_batch(x, RemaParams(min_margin=1.0)).flag.sum() == 0


def test_trend_mode_is_translation_invariant_and_catches_a_jump_on_a_moving_car() -> None:
    x = _drive()
    prm = RemaParams(mode="trend", min_margin=3.0)
    a = rema_batch(x, prm)
    b = rema_batch(x + 1.0e5, prm)
    np.testing.assert_array_equal(a.flag, b.flag)
    assert a.flag[120:123].tolist() == [1, 1, 1]
    assert a.flag.sum() <= 6
    # The raw-position paper mode misses it: its bounds widen with the car's motion.
    assert rema_batch(x, RemaParams(min_margin=3.0)).flag[120:123].sum() == 0


@pytest.mark.parametrize("mode", REMA_MODES)
def test_kernel_matches_reference(mode: str) -> None:
    prm = RemaParams(mode=mode, min_margin=1.0, slide_size=7)
    _assert_same(rema_batch(_drive(), prm), rema_reference(_drive(), prm))


@settings(max_examples=40, deadline=None)
@given(
    values=st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=120),
    mode=st.sampled_from(REMA_MODES),
    ss=st.integers(3, 12),
    sens=st.floats(0.5, 5.0),
    margin=st.floats(0.0, 5.0),
    growth=st.floats(0.0, 2.0),
    reacquire=st.integers(0, 4),
    max_run=st.integers(0, 6),
    with_steps=st.booleans(),
)
def test_kernel_matches_reference_on_generated_tracks(
    values: list[float],
    mode: str,
    ss: int,
    sens: float,
    margin: float,
    growth: float,
    reacquire: int,
    max_run: int,
    with_steps: bool,
) -> None:
    x = np.cumsum(values)
    prm = RemaParams(
        mode=mode,
        slide_size=ss,
        sensitivity=sens,
        min_margin=margin,
        run_growth=growth,
        reacquire_after=reacquire,
        max_run=max_run,
    )
    # Known steps: the true steps with every third one unknown (NaN) and a small error.
    steps = np.diff(x, prepend=x[0]) + 0.5 if with_steps else None
    if steps is not None:
        steps[::3] = np.nan
    _assert_same(rema_batch(x, prm, steps), rema_reference(x, prm, steps))


@pytest.mark.parametrize("mode", REMA_MODES)
def test_streaming_equals_batch_across_a_json_state_round_trip(mode: str) -> None:
    x = _drive()
    prm = RemaParams(mode=mode, min_margin=2.0)
    batch = rema_batch(x, prm)
    stream = Rema(prm)
    rows = []
    for i, v in enumerate(x):
        if i == 150:
            stream = Rema().set_state(json.loads(json.dumps(stream.get_state())))
        rows.append(stream.update(v))
    got = np.array(rows, dtype=np.float64)
    np.testing.assert_array_equal(got[:, 0], batch.flag)
    np.testing.assert_array_equal(got[:, 1], batch.ema)
    np.testing.assert_array_equal(got[:, 5], batch.alpha)


def test_params_json_round_trip_and_validation() -> None:
    prm = RemaParams(alpha=0.4, slide_size=12, mode="trend", min_margin=2.5)
    assert RemaParams.from_json(prm.to_json()) == prm
    with pytest.raises(ConfigError, match="unknown REMA parameters"):
        RemaParams.from_json('{"alpha": 0.5, "window": 3}')
    with pytest.raises(ConfigError, match="slide_size"):
        RemaParams(slide_size=2).checked()
    with pytest.raises(ConfigError, match="mode"):
        rema_batch([1.0, 2.0], RemaParams(mode="fancy"))
    with pytest.raises(ConfigError, match="alpha_min"):
        RemaParams(alpha=0.05, alpha_min=0.1).checked()


@given(
    shift=st.floats(-500.0, 500.0).filter(lambda v: abs(v) > 1.0),
    length=st.integers(1, 150),
    max_run=st.integers(1, 25),
    speed=st.floats(0.0, 40.0),
)
def test_trend_never_dead_reckons_longer_than_max_run(
    shift: float, length: int, max_run: int, speed: float
) -> None:
    """Whatever the input (here: a shift of any size and length on a moving car with a
    known step that is slightly wrong), no run of flags outlasts ``max_run`` points."""
    x = np.arange(400) * speed + np.sin(np.arange(400) * 0.3)
    x[100 : 100 + length] += shift
    prm = RemaParams(mode="trend", min_margin=2.0, max_run=max_run)
    flags = rema_batch(x, prm, np.full(400, speed * 1.01)).flag
    run = longest = 0
    for f in flags:
        run = run + 1 if f else 0
        longest = max(longest, run)
    assert longest <= max_run
    with pytest.raises(ConfigError):
        RemaParams(max_run=-1).checked()
