"""Thinning a track to a slower rate, as a slower receiver would have logged it."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["THIN_SLACK", "thin_mask"]

#: Share of the period a step may fall short and still count as a whole period.
#: Receivers stamp fixes with jitter (the GoPro's "1 Hz" steps are 0.95-1.05 s):
#: with no slack, thinning such a file to 1 Hz would drop every second fix.
THIN_SLACK = 0.1


def thin_mask(
    tracks: NDArray[np.object_],
    t: NDArray[np.float64],
    period_s: float,
    slack: float = THIN_SLACK,
) -> NDArray[np.bool_]:
    """Which fixes a receiver logging every ``period_s`` seconds would have kept.

    Per track, in time order: the first fix, then every fix at least
    ``period_s * (1 - slack)`` after the last kept one. Fixes without a
    finite time are never kept. ``tracks`` and ``t`` are per row.
    """
    keep = np.zeros(t.size, dtype=bool)
    limit = period_s * (1.0 - slack)
    finite = np.flatnonzero(np.isfinite(t))
    order = finite[np.lexsort((t[finite], tracks[finite].astype(str)))]
    last_track: object = None
    last_t = -np.inf
    for row in order:
        if tracks[row] != last_track:
            last_track, last_t = tracks[row], -np.inf
        if t[row] - last_t >= limit:
            keep[row] = True
            last_t = t[row]
    return keep
