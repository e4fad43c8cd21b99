"""How the pipeline's states behave on positions-only drives, with and without the motion model.

Prints, per synthetic drive (straight motorway, 600 m motorway curve at 1 Hz
and 0.5 Hz, a 25 m roundabout, a 10 Hz bend; receiver error as in
tests/test_reacquire.py): the share of clean fixes where the offset tracker
holds a phantom offset above its threshold, the median offset, the share of
REMA flags on the clean drive, and after a 100-fix 150 m jump how many fixes
after its end REMA and the offset tracker still hold it. Run:

    python benchmarks/positions_only_states.py
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from gradgps._grad.defaults import grad_rema_params
from gradgps._grad.pipeline import PipelineParams, grad_features, pipeline_feature_names
from gradgps._tracks.geo import LocalFrame
from test_reacquire import CASES, _drive, _last_true, _uncompress

FRAME = LocalFrame(48.1, 11.5)


#: m: an offset held above this on a clean fix is a phantom (the 8 m the offset tracker's
#: rule-based predecessor called a suspected fault, kept so figures stay comparable).
PHANTOM_M = 8.0


def _features(params: PipelineParams, t, east, north):  # type: ignore[no-untyped-def]
    lat, lon = FRAME.to_geodetic(east, north)
    nan = np.full(t.size, np.nan)
    names = pipeline_feature_names(params)
    f = grad_features(params, FRAME, t, lat, lon, nan, nan).features
    return {n: _uncompress(f[:, k]) for k, n in enumerate(names)}


def main() -> None:
    before = PipelineParams(
        motion=None,
        rema=replace(grad_rema_params(), reacquire_after=0, max_run=0),
    )
    configs = {
        "before (no motion model, unbounded REMA)": before,
        "now": PipelineParams(),
    }
    thr = PHANTOM_M
    print(
        "| pipeline | drive | phantom offset share | median offset (m) | REMA flags clean | "
        "REMA flags after jump end (fixes) | offset held after jump end (fixes) |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, params in configs.items():
        for period, speed, radius in CASES:
            t, east, north = _drive(600, period, speed, radius, seed=2)
            f = _features(params, t, east, north)
            rema = (f["east_rema_flag"] > 0) | (f["north_rema_flag"] > 0)
            shifted = east.copy()
            shifted[200:300] += 150.0
            g = _features(params, t, shifted, north)
            rema_j = (g["east_rema_flag"] > 0) | (g["north_rema_flag"] > 0)
            drive = f"{speed:g} m/s, {'straight' if not np.isfinite(radius) else f'r {radius:g} m'}, {1 / period:g} Hz"
            print(
                f"| {label} | {drive} | {np.mean(f['offset_norm'][20:] > thr):.3f} | "
                f"{np.median(f['offset_norm'][20:]):.1f} | {rema[20:].mean():.3f} | "
                f"{_last_true(rema_j[300:])} | {_last_true(g['offset_norm'][300:] > thr)} |"
            )


if __name__ == "__main__":
    main()
