"""A streamed fix allocates nothing: ``grad_step`` works in arrays made once per segment."""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from numba.core.runtime import _nrt_python as nrt

from gradgps import Detector, LocalFrame
from gradgps._grad.pipeline import N_POINT_OUT, grad_step, new_state, new_work


@numba.njit
def _steps(P, S, H, gp, work, n, out):  # type: ignore[no-untyped-def]
    for i in range(n):
        grad_step(
            P, S, H, gp, work, 1.0, 41.25 + i * 1e-5, -95.98, math.nan, math.nan, out[0], out[1]
        )


@pytest.mark.slow
def test_grad_step_allocates_nothing_per_fix() -> None:
    m = Detector().model_
    P = m.params.array(1.0, LocalFrame(41.25, -95.98), m.dims)
    S, work = new_state(P), new_work(P)
    H = np.zeros(int(m.dims[1] + m.dims[2]), np.float32)
    out = np.zeros((2, N_POINT_OUT))
    _steps(P, S, H, m.gru_params, work, 1, out)  # compile
    was_on = nrt.memsys_stats_enabled()
    nrt.memsys_enable_stats()
    try:
        start = nrt.memsys_get_stats_alloc()
        _steps(P, S, H, m.gru_params, work, 1, out)
        one = nrt.memsys_get_stats_alloc() - start  # unboxing the arguments
        start = nrt.memsys_get_stats_alloc()
        _steps(P, S, H, m.gru_params, work, 200, out)
        many = nrt.memsys_get_stats_alloc() - start
    finally:
        if not was_on:
            nrt.memsys_disable_stats()
    assert many == one  # was one + 6 scratch arrays per fix (1,200 more)
