"""pipeline.lanes_step (many streams in one step) gives grad_step's numbers bit for bit.

Streams of different sampling periods (different parameters), with and without
speed and heading, with jumps and NaN readings, stepped together in blocks of
varying size (a block smaller than, equal to and larger than the work arrays'
``LANES`` is not needed: the caller splits), against one ``grad_step`` per
stream: every output and every state equal as bits.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gradgps._grad.detector import load_grad_model
from gradgps._grad.pipeline import (
    N_POINT_OUT,
    grad_step,
    lanes_step,
    new_lane_work,
    new_state,
    new_work,
)
from gradgps._tracks.geo import LocalFrame


def _streams(n: int, steps: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    lat = 45.0 + np.cumsum(rng.normal(8e-5, 3e-5, (steps, n)), axis=0)
    lon = 7.0 + np.cumsum(rng.normal(0.0, 5e-5, (steps, n)), axis=0)
    jumps = rng.random((steps, n)) < 0.03
    lat[jumps] += 4e-4  # about 45 m
    speed = np.abs(rng.normal(11.0, 3.0, (steps, n)))
    heading = rng.uniform(0.0, 360.0, (steps, n))
    speed[rng.random((steps, n)) < 0.05] = np.nan
    heading[:, : n // 3] = np.nan  # a third positions only
    return {"lat": lat, "lon": lon, "speed": speed, "heading": heading}


@pytest.mark.parametrize("n", [1, 5, 37])
def test_lanes_step_equals_grad_step_bit_for_bit(n: int) -> None:
    _check_lanes(load_grad_model(None), n)


def test_lanes_step_carries_a_confirm_head_bit_for_bit(tmp_path) -> None:
    from _gru_support import random_detector_model
    from gradgps._grad.pipeline import O_CONFIRM

    m = load_grad_model(random_detector_model(tmp_path, confirm_head=True))
    # Verdicts that settle one fix late (the loaded model's confirm threshold)...
    out, settled = _check_lanes(m, 5)
    assert np.isnan(out[:, O_CONFIRM]).all()  # at once: no confirm read yet
    assert np.isfinite(settled[:, O_CONFIRM]).all()  # settled: the read that decided it
    # ... and at once, the head's output riding along.
    m = dataclasses.replace(m, params=dataclasses.replace(m.params, confirm_threshold=None))
    out, settled = _check_lanes(m, 5)
    assert np.isfinite(out[:, O_CONFIRM]).all()
    assert np.isnan(settled).all()


def _check_lanes(m, n: int) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Step ``n`` streams of model ``m`` both ways, assert equal bits; the last outputs (at
    once, and settled)."""
    steps = 60
    data = _streams(n, steps, seed=n)
    periods = [(0.2, 1.0, 2.0)[v % 3] for v in range(n)]
    frames = [LocalFrame(float(data["lat"][0, v]), float(data["lon"][0, v])) for v in range(n)]
    Ps = np.array([m.params.array(periods[v], frames[v], m.dims) for v in range(n)])
    states = [new_state(Ps[v]) for v in range(n)]
    s_len = np.array([s.size for s in states], np.int64)
    s_off = np.r_[0, np.cumsum(s_len)[:-1]].astype(np.int64)
    Ss = np.concatenate(states)
    h_len = int(m.dims[1] + m.dims[2])
    Hs = np.zeros((n, h_len), np.float32)
    # The reference: one grad_step per stream per fix.
    ref_S = [s.copy() for s in states]
    ref_H = [np.zeros(h_len, np.float32) for _ in range(n)]
    ref_work = [new_work(Ps[v]) for v in range(n)]
    work = new_lane_work(Ps[0], 64)
    slot = np.arange(n, dtype=np.int64)[::-1].copy()  # lanes need not be in slot order
    rows = np.arange(n, dtype=np.int64)
    for k in range(steps):
        dt = np.array([0.0 if k == 0 else periods[v] for v in slot])
        cols = {name: np.ascontiguousarray(data[name][k][slot]) for name in data}
        out = np.full((n, N_POINT_OUT), np.nan)
        settled = np.full((n, N_POINT_OUT), np.nan)
        lanes_step(
            Ps, Ss, s_off, s_len, Hs, m.gru_params, work, slot, rows, n, dt,
            cols["lat"], cols["lon"], cols["speed"], cols["heading"], out, settled,
        )  # fmt: skip
        for v, s in enumerate(slot):
            expected = np.empty(N_POINT_OUT)
            expected_settled = np.full(N_POINT_OUT, np.nan)
            grad_step(
                Ps[s], ref_S[s], ref_H[s], m.gru_params, ref_work[s], dt[v],
                cols["lat"][v], cols["lon"][v], cols["speed"][v], cols["heading"][v], expected,
                expected_settled,
            )  # fmt: skip
            assert out[v].view(np.int64).tolist() == expected.view(np.int64).tolist(), (k, s)
            assert settled[v].view(np.int64).tolist() == expected_settled.view(np.int64).tolist(), (
                k,
                s,
            )
    for s in range(n):
        a = s_off[s]
        assert Ss[a : a + s_len[s]].view(np.int64).tolist() == ref_S[s].view(np.int64).tolist()
        assert Hs[s].view(np.int32).tolist() == ref_H[s].view(np.int32).tolist()
    return out, settled
