"""Time columns as users' files write them: what the detector does, what the checks say.

A receiver's positions can be right while its file's times are not what the
model was validated on: fixes lost at random or in dropouts, times stamped by
a logger with some latency, or written to whole seconds. Per real validation
drive (positions only, native rate, via ``_clean_variants.py``) and per
rewriting of the time column (positions untouched):

* ``as recorded``;
* ``10 % dropped`` / ``30 % dropped``: fixes lost at random (seed 0);
* ``5 s gaps`` / ``20 s gaps``: dropouts of that length, on average every 60 /
  120 s (exponential, seed 0);
* ``jitter 0.1 s`` / ``0.3 s``: each time moved uniformly within that much (a
  logger's latency; rows re-sorted by the new times);
* ``whole s``: times written as whole seconds (floor);
* ``whole s, offset 0.5 s, jitter 50 ms``: the same after moving the times by
  half a second and up to 50 ms either way (fixes near a second's edge);
* ``whole s, fixes 0.995 s apart`` / ``1.005 s apart``: the times of a clock
  that runs 0.5 % slower / faster than the receiver's (a 1 Hz fix every 0.995
  / 1.005 s of it), written as whole seconds: one repeated or skipped second
  every 200 s.

No fault is injected: every flag is a false alarm (a fix set aside as invalid
counts as flagged, as in the output's ``anomaly`` column). Never the test
splits. Run:

    python benchmarks/time_columns.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from _clean_variants import Rewrite, print_table


def dropped(share: float) -> Rewrite:
    def rewrite(fixes: pd.DataFrame) -> pd.DataFrame:
        keep = np.random.default_rng(0).random(len(fixes)) >= share
        return fixes[keep].reset_index(drop=True)

    return rewrite


def gaps(every_s: float, length_s: float) -> Rewrite:
    def rewrite(fixes: pd.DataFrame) -> pd.DataFrame:
        rng = np.random.default_rng(0)
        parts = []
        for _, g in fixes.groupby("track", sort=False):
            t = g["t"].to_numpy()
            keep = np.ones(len(g), dtype=bool)
            start = t[0] + rng.exponential(every_s)
            while start < t[-1]:
                keep &= ~((t >= start) & (t < start + length_s))
                start += length_s + rng.exponential(every_s)
            parts.append(g[keep])
        return pd.concat(parts).reset_index(drop=True)

    return rewrite


def jittered(within_s: float) -> Rewrite:
    def rewrite(fixes: pd.DataFrame) -> pd.DataFrame:
        rng = np.random.default_rng(0)
        t = fixes["t"].to_numpy() + rng.uniform(-within_s, within_s, len(fixes))
        moved = fixes.assign(t=t).sort_values(["track", "t"], kind="stable")
        return moved.reset_index(drop=True)

    return rewrite


def whole_seconds(offset_s: float = 0.0, jitter_s: float = 0.0, clock: float = 1.0) -> Rewrite:
    def rewrite(fixes: pd.DataFrame) -> pd.DataFrame:
        rng = np.random.default_rng(0)
        t0 = fixes.groupby("track", sort=False)["t"].transform("min")
        t = t0 + (fixes["t"] - t0) * clock + offset_s
        t = t + rng.uniform(-jitter_s, jitter_s, len(fixes))
        return fixes.assign(t=np.floor(t)).reset_index(drop=True)

    return rewrite


if __name__ == "__main__":
    print_table(
        __doc__.splitlines()[0],
        {
            "as recorded": lambda fixes: fixes,
            "10 % dropped": dropped(0.1),
            "30 % dropped": dropped(0.3),
            "5 s gaps": gaps(60.0, 5.0),
            "20 s gaps": gaps(120.0, 20.0),
            "jitter 0.1 s": jittered(0.1),
            "jitter 0.3 s": jittered(0.3),
            "whole s": whole_seconds(),
            "whole s, offset 0.5 s, jitter 50 ms": whole_seconds(0.5, 0.05),
            "whole s, fixes 0.995 s apart": whole_seconds(clock=0.995),
            "whole s, fixes 1.005 s apart": whole_seconds(clock=1.005),
        },
    )
