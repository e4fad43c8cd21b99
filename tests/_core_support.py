"""``CorePipeline``: the statistical core streamed point by point, for tests and benchmarks.

The product streams through :class:`gradgps.Detector` (:mod:`gradgps._grad.pipeline`);
this wrapper around :func:`gradgps._grad.core.core_step` lets the tests check
stream against batch (:func:`gradgps._grad.core.core_batch`) and lets
``benchmarks/core_speed.py`` time one streaming step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gradgps._exceptions import ConfigError
from gradgps._grad.core import (
    N_RESULT,
    R_ALERT,
    R_CODE,
    R_EAST,
    R_FLAG,
    R_NORTH,
    R_SCORE,
    CoreParams,
    core_new_state,
    core_state_size,
    core_step,
)
from gradgps._grad.rema import N_OUT

__all__ = ["CorePipeline"]


class CorePipeline:
    """Streaming pipeline for one segment: ``update(east, north, speed, heading)`` per point.

    Returns ``(flag, time_code, east_clean, north_clean, alert, score)``; the
    point's feature vector is :attr:`features` (a view, overwritten by the
    next call). State: one float array, moved by :meth:`get_state` /
    :meth:`set_state` as plain JSON-able data.
    """

    def __init__(self, params: CoreParams | None = None) -> None:
        self.params = params or CoreParams()
        self._P = self.params.to_array()
        self._S = core_new_state(self._P)
        self._out = np.zeros(N_RESULT + 2 * N_OUT + self.params.n_features())
        self.features = self._out[N_RESULT + 2 * N_OUT :]

    def update(
        self, east: float, north: float, speed: float = np.nan, heading: float = np.nan
    ) -> tuple[int, int, float, float, int, float]:
        core_step(self._P, self._S, east, north, speed, heading, self._out)
        o = self._out
        return (
            int(o[R_FLAG]),
            int(o[R_CODE]),
            float(o[R_EAST]),
            float(o[R_NORTH]),
            int(o[R_ALERT]),
            float(o[R_SCORE]),
        )

    def get_state(self) -> dict[str, Any]:
        # JSON has no infinity: the time classifier's "no earlier run" gap is stored as None.
        return {
            "params": self.params.to_dict(),
            "state": [None if not np.isfinite(v) else float(v) for v in self._S],
        }

    def set_state(self, state: dict[str, Any]) -> CorePipeline:
        params = CoreParams.from_dict(state["params"])
        P = params.to_array()
        values = np.array([np.inf if v is None else v for v in state["state"]], dtype=np.float64)
        if values.shape != (core_state_size(P),):
            raise ConfigError(
                f"pipeline state has {values.size} values, expected {core_state_size(P)}: "
                "it was saved by another version or with other parameters"
            )
        self.params, self._P, self._S = params, P, values
        self._out = np.zeros(N_RESULT + 2 * N_OUT + params.n_features())
        self.features = self._out[N_RESULT + 2 * N_OUT :]
        return self
