"""One GRAD step for many independent streams at once ("lanes"), the same numbers bit for bit.

:func:`gradgps._grad.pipeline.grad_step` scores one fix of one stream: the
features, then the GRU as matrix-vector products (96 and 48 gate rows), then
the verdict. Each of those products is a loop over the inputs whose body is a
short vector loop over the gates, and at this size the loop's set-up costs
about as much as its arithmetic: the network took more than half of a fix's
time. A fleet scores one fix of thousands of vehicles at a time, so
:func:`lanes_step` runs the same step for many streams together: the
features stream by stream (the very function ``grad_step`` calls), then both
GRU layers for all streams as matrix-matrix products whose innermost loop
runs over the streams (long, contiguous, vectorised), then the verdict
stream by stream (again ``grad_step``'s own function).

The numbers are those of ``grad_step``, bit for bit: every gate of every
stream is summed in the same order as :func:`gradgps._grad.gru._cell` sums it
(its bias, then input 0, 1, 2, ..., each product rounded to float32 and added
in float32), four inputs per pass with the additions kept in that order, and
the gates go through the same functions. ``tests/test_lanes.py`` holds
:func:`lanes_step` to ``grad_step`` fix by fix; the fleet's property test
holds :class:`gradgps.FleetDetector` (which runs on it) to one Detector per
vehicle.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from .gru import _heads, _layer_size, _scratch_size, _sigmoid_scalar, _tanh_scalar
from .pipeline import _N_OFF_OUT, _SH, _core_width, _dims, _features_point, _verdict

__all__ = ["LANES", "lanes_step", "new_lane_work"]

FloatArray = NDArray[np.float64]

#: Streams stepped together: long enough that the GRU's inner loops run over many
#: streams, short enough that one block's gate buffers stay in the L1/L2 caches.
LANES = 128


@numba.njit(cache=True)
def new_lane_work(P: FloatArray, lanes: int) -> Any:
    """Work arrays of :func:`lanes_step` for up to ``lanes`` streams of models shaped like ``P``.

    ``(dims, core_out, off_out, rec_out, x, xt, ht, gi, gh, scratch, gru_out, east_north)``.
    """
    dims = _dims(P)
    n_features, hidden1, hidden2 = dims[0], dims[1], dims[2]
    widest = max(hidden1, hidden2)
    return (
        dims,
        np.empty((lanes, _core_width(P))),
        np.empty((lanes, _N_OFF_OUT)),
        np.empty(3),
        np.empty((lanes, n_features), np.float32),
        np.empty((n_features, lanes), np.float32),
        np.empty((hidden1 + hidden2, lanes), np.float32),
        np.empty((3 * widest, lanes), np.float32),
        np.empty((3 * widest, lanes), np.float32),
        np.empty(_scratch_size(dims), np.float32),
        np.empty(1 + dims[3], np.float32),
        np.empty((lanes, 2)),
    )


@numba.njit(cache=True)
def _products(params: Any, o_w: int, n_in: int, g: int, inputs: Any, gates: Any, n: int) -> None:
    """``gates[i, v] += sum_j W[j, i] * inputs[j, v]`` for the first ``n`` streams, ``W`` (n_in x
    g) at ``params[o_w:]``, in :func:`gradgps._grad.gru._cell`'s order: j = 0, 1, 2, ...,
    each product and sum in float32 (four inputs per pass, added left to right)."""
    j = 0
    while j + 4 <= n_in:
        x0, x1, x2, x3 = inputs[j], inputs[j + 1], inputs[j + 2], inputs[j + 3]
        for i in range(g):
            w0 = params[o_w + j * g + i]
            w1 = params[o_w + (j + 1) * g + i]
            w2 = params[o_w + (j + 2) * g + i]
            w3 = params[o_w + (j + 3) * g + i]
            row = gates[i]
            for v in range(n):
                row[v] = (((row[v] + w0 * x0[v]) + w1 * x1[v]) + w2 * x2[v]) + w3 * x3[v]
        j += 4
    while j < n_in:
        xj = inputs[j]
        for i in range(g):
            w = params[o_w + j * g + i]
            row = gates[i]
            for v in range(n):
                row[v] += w * xj[v]
        j += 1


@numba.njit(cache=True)
def _cell_lanes(
    params: Any, o_wih: int, n_in: int, size: int, x: Any, h: Any, gi: Any, gh: Any, n: int
) -> None:
    """:func:`gradgps._grad.gru._cell` for ``n`` streams: ``x`` (n_in x lanes), ``h`` (size x
    lanes) updated in place; ``gi``, ``gh``: gate buffers (at least 3 size x lanes)."""
    g = 3 * size
    o_whh = o_wih + n_in * g
    o_bih = o_whh + size * g
    o_bhh = o_bih + g
    for i in range(g):
        bi = params[o_bih + i]
        bh = params[o_bhh + i]
        for v in range(n):
            gi[i, v] = bi
            gh[i, v] = bh
    _products(params, o_wih, n_in, g, x, gi, n)
    _products(params, o_whh, size, g, h, gh, n)
    for i in range(size):
        for v in range(n):
            r = _sigmoid_scalar(gi[i, v] + gh[i, v])
            z = _sigmoid_scalar(gi[size + i, v] + gh[size + i, v])
            c = _tanh_scalar(gi[2 * size + i, v] + r * gh[2 * size + i, v])
            h[i, v] = (1.0 - z) * c + z * h[i, v]


@numba.njit(cache=True)
def lanes_step(
    Ps: FloatArray,
    Ss: FloatArray,
    s_off: NDArray[np.int64],
    s_len: NDArray[np.int64],
    Hs: Any,
    gp: Any,
    work: Any,
    slot: NDArray[np.int64],
    rows: NDArray[np.int64],
    n: int,
    dt: FloatArray,
    lat: FloatArray,
    lon: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    out: FloatArray,
) -> None:
    """One fix for each of ``n`` streams (no stream twice), as :func:`grad_step` scores it.

    Stream ``v`` has parameters ``Ps[slot[v]]``, state ``Ss[s_off[slot[v]]:][:s_len[slot[v]]]``
    and GRU state ``Hs[slot[v]]``; its fix is row ``rows[v]`` of ``dt``, ``lat``, ``lon``,
    ``speed``, ``heading``, and its 7 outputs go to ``out[rows[v]]``. ``work``:
    :func:`new_lane_work` (for at least ``n`` streams).
    """
    dims, core_out, off_out, rec_out, x, xt, ht, gi, gh, scratch, gru_out, en = work
    n_features, hidden1, hidden2 = dims[0], dims[1], dims[2]
    for v in range(n):
        s = slot[v]
        i = rows[v]
        a = s_off[s]
        en[v, 0], en[v, 1] = _features_point(
            Ps[s],
            Ss[a : a + s_len[s]],
            core_out[v],
            off_out[v],
            dt[i],
            lat[i],
            lon[i],
            speed[i],
            heading[i],
            x[v],
        )
    # The GRU for all streams at once (gradgps._grad.gru._recurrent_step, transposed).
    for j in range(n_features):
        mean = gp[j]
        inv_std = gp[n_features + j]
        for v in range(n):
            scaled = (x[v, j] - mean) * inv_std
            xt[j, v] = scaled if math.isfinite(scaled) else 0.0
    for k in range(hidden1 + hidden2):
        for v in range(n):
            ht[k, v] = Hs[slot[v], k]
    o1 = 2 * n_features
    _cell_lanes(gp, o1, n_features, hidden1, xt, ht[:hidden1], gi, gh, n)
    o2 = o1 + _layer_size(n_features, hidden1)
    _cell_lanes(gp, o2, hidden1, hidden2, ht[:hidden1], ht[hidden1:], gi, gh, n)
    for v in range(n):
        s = slot[v]
        H = Hs[s]
        for k in range(hidden1 + hidden2):
            H[k] = ht[k, v]
        _heads(gp, dims, H, scratch, gru_out)
        a = s_off[s]
        _verdict(
            Ps[s],
            Ss[a : a + s_len[s]],
            dims,
            gru_out,
            core_out[v],
            rec_out,
            en[v, 0],
            en[v, 1],
            off_out[v, _SH],
            off_out[v, _SH + 1],
            out[rows[v]],
        )
